"""Export a canonical sequence in the layouts external SLAM systems read unchanged.

Formats (``egs-bench export SEQ -o OUT --format F``):

``tum-rgbd`` (MonoGS ``type: tum``, ORB-SLAM2 ``rgbd_tum``, Photo-SLAM ``tum_rgbd``)::

    OUT/rgb/%06d.png  depth/%06d.png     8-bit RGB; 16-bit depth at 5000 units per metre
    OUT/rgb.txt  depth.txt               "t path" per line after '#' comment lines
    OUT/groundtruth.txt                  TUM "t tx ty tz qx qy qz qw", one '#' header line
    OUT/associations.txt                 "t rgb/... t depth/..." (ORB-SLAM's format, no comments)
    OUT/monogs_rgbd.yaml  orbslam2_rgbd.yaml  photoslam_rgbd.yaml

``replica`` (NICE-SLAM-style loaders, MonoGS ``type: replica``)::

    OUT/results/frame%06d.jpg  depth%06d.png  OUT/traj.txt  OUT/cam_params.json
    OUT/monogs_replica.yaml  nice_slam.yaml

``eds`` (RampVO's EDS scene folder)::

    OUT/image_left/%06d.png  OUT/events.h5  OUT/timestamps.txt  OUT/pose_left.txt  OUT/K.yaml

Every export also writes ``index_map.csv`` (export frame -> sequence frame and both time
stamps) and ``egs_export.yaml`` (what was written and why), which ``egs-bench import-run``
reads to map an external system's output back onto the sequence.

Pitfalls handled (each checked in ``tests/interop/test_interop_export.py`` against the
consuming loader's parsing logic):

* MonoGS' ``TUMParser`` reads ``groundtruth.txt`` with ``skiprows=1`` (the first line is lost
  even if it is a pose): the file starts with a comment line. It keeps a frame only when it is
  **more than 1/32 s** after the last kept one: with ``retime="auto"`` (default) a
  ``tum-rgbd`` export of a sequence whose frames are closer is written with stamps
  ``t_0 + j / 30`` (recorded in ``index_map.csv`` and undone on import); otherwise, and in the
  other formats, the sequence's own exposure-end stamps are kept.
* Its ``np.loadtxt(delimiter=" ")`` needs single spaces; ORB-SLAM's association reader treats
  every non-empty line as data, so ``associations.txt`` has no comments.
* Depth is written at 5000 units per metre (TUM); depths beyond 13.1 m become 0 (invalid) and
  are counted in ``egs_export.yaml``. Replica exports use 6553.5 (its own scale).
* Intrinsics in the camera files use the OpenCV pixel convention (``cx - 0.5``, see
  :mod:`egs_bench.interop.camera_files`). Each layout gets the camera file of every system
  that reads it (:func:`egs_bench.interop.registry.systems_reading`).
* RampVO's ``Events`` class asserts ``t`` int64 and ``p`` int8 in {0, 1}; its EDS path reads
  ``timestamps.txt`` in microseconds and ``pose_left.txt`` in seconds: the export's
  ``events.h5`` holds absolute microseconds in those dtypes plus ``events/height`` and
  ``events/width``.

Output safety: an existing ``OUT`` is only replaced with ``overwrite=True`` and only if it is
an earlier egs-bench export (it has ``egs_export.yaml``); the export is built under a temporary
name and renamed at the end (:func:`egs_bench.fileio.atomic_dir`). Every image is decoded and
its size checked before it is copied, so a truncated or resized frame stops the export with an
error naming the file, and nothing is published.
"""

from __future__ import annotations

import collections.abc
import csv
import shutil
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, overload

import numpy as np
import yaml

from egs_bench.errors import ConfigError, InputError, OutputError
from egs_bench.fileio import atomic_dir, to_plain
from egs_bench.geometry import write_tum
from egs_bench.images import image_header, write_depth_png, write_ldr_image
from egs_bench.interop.camera_files import checkout_path, opencv_camera
from egs_bench.interop.registry import systems_reading
from egs_bench.interop.systems import CameraFileRequest
from egs_bench.outputs import check_never_replaced

if TYPE_CHECKING:
    from egs_bench.datasets.sequence import Sequence

FORMATS = ("tum-rgbd", "replica", "eds")
MANIFEST = "egs_export.yaml"
INDEX_MAP = "index_map.csv"
TUM_DEPTH_SCALE = 5000.0
MONOGS_MIN_GAP_S = 1.0 / 32.0  # TUMParser keeps a frame only if t - t_kept > 1/32 s
RETIMED_PERIOD_S = 1.0 / 30.0
_EVENT_CHUNK_US = 1_000_000
# what a format writer returns: camera files by consumer, manifest entries, notes
_Written = tuple[dict[str, str], dict[str, Any], list[str]]


