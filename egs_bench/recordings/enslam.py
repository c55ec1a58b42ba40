"""EN-SLAM's DEV-Reals sequences (Qu et al., "Implicit Event-RGBD Neural SLAM", CVPR 2024).

The published loader is ``datasets/dataset.py`` in the Hugging Face dataset
``delinqu/EN-SLAM-Dataset``, but no copy of it could be read here. The layout below is the one
the authors' extraction toolkit writes, github ``NPU-YanChi/toolkit_for_dev-reals`` (Chi Yan is
a first author): ``fetchrgbd.py``, ``src/scripts/npzs_to_frame.py``,
``src/scripts/fake_pose_generate.py`` and ``check.py``. One folder per sequence::

    <seq>/rgbd/rgb/<stamp>.jpg                RealSense colour (/camera/color/image_raw)
    <seq>/rgbd/depth/<stamp>.png              16UC1 aligned to the colour camera
                                              (/camera/aligned_depth_to_color/image_raw)
    <seq>/davis346/rgb/<stamp>.jpg            DAVIS346 APS frames (/dvs/image_raw)
    <seq>/davis346/event/events.csv           header x,y,ts_s,ts_n,polarity (/dvs/events)
    <seq>/davis346/intrinsic/intrinsic.yaml   David346: image_width, image_height,
                                              intrinsics.data (K, 9 numbers), distortion.data
    <seq>/pose/pose.txt                       TUM: timestamp x y z q_x q_y q_z q_w

``<stamp>`` is the ROS header stamp in seconds with six decimals (``%.6f``). The colour and depth
images of one instant share a stamp (``check.py`` checks that they pair up). Event times are
``ts_s`` seconds plus ``ts_n`` nanoseconds, and the polarity is ``True``/``False``.

The layout does not give the exposure time, what a stamp marks, the colour camera's
intrinsics, the DAVIS-RealSense extrinsics, which camera the poses describe, or the depth
unit. The toolkit's own comment reads the 16UC1 values as millimetres, but that is a comment,
not data. All of these come from ``calib.yaml`` and the command line, with no defaults. Only
the event camera is taken from ``intrinsic.yaml``, when ``calib.yaml`` has none.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any, Literal

import numpy as np
import yaml

from egs_bench.datasets.events import Events
from egs_bench.errors import ConfigError, InputError
from egs_bench.outputs import prepare_output
from egs_bench.recordings.calib import load_calib
from egs_bench.recordings.camera import CameraModel
from egs_bench.recordings.folders import depth_images, image_frames, tum_track
from egs_bench.recordings.importer import (
    RecordingSpec,
    checked_inputs,
    require_depth_scale,
    write_sequence,
)
from egs_bench.recordings.streams import EventSource, FrameStamp, exposure_windows

#: the files of one sequence, relative to its folder
LAYOUT = {
    "rgb": "rgbd/rgb",
    "depth": "rgbd/depth",
    "davis_rgb": "davis346/rgb",
    "events": "davis346/event/events.csv",
    "intrinsic": "davis346/intrinsic/intrinsic.yaml",
    "pose": "pose/pose.txt",
}
EVENT_COLUMNS = ["x", "y", "ts_s", "ts_n", "polarity"]
#: rows of events.csv per batch (about 40 MB of columns)
CSV_CHUNK_ROWS = 1 << 20
#: ``<seconds>.<fraction>`` as the toolkit names images
_STAMP = re.compile(r"^(\d+)\.(\d{1,9})$")
#: what the two frame choices read
#: Which camera the frames come from: the RGB-D sensors colour or the DAVIS frames.
EnslamFrames = Literal["rgbd", "davis"]
FRAME_SOURCES: dict[EnslamFrames, str] = {"rgbd": "rgb", "davis": "davis_rgb"}


def stamp_us(path: Path) -> int:
    """The stamp in an image's name (``1700000000.123456.jpg``) as integer microseconds, read
    from the digits (no float rounding).

    Raises:
        InputError: a name that is not ``<seconds>.<fraction>.<ext>``.
    """
    match = _STAMP.match(path.stem)
    if match is None:
        raise InputError(path, "the name is not a time stamp '<seconds>.<fraction>' (the DEV-Reals "
                               "toolkit names images by their ROS header stamp)")
    seconds, fraction = match.groups()
    return int(seconds) * 1_000_000 + int(fraction.ljust(9, "0")) // 1000


def stamped_images(folder: Path) -> tuple[list[Path], np.ndarray]:
    """The images of ``folder`` in time order and their stamps ([N] int64 us).

    Raises:
        InputError: no image, a name that is no stamp, or two images with one stamp.
    """
    from egs_bench.recordings.folders import list_images

    files = list_images(folder)
    t = np.asarray([stamp_us(f) for f in files], np.int64)
    order = np.argsort(t, kind="stable")
    files, t = [files[i] for i in order], t[order]
    if (np.diff(t) == 0).any():
        i = int(np.argmax(np.diff(t) == 0))
        raise InputError(files[i + 1], f"has the same stamp as {files[i].name}")
    return files, t


def read_davis_intrinsics(path: Path) -> CameraModel:
    """The DAVIS camera of the toolkit's ``intrinsic.yaml``: a ``David346`` mapping (the
    toolkit's spelling; ``DAVIS346`` is accepted too) with ``image_width``, ``image_height``,
    ``intrinsics.data`` (K row by row) and ``distortion.data`` (radtan / plumb_bob), in the
    OpenCV pixel convention of ROS calibrations.

    Raises:
        InputError: naming the file and what is missing.
    """
    try:
        raw = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise InputError(path, f"not a readable YAML file ({exc})") from None
    entry = None
    if isinstance(raw, dict):
        entry = raw.get("David346", raw.get("DAVIS346"))
    if not isinstance(entry, dict):
        raise InputError(path, "no 'David346' camera (the DEV-Reals toolkit's intrinsic.yaml)")
    try:
        k = [float(v) for v in entry["intrinsics"]["data"]]
        coeffs = tuple(float(v) for v in (entry.get("distortion") or {}).get("data") or ())
        if len(k) != 9:
            raise ValueError(f"intrinsics.data has {len(k)} numbers, K needs 9")
        model = "radtan" if coeffs else "none"
        return CameraModel(int(entry["image_width"]), int(entry["image_height"]), k[0], k[4],
                           k[2], k[5], model=model, coeffs=coeffs)
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(path, f"David346: not a camera ({exc})") from None


def csv_events(path: Path, width: int, height: int) -> EventSource:
    """The events of the toolkit's ``events.csv`` (header ``x,y,ts_s,ts_n,polarity``; time
    ``ts_s`` s + ``ts_n`` ns; polarity True/False or 1/0), read in batches.

    Raises (while reading):
        InputError: another header, a row that is not numbers, a negative coordinate, an
            unknown polarity; each names the file (and the row).
    """
    import pandas as pd

    with path.open(encoding="utf-8", errors="replace") as handle:
        header = [c.strip() for c in handle.readline().strip().split(",")]
    if header != EVENT_COLUMNS:
        raise InputError(path, f"header is {','.join(header)!r}, expected "
                               f"{','.join(EVENT_COLUMNS)!r} (the DEV-Reals toolkit's events.csv)")

    def batches() -> Iterator[Events]:
        row = 2  # the first data row's line number
        try:
            with pd.read_csv(path, chunksize=CSV_CHUNK_ROWS, dtype=str,
                             keep_default_na=False) as chunks:  # closes the file on errors
                for chunk in chunks:
                    yield _event_batch(chunk, path, row)
                    row += len(chunk)
        except (ValueError, pd.errors.ParserError) as exc:
            raise InputError(path, f"near line {row}: not an events table ({exc})") from None

    return EventSource(str(path), width, height, batches)


def _event_batch(chunk: Any, path: Path, first_row: int) -> Events:
    """One chunk of ``events.csv`` (strings) -> :class:`Events`."""
    pol = chunk["polarity"].str.strip().str.lower()
    on, off = pol.isin(["true", "1"]).to_numpy(), pol.isin(["false", "0"]).to_numpy()
    if not (on | off).all():
        i = int(np.argmax(~(on | off)))
        raise InputError(path, f"line {first_row + i}: polarity {chunk['polarity'].iloc[i]!r} "
                               "is not True/False or 1/0")
    cols = {}
    for name in ("x", "y", "ts_s", "ts_n"):
        values = chunk[name].str.strip()
        bad = ~values.str.fullmatch(r"\d+").to_numpy()
        if bad.any():
            i = int(np.argmax(bad))
            raise InputError(path, f"line {first_row + i}: {name} {chunk[name].iloc[i]!r} is "
                                   "not a non-negative integer")
        cols[name] = values.to_numpy().astype(np.int64)
    t = cols["ts_s"] * 1_000_000 + cols["ts_n"] // 1000
    return Events.from_arrays(cols["x"], cols["y"], t, np.where(on, 1, -1))


def import_enslam(root: str | Path, out: str | Path, *, calib: str | Path,
                  exposure_us: int, frame_stamp: FrameStamp, frames: EnslamFrames = "rgbd",
                  max_depth_dt_us: int = 15_000, max_gt_gap_us: int = 50_000,
                  first_frame: int = 0, max_frames: int | None = None, name: str | None = None,
                  sensors: dict[str, str] | None = None, overwrite: bool = False,
                  progress: bool = True) -> Path:
    """Import one DEV-Reals sequence folder (see the module docstring) as a sequence folder,
    with everything :func:`~egs_bench.recordings.import_recording` does (undistortion, depth
    reprojection, frames warped into the event camera when they come from the RealSense).

    Args:
        root: the sequence folder (``rgbd/``, ``davis346/``, ``pose/``).
        out: the sequence folder to write.
        calib: ``calib.yaml``: ``depth_camera`` (the RealSense colour camera, since the depth is
            aligned to it) with ``depth_scale``, ``T_event_depth``, ``T_body_event`` (pose.txt's
            frame -> DAVIS), the time offsets and, with ``frames="rgbd"``, ``frame_camera``
            and ``T_event_frame``. A missing ``event_camera`` is read from ``intrinsic.yaml``.
        exposure_us: the frames' exposure time (the layout has none).
        frame_stamp: what a frame's stamp marks: start, mid or end of its exposure.
        frames: ``rgbd`` (the RealSense colour images, EN-SLAM's RGB input) or ``davis`` (the
            DAVIS APS frames, on the event sensor).
        max_depth_dt_us, max_gt_gap_us, first_frame, max_frames, name: as in
            :class:`~egs_bench.recordings.RecordingSpec`.
        sensors: sensor names for ``meta.yaml`` by stream.
        overwrite: replace an existing sequence folder at ``out``.
        progress: show a progress bar.

    Returns:
        ``out``.

    Raises:
        ConfigError: an unknown ``frames`` choice or ``frame_stamp``, a non-positive exposure.
        InputError: a missing layout file, a malformed file, a calibration that does not fit
            the data; each names the file.
    """
    root, out, calib_path = Path(root), Path(out), Path(calib)
    if frames not in FRAME_SOURCES:
        raise ConfigError(f"--frames {frames!r}: choose rgbd or davis")
    if frame_stamp not in ("start", "mid", "end"):
        raise ConfigError(f"--frame-stamp {frame_stamp!r}: choose start, mid or end")
    if exposure_us <= 0:
        raise ConfigError(f"--exposure-us {exposure_us}: must be positive")
    if not root.is_dir():
        raise InputError(root, "sequence folder not found")
    needed = ["depth", "events", "pose", FRAME_SOURCES[frames]]
    paths = {key: root / rel for key, rel in LAYOUT.items()}
    for key in needed:
        if not paths[key].exists():
            raise InputError(paths[key], "missing: not a DEV-Reals sequence folder (rgbd/rgb, "
                                         "rgbd/depth, davis346/event/events.csv, pose/pose.txt)")
    prepare_output(out, "sequence", overwrite=overwrite, inputs=[root, calib_path])
    cal = load_calib(calib_path)
    event_camera_from = "calib.yaml"
    if cal.event_camera is None:
        if not paths["intrinsic"].is_file():
            raise cal.error(f"no event_camera, and no {paths['intrinsic']} to take it from")
        cam = read_davis_intrinsics(paths["intrinsic"])
        cal = replace(cal, event_camera=cam,
                      depth_camera=cam if cal.depth_on_event_grid else cal.depth_camera)
        event_camera_from = str(paths["intrinsic"])
    assert cal.event_camera is not None
    frame_files, frame_t = stamped_images(paths[FRAME_SOURCES[frames]])
    t0, t1 = exposure_windows(frame_t, exposure_us, frame_stamp)
    depth_files, depth_t = stamped_images(paths["depth"])
    depth_stream = depth_images(str(paths["depth"]), depth_files, depth_t,
                                require_depth_scale(cal, paths["depth"]))
    inp = checked_inputs(
        cal, csv_events(paths["events"], cal.event_camera.width, cal.event_camera.height),
        image_frames(str(paths[FRAME_SOURCES[frames]]), frame_files, t0, t1), depth_stream,
        tum_track(paths["pose"]))
    spec = RecordingSpec(
        events=paths["events"], frames=paths[FRAME_SOURCES[frames]], depth=paths["depth"],
        gt=paths["pose"], calib=calib_path, frame_stamp=frame_stamp, exposure_us=exposure_us,
        max_depth_dt_us=max_depth_dt_us, max_gt_gap_us=max_gt_gap_us, first_frame=first_frame,
        max_frames=max_frames, name=name, depth_source="rgbd", sensors=dict(sensors or {}))
    layout = {"dataset": "EN-SLAM DEV-Reals", "root": str(root), "frames": frames,
              "exposure_us": int(exposure_us), "event_camera_from": event_camera_from,
              "reference": "github NPU-YanChi/toolkit_for_dev-reals (fetchrgbd.py, "
                           "src/scripts/npzs_to_frame.py)"}
    return write_sequence(inp, spec, out, overwrite=overwrite, progress=progress,
                          generator="egs-bench import-enslam", layout=layout)
