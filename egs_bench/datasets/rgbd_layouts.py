"""Readers for plain RGB-D + pose layouts other than Replica's: TUM RGB-D and a generic one.

Both return the :class:`~egs_bench.datasets.replica.ReplicaScene` the Replica reader returns, so
the EventReplica generator turns any of them into a blurred event sequence.

**TUM RGB-D** (the benchmark of Sturm et al., IROS 2012, and what ``egs-bench export --format
tum-rgbd`` writes)::

    <folder>/rgb.txt           "timestamp path" per line, '#' comments (seconds; path relative)
    <folder>/depth.txt         the same for 16-bit depth PNGs, metres = value / 5000
    <folder>/groundtruth.txt   TUM trajectory "t tx ty tz qx qy qz qw" (camera-to-world)

Colour and depth, then the kept colour frames and the ground truth, are associated as the
benchmark's ``associate.py`` does (:func:`associate`): every pair closer than ``max_dt_s``
(default 0.02 s) is a candidate, candidates are taken closest first, and a stamp is used at
most once. Colour frames left without a depth map or a pose are dropped (counted in the
record). The file lists must be in time order with one stamp per file (the benchmark's reader
would sort them and keep the last line of a repeated stamp, dropping a frame unseen); a
repeated pose stamp in the ground truth keeps its last line, as the benchmark's reader does.

The camera comes from, in this order: an intrinsics yaml given by the caller; a named TUM
camera (``fr1``, ``fr2``, ``fr3``: the benchmark's published calibration of each Kinect,
distortion included); the folder's ``egs_export.yaml`` (an egs-bench export); the folder's
name (TUM names its sequences ``rgbd_dataset_freiburgN_...``). Otherwise opening fails.

**Generic**: a colour image folder, a depth PNG folder, a TUM trajectory and an intrinsics
yaml. Images and depth maps are taken in natural name order (``frame2`` before ``frame10``) and
paired with the trajectory's poses by position: the three counts must agree.

**Intrinsics yaml** (OpenCV's pixel convention, pixel centres at integers, as published by TUM
and ROS; egs-bench adds 0.5 to ``cx, cy`` on reading, docs/design.md §2)::

    fx: 517.3           # required: focal lengths and principal point in pixels
    fy: 516.5
    cx: 318.6
    cy: 255.3
    width: 640          # optional; must match the images when given
    height: 480
    depth_scale: 5000   # PNG value per metre: required for the generic layout, 5000 for TUM
    distortion: [0.2624, -0.9531, -0.0054, 0.0026, 1.1633]   # optional: k1 k2 p1 p2 [k3]

The keys may also sit under ``camera:`` or ``camera_opencv:`` (so an export's
``egs_export.yaml`` serves as one). Frames with a distortion are undistorted to the same
``fx, fy, cx, cy`` on reading (colour bilinear, depth nearest neighbour).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, get_args

import numpy as np
import yaml

from egs_bench.datasets.replica import ReplicaScene, check_headers, read_replica
from egs_bench.errors import ConfigError, InputError
from egs_bench.fileio import read_text
from egs_bench.geometry import Intrinsics, read_tum
from egs_bench.images import image_header

RgbdLayout = Literal["replica", "tum-rgbd", "generic"]
LAYOUTS: tuple[RgbdLayout, ...] = get_args(RgbdLayout)
TUM_DEPTH_SCALE = 5000.0
#: associate.py's default --max_difference
DEFAULT_MAX_DT_S = 0.02
EXPORT_MANIFEST = "egs_export.yaml"


@dataclass(frozen=True)
class TumCamera:
    """A camera of the TUM RGB-D benchmark (OpenCV pixel convention), 640x480."""

    fx: float
    fy: float
    cx: float
    cy: float
    distortion: tuple[float, ...]


#: the benchmark's published colour-camera calibrations ("File Formats" / "Intrinsic Camera
#: Calibration of the Kinect" pages); freiburg3's images were already undistorted
TUM_CAMERAS = {
    "fr1": TumCamera(517.3, 516.5, 318.6, 255.3, (0.2624, -0.9531, -0.0054, 0.0026, 1.1633)),
    "fr2": TumCamera(520.9, 521.0, 325.1, 249.7, (0.2312, -0.7849, -0.0033, -0.0001, 0.9172)),
    "fr3": TumCamera(535.4, 539.2, 320.1, 247.6, ()),
}
_TUM_SIZE = (640, 480)
_FOLDER_CAMERA_RE = re.compile(r"freiburg([123])", re.IGNORECASE)
_COLOUR_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")
_DEPTH_SUFFIXES = (".png", ".tif", ".tiff")


@dataclass(frozen=True)
class CameraFile:
    """What an intrinsics yaml says (``cx, cy`` already in egs-bench's convention).

    Attributes:
        path: the file.
        fx, fy, cx, cy: pinhole parameters in pixels.
        width, height: image size, or None when the file does not give it.
        depth_scale: PNG value per metre, or None.
        distortion: OpenCV ``k1 k2 p1 p2 [k3 ...]``, empty for none.
    """

    path: Path
    fx: float
    fy: float
    cx: float
    cy: float
    width: int | None
    height: int | None
    depth_scale: float | None
    distortion: tuple[float, ...]


@dataclass(frozen=True)
class RGBDInput:
    """Where an RGB-D + pose sequence is and in which layout (see the module docstring).

    Attributes:
        layout: one of :data:`LAYOUTS`.
        path: the scene folder (``replica``, ``tum-rgbd``).
        rgb_dir, depth_dir, trajectory: the generic layout's colour folder, depth folder and
            TUM trajectory.
        camera: ``cam_params.json`` (replica) or an intrinsics yaml (the others).
        tum_camera: ``fr1``, ``fr2`` or ``fr3`` (tum-rgbd only).
        max_dt_s: association window of the TUM layout, seconds.
    """

    layout: RgbdLayout = "replica"
    path: Path | None = None
    rgb_dir: Path | None = None
    depth_dir: Path | None = None
    trajectory: Path | None = None
    camera: Path | None = None
    tum_camera: str | None = None
    max_dt_s: float = DEFAULT_MAX_DT_S

    def __post_init__(self) -> None:
        if self.layout not in LAYOUTS:
            raise ConfigError(f"--layout must be one of {', '.join(LAYOUTS)}, "
                              f"not {self.layout!r}")
        generic = (self.rgb_dir, self.depth_dir, self.trajectory)
        if self.layout == "generic":
            if self.path is not None:
                raise ConfigError("--layout generic takes --rgb-dir, --depth-dir, --trajectory "
                                  "and --intrinsics, not --input")
            if any(p is None for p in (*generic, self.camera)):
                raise ConfigError("--layout generic needs --rgb-dir, --depth-dir, --trajectory "
                                  "and --intrinsics")
        else:
            if self.path is None:
                raise ConfigError(f"--layout {self.layout} needs --input FOLDER")
            if any(p is not None for p in generic):
                raise ConfigError("--rgb-dir, --depth-dir and --trajectory only work with "
                                  "--layout generic")
        if self.tum_camera is not None:
            if self.layout != "tum-rgbd":
                raise ConfigError("--tum-camera only works with --layout tum-rgbd")
            if self.tum_camera not in TUM_CAMERAS:
                raise ConfigError(f"--tum-camera must be one of {', '.join(TUM_CAMERAS)}, "
                                  f"not {self.tum_camera!r}")
            if self.camera is not None:
                raise ConfigError("give --tum-camera or --intrinsics, not both")
        if not (math.isfinite(self.max_dt_s) and self.max_dt_s > 0):
            raise ConfigError(f"--max-dt must be a positive number of seconds, "
                              f"not {self.max_dt_s}")

    def inputs(self) -> list[Path]:
        """Every path the input consists of (never to be replaced by an output)."""
        paths = (self.path, self.rgb_dir, self.depth_dir, self.trajectory, self.camera)
        return [p for p in paths if p is not None]

    def open(self, *, check_image_headers: bool = True) -> ReplicaScene:
        """Open and validate the scene (see :func:`read_tum_rgbd`, :func:`read_generic_rgbd`)."""
        if self.layout == "replica":
            assert self.path is not None  # checked in __post_init__
            return read_replica(self.path, cam_params=self.camera,
                                check_image_headers=check_image_headers)
        if self.layout == "tum-rgbd":
            assert self.path is not None
            return read_tum_rgbd(self.path, intrinsics=self.camera, tum_camera=self.tum_camera,
                                 max_dt_s=self.max_dt_s, check_image_headers=check_image_headers)
        assert self.rgb_dir and self.depth_dir and self.trajectory and self.camera
        return read_generic_rgbd(self.rgb_dir, self.depth_dir, self.trajectory, self.camera,
                                 check_image_headers=check_image_headers)


def associate(first_s: np.ndarray, second_s: np.ndarray, max_dt_s: float = DEFAULT_MAX_DT_S
              ) -> tuple[np.ndarray, np.ndarray]:
    """One-to-one nearest-time matching, the rule of the TUM benchmark's ``associate.py``.

    Every pair with ``|a - b| < max_dt_s`` is a candidate; candidates are accepted in order of
    increasing ``|a - b|`` (ties: earlier ``a``, then earlier ``b``) unless one of the two
    stamps is already matched.

    Args:
        first_s: sorted time stamps [N] (seconds).
        second_s: sorted time stamps [M] (seconds).
        max_dt_s: largest accepted difference (exclusive), seconds.

    Returns:
        ``(i, j)``: int64 index arrays [K] into ``first_s`` and ``second_s``, in increasing
        ``i`` (and, the matching being monotone for sorted inputs, increasing ``j``).
    """
    a = np.asarray(first_s, dtype=np.float64)
    b = np.asarray(second_s, dtype=np.float64)
    # candidates of a[i]: b[lo[i]:hi[i]], the stamps inside the open window around it
    lo = np.searchsorted(b, a - max_dt_s, side="left")
    hi = np.searchsorted(b, a + max_dt_s, side="right")
    counts = hi - lo
    ii = np.repeat(np.arange(len(a)), counts)
    jj = (np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts)
          + np.repeat(lo, counts))
    diff = np.abs(a[ii] - b[jj])
    keep = diff < max_dt_s
    ii, jj, diff = ii[keep], jj[keep], diff[keep]
    order = np.lexsort((jj, ii, diff))
    used_a = np.zeros(len(a), dtype=bool)
    used_b = np.zeros(len(b), dtype=bool)
    pairs = []
    for k in order:
        i, j = int(ii[k]), int(jj[k])
        if not used_a[i] and not used_b[j]:
            used_a[i] = used_b[j] = True
            pairs.append((i, j))
    pairs.sort()
    out = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    return out[:, 0].copy(), out[:, 1].copy()


def read_tum_list(path: str | Path) -> tuple[np.ndarray, list[str], int]:
    """Read a TUM file list (``rgb.txt``, ``depth.txt``): ``timestamp path`` per line.

    Commas and tabs count as spaces and ``#`` lines are comments, as in the benchmark's reader.
    The stamps must increase, as the trajectory readers require: the benchmark's reader sorts
    and keeps the last of a repeated stamp, which silently drops a frame. A line repeated
    exactly is counted and read once.

    Returns:
        ``(stamps [N] float64 seconds, increasing; paths [N] as written; repeated lines)``.

    Raises:
        InputError: missing or non-text file, a line without a stamp and a path, a stamp that
            is not a finite number, a stamp out of order or repeated for another file, or no
            entries.
    """
    path = Path(path)
    entries: dict[float, str] = {}
    lines = 0
    last: tuple[int, float] | None = None  # line number and stamp of the previous entry
    for lineno, line in enumerate(read_text(path, "file list").splitlines(), start=1):
        text = line.replace(",", " ").replace("\t", " ").strip()
        if not text or text.startswith("#"):
            continue
        parts = text.split()
        if len(parts) < 2:
            raise InputError(path, f"line {lineno}: expected 'timestamp path', "
                                   f"found {text[:80]!r}")
        try:
            stamp = float(parts[0])
        except ValueError:
            raise InputError(path, f"line {lineno}: time stamp {parts[0][:40]!r} is not a "
                                   "number") from None
        if not math.isfinite(stamp):
            raise InputError(path, f"line {lineno}: time stamp is not finite")
        if last is not None and stamp < last[1]:
            raise InputError(path, f"line {lineno}: time stamp {parts[0]} comes before the "
                                   f"{last[1]!r} of line {last[0]} (the list must be in time "
                                   "order)")
        if stamp in entries and entries[stamp] != parts[1]:
            raise InputError(path, f"line {lineno}: time stamp {parts[0]} of {parts[1]} is "
                                   f"also the stamp of {entries[stamp]} (one stamp per frame)")
        entries[stamp] = parts[1]
        last = (lineno, stamp)
        lines += 1
    if not entries:
        raise InputError(path, "lists no files")
    stamps = np.array(sorted(entries), dtype=np.float64)
    return stamps, [entries[float(t)] for t in stamps], lines - len(entries)


def read_camera_yaml(path: str | Path) -> CameraFile:
    """Read an intrinsics yaml (see the module docstring).

    Raises:
        InputError: naming the file: missing, not YAML, not a mapping, a required value missing,
            a value of the wrong type or sign, a distortion list of the wrong length.
    """
    path = Path(path)
    try:
        data = yaml.safe_load(read_text(path, "intrinsics file"))
    except yaml.YAMLError as exc:
        raise InputError(path, f"not valid YAML ({str(exc).splitlines()[0]})") from None
    if not isinstance(data, dict):
        raise InputError(path, "expected a YAML mapping with fx, fy, cx, cy")
    block = data
    for key in ("camera_opencv", "camera"):
        if isinstance(data.get(key), dict):
            block = data[key]
            break

    def number(key: str, required: bool) -> float | None:
        value = block.get(key, data.get(key))
        if value is None:
            if required:
                raise InputError(path, f"missing '{key}'")
            return None
        if isinstance(value, bool) or not isinstance(value, int | float) or not (
                math.isfinite(value) and value > 0):
            raise InputError(path, f"'{key}' must be a positive number, got {value!r}")
        return float(value)

    def integer(key: str) -> int | None:
        value = number(key, required=False)
        if value is not None and value != int(value):
            raise InputError(path, f"'{key}' must be a whole number of pixels, got {value!r}")
        return None if value is None else int(value)

    raw = block.get("distortion", data.get("distortion"))
    distortion: tuple[float, ...] = ()
    if raw is not None:
        if not isinstance(raw, list) or len(raw) not in (4, 5, 8) or not all(
                isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
                for v in raw):
            raise InputError(path, "'distortion' must be a list of 4, 5 or 8 numbers "
                                   f"(k1 k2 p1 p2 [k3 ...]), got {raw!r}")
        if any(v != 0 for v in raw):
            distortion = tuple(float(v) for v in raw)
    fx, fy, cx, cy = (number(k, required=True) for k in ("fx", "fy", "cx", "cy"))
    assert fx is not None and fy is not None and cx is not None and cy is not None
    return CameraFile(path, fx, fy, cx + 0.5, cy + 0.5, integer("width"), integer("height"),
                      number("depth_scale", required=False), distortion)


def read_tum_rgbd(
    folder: str | Path, *, intrinsics: str | Path | None = None, tum_camera: str | None = None,
    max_dt_s: float = DEFAULT_MAX_DT_S, check_image_headers: bool = True,
) -> ReplicaScene:
    """Open and validate a TUM RGB-D folder (see the module docstring).

    Args:
        folder: holding ``rgb.txt``, ``depth.txt`` and ``groundtruth.txt``.
        intrinsics: an intrinsics yaml; its ``depth_scale`` (default 5000) applies.
        tum_camera: ``fr1``, ``fr2`` or ``fr3`` instead of a yaml.
        max_dt_s: association window, seconds.
        check_image_headers: check every associated image's size and type on open.

    Returns:
        The scene: associated frames in time order, each frame's colour stamp in
        ``timestamps_s``, the association counts in ``record``.

    Raises:
        InputError: naming the file: a missing folder or list, a malformed list or trajectory,
            a listed image that does not exist, fewer than 2 associated frames, no camera, a bad
            intrinsics file, images of the wrong size.
    """
    root = Path(folder)
    if not root.is_dir():
        raise InputError(root, "TUM RGB-D folder does not exist")
    names = {"rgb": root / "rgb.txt", "depth": root / "depth.txt",
             "groundtruth": root / "groundtruth.txt"}
    for name, path in names.items():
        if not path.is_file():
            raise InputError(path, f"missing (a TUM RGB-D folder holds rgb.txt, depth.txt and "
                                   f"groundtruth.txt; {name} not found)")
    t_rgb, rgb_files, rgb_repeats = read_tum_list(names["rgb"])
    t_depth, depth_files, depth_repeats = read_tum_list(names["depth"])
    gt = read_tum(names["groundtruth"])
    # the benchmark's reader keeps the last line of a repeated stamp
    t_gt, gt_rows = np.unique(gt.timestamps[::-1], return_index=True)
    gt_rows = len(gt.timestamps) - 1 - gt_rows
    i_rgb, i_depth = associate(t_rgb, t_depth, max_dt_s)
    if len(i_rgb) < 2:
        raise InputError(names["depth"], f"only {len(i_rgb)} of {len(t_rgb)} colour frames have "
                                         f"a depth map within {max_dt_s} s; at least 2 needed")
    k_rgb, k_gt = associate(t_rgb[i_rgb], t_gt, max_dt_s)
    if len(k_rgb) < 2:
        raise InputError(names["groundtruth"], f"only {len(k_rgb)} of {len(i_rgb)} colour + "
                                               f"depth frames have a pose within {max_dt_s} s "
                                               f"(poses span {t_gt[0]:.3f}..{t_gt[-1]:.3f} s, "
                                               f"frames {t_rgb[0]:.3f}..{t_rgb[-1]:.3f} s); at "
                                               "least 2 needed")
    i_rgb, i_depth, i_gt = i_rgb[k_rgb], i_depth[k_rgb], gt_rows[k_gt]
    rgb_paths = tuple(_listed_file(root, rgb_files[i], names["rgb"]) for i in i_rgb)
    depth_paths = tuple(_listed_file(root, depth_files[i], names["depth"]) for i in i_depth)
    camera, camera_file, scale, distortion = _tum_camera(root, intrinsics, tum_camera,
                                                         rgb_paths[0])
    stamps = t_rgb[i_rgb]
    record = {
        "association": {
            "max_dt_s": max_dt_s,
            "colour_listed": len(t_rgb), "depth_listed": len(t_depth), "poses_listed": len(t_gt),
            "frames": len(i_rgb), "colour_dropped": len(t_rgb) - len(i_rgb),
            "repeated_stamps_dropped": {"rgb": rgb_repeats, "depth": depth_repeats,
                                        "groundtruth": len(gt.timestamps) - len(t_gt)},
            "max_depth_dt_s": float(np.abs(stamps - t_depth[i_depth]).max()),
            "max_pose_dt_s": float(np.abs(stamps - gt.timestamps[i_gt]).max()),
            "largest_frame_gap_s": float(np.diff(stamps).max()),
        },
        "camera_source": f"TUM {tum_camera or _folder_camera(root)} calibration"
                         if camera_file is None else Path(camera_file),
    }
    scene = ReplicaScene(
        path=root, rgb_paths=rgb_paths, depth_paths=depth_paths,
        poses=gt.poses[i_gt], intrinsics=camera, depth_scale=scale,
        cam_params_path=camera_file,
        distortion=distortion, layout="tum-rgbd", timestamps_s=stamps, record=record,
    )
    if check_image_headers:
        check_headers(scene)
    return scene


def read_generic_rgbd(
    rgb_dir: str | Path, depth_dir: str | Path, trajectory: str | Path,
    intrinsics: str | Path, *, check_image_headers: bool = True,
) -> ReplicaScene:
    """Open and validate the generic layout (see the module docstring).

    Args:
        rgb_dir: colour images (8-bit PNG/JPEG/BMP/TIFF), natural name order.
        depth_dir: 16-bit one-channel depth PNGs (or TIFFs), natural name order.
        trajectory: TUM trajectory with one pose per image, in the same order.
        intrinsics: intrinsics yaml with a ``depth_scale``.
        check_image_headers: check every image's size and type on open.

    Raises:
        InputError: naming the folder or file: missing, empty, counts that disagree, a bad
            trajectory or intrinsics file, no ``depth_scale``, images of the wrong size.
    """
    rgb_dir, depth_dir, trajectory = Path(rgb_dir), Path(depth_dir), Path(trajectory)
    rgb = _list_folder(rgb_dir, _COLOUR_SUFFIXES, "colour")
    depth = _list_folder(depth_dir, _DEPTH_SUFFIXES, "depth")
    if len(depth) != len(rgb):
        raise InputError(depth_dir, f"{len(depth)} depth maps for {len(rgb)} colour images in "
                                    f"{rgb_dir}")
    traj = read_tum(trajectory, min_poses=2)
    if len(traj) != len(rgb):
        raise InputError(trajectory, f"{len(traj)} poses for {len(rgb)} images in {rgb_dir} "
                                     "(the generic layout pairs them one to one, in order)")
    if (np.diff(traj.timestamps) <= 0).any():
        raise InputError(trajectory, "time stamps must increase strictly (one pose per image)")
    cam = read_camera_yaml(intrinsics)
    if cam.depth_scale is None:
        raise InputError(cam.path, "missing 'depth_scale' (depth PNG value per metre, e.g. "
                                   "1000 for millimetres, 5000 for TUM)")
    scene = ReplicaScene(
        path=rgb_dir, rgb_paths=tuple(rgb), depth_paths=tuple(depth),
        poses=traj.poses, intrinsics=_intrinsics(cam, rgb[0]),
        depth_scale=cam.depth_scale, cam_params_path=cam.path, distortion=cam.distortion,
        layout="generic", timestamps_s=traj.timestamps.copy(),
        # paths, which the sequence's meta.yaml records relative to the output
        record={"depth_dir": depth_dir, "trajectory": trajectory, "camera_source": cam.path},
    )
    if check_image_headers:
        check_headers(scene)
    return scene


# --- helpers -----------------------------------------------------------------------------------


def _tum_camera(root: Path, explicit: str | Path | None, name: str | None, first_rgb: Path
                ) -> tuple[Intrinsics, Path | None, float, tuple[float, ...]]:
    """Intrinsics, the camera file they came from (None: a TUM calibration), the depth scale
    and the distortion of a TUM folder."""
    if name is None and explicit is None:
        manifest = root / EXPORT_MANIFEST
        if manifest.is_file():
            explicit = manifest
        else:
            name = _folder_camera(root)
    if name is not None:
        cam = TUM_CAMERAS[name]
        width, height = _TUM_SIZE
        intr = Intrinsics(cam.fx, cam.fy, cam.cx + 0.5, cam.cy + 0.5, width, height)
        return intr, None, TUM_DEPTH_SCALE, cam.distortion
    assert explicit is not None
    file = read_camera_yaml(explicit)
    scale = TUM_DEPTH_SCALE if file.depth_scale is None else file.depth_scale
    return _intrinsics(file, first_rgb), file.path, scale, file.distortion


def _folder_camera(root: Path) -> str:
    """The TUM camera a folder's name names (``rgbd_dataset_freiburg2_desk`` -> ``fr2``)."""
    match = _FOLDER_CAMERA_RE.search(root.resolve().name)
    if match is None:
        raise InputError(root, "no camera intrinsics: give --intrinsics FILE.yaml or "
                               f"--tum-camera {'|'.join(TUM_CAMERAS)} (the folder has no "
                               f"{EXPORT_MANIFEST} and its name names no freiburg camera)")
    return f"fr{match.group(1)}"


def _intrinsics(cam: CameraFile, first_rgb: Path) -> Intrinsics:
    """Intrinsics of ``cam``, the size taken from the first image when the file has none."""
    if cam.width is None or cam.height is None:
        width, height, _ = image_header(first_rgb)
    else:
        width, height = cam.width, cam.height
    if not (0 < cam.cx < width and 0 < cam.cy < height):
        raise InputError(cam.path, f"principal point ({cam.cx - 0.5}, {cam.cy - 0.5}) lies "
                                   f"outside the {width}x{height} image")
    return Intrinsics(cam.fx, cam.fy, cam.cx, cam.cy, int(width), int(height))


def _listed_file(root: Path, name: str, listing: Path) -> Path:
    path = root / name
    if not path.is_file():
        raise InputError(path, f"listed in {listing.name} but not found")
    return path


def _natural_key(path: Path) -> list[Any]:
    """Sort key putting ``frame2`` before ``frame10``."""
    return [int(part) if part.isdigit() else part.lower()
            for part in re.split(r"(\d+)", path.name)]


def _list_folder(folder: Path, suffixes: tuple[str, ...], what: str) -> list[Path]:
    if not folder.is_dir():
        raise InputError(folder, f"{what} folder does not exist")
    files = sorted((p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in suffixes),
                   key=_natural_key)
    if not files:
        raise InputError(folder, f"holds no {what} image ({', '.join(suffixes)})")
    return files