@dataclass
class ExportResult:
    """What an export wrote.

    Attributes:
        path: the export folder.
        format: one of :data:`FORMATS`.
        frames: number of frames written.
        retimed: whether the time stamps were rewritten (``t_0 + j / 30``).
        files: the camera / settings files written, by consumer.
        notes: human-readable remarks (also in ``egs_export.yaml``).
    """

    path: Path
    format: str
    frames: int
    retimed: bool
    files: dict[str, str] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)


def _check_out(out: Path, overwrite: bool) -> None:
    if not out.exists():
        return
    if not out.is_dir():
        raise OutputError(out, "exists and is not a folder")
    if not any(out.iterdir()):
        return
    if not overwrite:
        raise OutputError(out, "already exists (pass --overwrite to replace an earlier export)")
    if not (out / MANIFEST).is_file():
        raise OutputError(out, f"is not an egs-bench export (no {MANIFEST}); refusing to replace "
                              "it, choose another output folder")


def export_times(t_end_s: np.ndarray, retime: str) -> tuple[np.ndarray, bool]:
    """Time stamps to write (seconds) and whether they were rewritten.

    ``retime``: ``"auto"`` rewrites to ``t_0 + j / 30`` only when two consecutive frames are at
    most 1/32 s apart (MonoGS would drop frames), ``"never"`` keeps the sequence's stamps,
    ``"always"`` rewrites.
    """
    if retime not in ("auto", "never", "always"):
        raise ConfigError(f"retime must be auto, never or always, not {retime!r}")
    t = np.asarray(t_end_s, dtype=np.float64)
    gaps = np.diff(np.round(t, 6))
    if retime == "always" or (retime == "auto" and len(gaps) and gaps.min() <= MONOGS_MIN_GAP_S):
        return np.round(t[0] + np.arange(len(t)) * RETIMED_PERIOD_S, 6), True
    return t, False


def _write_index_map(path: Path, t_export: np.ndarray, t_seq: np.ndarray,
                     rgb: list[str], depth: list[str]) -> None:
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle, lineterminator="\n")
        writer.writerow(["index", "frame", "t_export_s", "t_sequence_s", "rgb", "depth"])
        for j, (te, ts) in enumerate(zip(t_export, t_seq, strict=True)):
            writer.writerow([j, j, f"{te:.6f}", f"{ts:.6f}", rgb[j], depth[j]])


def _copy_rgb(seq: Sequence, i: int, dst: Path) -> None:
    """Copy frame ``i``'s PNG bytes when it is plain 8-bit RGB (what every loader reads),
    re-encode it otherwise.

    The frame is decoded either way: a header-only check (what ``Sequence.open`` does) passes
    a truncated file, and a copied one would reach the consuming system as a corrupt frame.

    Raises:
        InputError: naming the frame's file, when it does not decode or has another size.
    """
    src = seq.frame_path(i, "rgb")
    pixels = seq.rgb(i)  # decodes and checks the size against meta.yaml
    plain = src.suffix.lower() == ".png" and image_header(src)[2] == "RGB"
    if plain:
        shutil.copyfile(src, dst)
    else:
        write_ldr_image(dst, pixels)  # dst is a .png name


def _depth_png(seq: Sequence, i: int, dst: Path, scale: float) -> int:
    """Write frame ``i``'s depth at ``scale`` units per metre; returns the number of valid
    pixels lost to the 16-bit range. Copies the bytes when the scale is unchanged, after
    decoding them (see :func:`_copy_rgb`).

    Raises:
        InputError: naming the depth file, when it does not decode, has another size or holds
            invalid values.
    """
    from egs_bench.datasets.sequence import encode_depth

    src = seq.frame_path(i, "depth")
    depth = seq.depth(i)  # decodes, checks the size and the values
    if src.suffix.lower() == ".png" and abs(seq.depth_scale - scale) < 1e-9:
        shutil.copyfile(src, dst)
        return 0
    raw = encode_depth(depth, scale)
    write_depth_png(dst, raw)
    return int(((depth > 0) & (raw == 0)).sum())


def _manifest(tmp: Path, seq: Sequence, fmt: str, n: int, retimed: bool, files: dict[str, str],
              extra: dict[str, Any], notes: list[str]) -> None:
    cam = opencv_camera(seq.intrinsics)
    data = {
        "egs_bench_export": 1,
        "format": fmt,
        "sequence": {"name": seq.name, "path": str(Path(seq.path).resolve())},
        "frames": n,
        "timestamps": ("retimed: t_0 + j / 30 s (MonoGS drops frames closer than 1/32 s); "
                       "index_map.csv maps them back" if retimed
                       else "the sequence's exposure-end times"),
        "retimed": retimed,
        "camera_opencv": {"fx": cam.fx, "fy": cam.fy, "cx": cam.cx, "cy": cam.cy,
                          "width": cam.width, "height": cam.height,
                          "convention": "pixel centre at integer coordinates (egs-bench cx, "
                                        "cy minus 0.5)"},
        "files": files,
        **extra,
        "notes": notes,
    }
    (tmp / MANIFEST).write_text(yaml.safe_dump(to_plain(data), sort_keys=False))


def _write_camera_files(tmp: Path, request: CameraFileRequest) -> dict[str, str]:
    """Write the camera file of every system that reads ``request.layout`` into ``tmp``;
    returns their names by system key, in registry order."""
    files = {}
    for system in systems_reading(request.layout):
        camera_file = system.camera_files[request.layout]
        (tmp / camera_file.name).write_text(camera_file.write(request))
        files[system.key] = camera_file.name
    return files


def _export_tum(seq: Sequence, tmp: Path, n: int, t_export: np.ndarray, in_checkout: str,
                progress: bool) -> _Written:
    from egs_bench.progress import tracked

    (tmp / "rgb").mkdir()
    (tmp / "depth").mkdir()
    rgb_names, depth_names = [], []
    lost = 0
    for i in tracked(range(n), f"export {seq.name} (tum-rgbd)", unit="frame", enabled=progress):
        name = f"{i:06d}.png"
        _copy_rgb(seq, i, tmp / "rgb" / name)
        lost += _depth_png(seq, i, tmp / "depth" / name, TUM_DEPTH_SCALE)
        rgb_names.append(f"rgb/{name}")
        depth_names.append(f"depth/{name}")
    stamps = [f"{t:.6f}" for t in t_export]
    head = "# {} exported by egs-bench from sequence '{}'\n# timestamp filename\n"
    (tmp / "rgb.txt").write_text(head.format("color images", seq.name) + "".join(
        f"{t} {f}\n" for t, f in zip(stamps, rgb_names, strict=True)))
    (tmp / "depth.txt").write_text(head.format("depth maps", seq.name) + "".join(
        f"{t} {f}\n" for t, f in zip(stamps, depth_names, strict=True)))
    (tmp / "associations.txt").write_text("".join(
        f"{t} {r} {t} {d}\n" for t, r, d in zip(stamps, rgb_names, depth_names, strict=True)))
    write_tum(tmp / "groundtruth.txt", t_export, seq.poses[:n])
    _write_index_map(tmp / INDEX_MAP, t_export, seq.timestamps_s[:n], rgb_names, depth_names)
    fps = 1.0 / float(np.median(np.diff(t_export))) if n > 1 else 30.0
    files = _write_camera_files(tmp, CameraFileRequest(
        opencv_camera(seq.intrinsics), seq, n, "tum-rgbd", in_checkout, TUM_DEPTH_SCALE, fps))
    files["associations"] = "associations.txt"
    notes = []
    if lost:
        notes.append(f"{lost} depth pixels beyond {65535 / TUM_DEPTH_SCALE:.1f} m became 0 "
                     "(invalid) at the TUM depth scale")
    return files, {"depth_scale": TUM_DEPTH_SCALE, "depth_pixels_lost": lost,
                   "fps": round(fps, 6)}, notes


class _LazyFrames(collections.abc.Sequence[np.ndarray]):
    """``frames[i]`` reads frame ``i`` on demand (the Replica writer iterates once)."""

    def __init__(self, n: int, read: Callable[[int], np.ndarray]) -> None:
        self._n, self._read = n, read

    def __len__(self) -> int:
        return self._n

    @overload
    def __getitem__(self, i: int) -> np.ndarray: ...

    @overload
    def __getitem__(self, i: slice) -> list[np.ndarray]: ...

    def __getitem__(self, i: int | slice) -> np.ndarray | list[np.ndarray]:
        if isinstance(i, slice):
            return [self._read(j) for j in range(*i.indices(self._n))]
        if not 0 <= i < self._n:
            raise IndexError(i)
        return self._read(i)


def _export_replica(seq: Sequence, tmp: Path, n: int, t_export: np.ndarray, in_checkout: str,
                    jpeg_quality: int) -> _Written:
    from egs_bench.datasets.replica import REPLICA_DEPTH_SCALE, export_replica_layout

    scene = tmp / "scene"
    export_replica_layout(_LazyFrames(n, seq.rgb), _LazyFrames(n, seq.depth), seq.poses[:n],
                          scene, intrinsics=seq.intrinsics, depth_scale=REPLICA_DEPTH_SCALE,
                          image_format="jpg", jpeg_quality=jpeg_quality, jpeg_chroma_444=True)
    for entry in scene.iterdir():
        entry.rename(tmp / entry.name)
    scene.rmdir()
    _write_index_map(tmp / INDEX_MAP, t_export, seq.timestamps_s[:n],
                     [f"results/frame{i:06d}.jpg" for i in range(n)],
                     [f"results/depth{i:06d}.png" for i in range(n)])
    files = _write_camera_files(tmp, CameraFileRequest(
        opencv_camera(seq.intrinsics), seq, n, "replica", in_checkout, REPLICA_DEPTH_SCALE))
    files["camera"] = "cam_params.json"
    notes = [f"colour re-encoded as JPEG (quality {jpeg_quality}, 4:4:4 chroma): Replica "
             "loaders glob frame*.jpg only", "the layout has no time stamps: frames are in order, "
             "index_map.csv gives their times"]
    return files, {"depth_scale": REPLICA_DEPTH_SCALE, "jpeg_quality": jpeg_quality}, notes


def _export_eds(seq: Sequence, tmp: Path, n: int, t_export: np.ndarray, in_checkout: str
                ) -> _Written:
    import h5py

    (tmp / "image_left").mkdir()
    names = []
    for i in range(n):
        name = f"image_left/{i:06d}.png"
        _copy_rgb(seq, i, tmp / name)
        names.append(name)
    t_us = np.round(np.asarray(t_export) * 1e6).astype(np.int64)
    (tmp / "timestamps.txt").write_text("".join(f"{t}\n" for t in t_us))
    write_tum(tmp / "pose_left.txt", t_export, seq.poses[:n])
    _write_index_map(tmp / INDEX_MAP, t_export, seq.timestamps_s[:n], names, [""] * n)
    files = _write_camera_files(tmp, CameraFileRequest(
        opencv_camera(seq.intrinsics), seq, n, "eds", in_checkout))
    stream = seq.events  # written with absolute microsecond stamps, like timestamps.txt
    count = 0
    with h5py.File(tmp / "events.h5", "w") as f:
        grp = f.create_group("events")
        specs = {"x": np.uint16, "y": np.uint16, "t": np.int64, "p": np.int8}
        dsets = {k: grp.create_dataset(k, shape=(0,), maxshape=(None,), dtype=d,
                                       chunks=(1 << 16,), compression="gzip",
                                       compression_opts=1, shuffle=True)
                 for k, d in specs.items()}
        grp.create_dataset("height", data=np.int64(seq.height))
        grp.create_dataset("width", data=np.int64(seq.width))
        t_first, t_last = stream.t_first, stream.t_last
        if t_first is not None and t_last is not None:  # both None when it is empty
            t_stop = min(t_last, int(seq.t_end_us[n - 1])) + 1
            for t0 in range(int(t_first), t_stop, _EVENT_CHUNK_US):
                ev = stream.window(t0, min(t0 + _EVENT_CHUNK_US, t_stop))
                if len(ev) == 0:
                    continue
                for key, values in (("x", ev.x), ("y", ev.y), ("t", ev.t),
                                    ("p", (ev.p > 0).astype(np.int8))):
                    dsets[key].resize((count + len(ev),))
                    dsets[key][count:] = values
                count += len(ev)
    per_frame = count / max(n, 1)
    notes = [f"{count} events ({per_frame:.0f} per frame): set RampVO's num_events_selected "
             "near that (its EDS config uses 250000)"]
    return files, {"events": count, "events_per_frame": round(per_frame, 1)}, notes


def export_sequence(sequence: str | Path | Sequence, out: str | Path, *, fmt: str,
                    overwrite: bool = False, retime: str = "auto", jpeg_quality: int = 95,
                    progress: bool = False) -> ExportResult:
    """Export ``sequence`` (a folder or an opened :class:`Sequence`) to ``out`` in ``fmt``.

    Args:
        sequence: sequence folder or opened sequence.
        out: the export folder to create.
        fmt: ``"tum-rgbd"``, ``"replica"`` or ``"eds"`` (see the module docstring).
        overwrite: replace an earlier egs-bench export at ``out``.
        retime: time stamps: ``auto`` / ``never`` / ``always`` (see :func:`export_times`).
        jpeg_quality: JPEG quality of the Replica layout.
        progress: show a progress bar.

    Raises:
        ConfigError: unknown format or option. InputError: unreadable sequence, ``out`` exists
            (without ``overwrite``, or not an export), ``eds`` without events.
    """
    from egs_bench.datasets.sequence import Sequence

    if fmt not in FORMATS:
        raise ConfigError(f"unknown export format {fmt!r}; choose one of {', '.join(FORMATS)}")
    if retime not in ("auto", "never", "always"):
        raise ConfigError(f"--retime must be auto, never or always, not {retime!r}")
    seq = sequence if isinstance(sequence, Sequence) else Sequence.open(sequence)
    if fmt == "eds" and not seq.has_events:
        raise InputError(seq.path, "has no events; the eds layout (RampVO) needs them")
    out = Path(out)
    check_never_replaced(out, inputs=[seq.path])
    _check_out(out, overwrite)
    # the configs name the export relative to the system's checkout, not by this machine's path
    in_checkout = checkout_path(out.resolve())
    n = len(seq)
    # only MonoGS' TUM loader drops close frames; RampVO and the Replica layout keep the stamps
    t_export, retimed = export_times(seq.timestamps_s[:n], retime if fmt == "tum-rgbd" else
                                     "never")
    notes: list[str] = []
    if retimed:
        notes.append("time stamps rewritten to t_0 + j/30 s: the sequence has frames at most "
                     "1/32 s apart, which MonoGS' TUM loader would drop")
    with atomic_dir(out, replace=overwrite) as tmp:
        tmp.mkdir()
        if fmt == "tum-rgbd":
            files, extra, more = _export_tum(seq, tmp, n, t_export, in_checkout, progress)
        elif fmt == "replica":
            files, extra, more = _export_replica(seq, tmp, n, t_export, in_checkout, jpeg_quality)
        else:
            files, extra, more = _export_eds(seq, tmp, n, t_export, in_checkout)
        notes += more
        _manifest(tmp, seq, fmt, n, retimed, files, extra, notes)
    return ExportResult(out, fmt, n, retimed, files, notes)


@dataclass(frozen=True)
class ExportIndex:
    """``index_map.csv`` of an export: export frame ``j`` is sequence frame ``frame[j]``.

    Attributes:
        path: the export folder.
        format: the export format.
        sequence_name, sequence_path: the exported sequence.
        frame: sequence frame index per export frame, [N] int64.
        t_export_s: time stamp written in the export, [N] seconds.
        t_sequence_s: the sequence's exposure-end time, [N] seconds.
        rgb: colour file per export frame (relative to the export folder).
    """

    path: Path
    format: str
    sequence_name: str
    sequence_path: Path
    frame: np.ndarray
    t_export_s: np.ndarray
    t_sequence_s: np.ndarray
    rgb: tuple[str, ...]


def read_export_index(path: str | Path) -> ExportIndex:
    """Read an export folder's ``egs_export.yaml`` and ``index_map.csv``.

    Raises:
        InputError: not an egs-bench export, or a malformed index.
    """
    root = Path(path)
    manifest = root / MANIFEST
    if not manifest.is_file():
        raise InputError(root, f"not an egs-bench export (no {MANIFEST})")
    try:
        meta = yaml.safe_load(manifest.read_text()) or {}
        seq = meta["sequence"]
        with (root / INDEX_MAP).open(newline="") as handle:
            rows = list(csv.DictReader(handle))
        frame = np.array([int(r["frame"]) for r in rows], dtype=np.int64)
        t_exp = np.array([float(r["t_export_s"]) for r in rows])
        t_seq = np.array([float(r["t_sequence_s"]) for r in rows])
        rgb = tuple(r.get("rgb", "") for r in rows)
    except (OSError, KeyError, TypeError, ValueError, yaml.YAMLError) as exc:
        raise InputError(root, f"malformed export index ({type(exc).__name__}: {exc})") \
            from None
    if not len(rows):
        raise InputError(root / INDEX_MAP, "lists no frames")
    return ExportIndex(root, str(meta.get("format")), str(seq["name"]), Path(seq["path"]),
                       frame, t_exp, t_seq, rgb)
