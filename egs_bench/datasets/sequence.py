"""The canonical sequence folder (docs/design.md §3): reader with validation, and writer.

```
<seq>/meta.yaml               calibration, generator, event thresholds, exposure, camera response
                              (keys: :data:`META_KEYS`)
<seq>/frames.csv              index, t_start_us, t_end_us, rgb, depth, sharp
                              (columns: :data:`FRAME_COLUMN_DOCS`)
<seq>/rgb/%06d.png            observed (blurred) 8-bit sRGB frames
<seq>/depth/%06d.png          depth at exposure end, uint16, metres * depth_scale (0 = invalid)
<seq>/sharp/%06d.png          sharp ground truth at exposure end (synthetic data only)
<seq>/events.h5               DSEC-style events (see :mod:`egs_bench.datasets.events`)
<seq>/groundtruth.txt         TUM, camera-to-world pose at each frame's exposure end
<seq>/groundtruth_dense.txt   optional high-rate ground truth (synthetic data)
```
"""

from __future__ import annotations

import csv
import functools
from pathlib import Path
from typing import Any, Literal, overload

import numpy as np
import yaml

from egs_bench.datasets.events import EventStream, EventWriter
from egs_bench.errors import InputError
from egs_bench.fileio import read_text, to_plain
from egs_bench.geometry import Intrinsics, Trajectory, read_tum, write_tum
from egs_bench.images import (
    image_size,
    read_depth_png,
    read_ldr_image,
    write_depth_png,
    write_ldr_image,
)

FORMAT_VERSION = 1
FRAME_COLUMNS = ("index", "t_start_us", "t_end_us", "rgb", "depth", "sharp")
REQUIRED_META = ("width", "height", "fx", "fy", "cx", "cy", "depth_scale")
#: what each ``frames.csv`` column holds (one row per frame; the reference page lists these)
FRAME_COLUMN_DOCS = {
    "index": "frame number: 0, 1, 2, ... in order",
    "t_start_us": "exposure start, integer microseconds",
    "t_end_us": "exposure end, integer microseconds, after t_start_us and at most the next "
                "frame's t_start_us; the frame's timestamp",
    "rgb": "observed image, path relative to the folder",
    "depth": "depth map at the exposure end, path relative to the folder",
    "sharp": "sharp ground-truth image, path relative to the folder (empty: none; the column "
             "may be absent)",
}
#: the keys of ``meta.yaml`` (:data:`REQUIRED_META` required, the others optional) and what
#: each holds; :func:`read_meta` checks them. A writer may add records of its own (an importer's
#: settings, say), which readers ignore.
META_KEYS = {
    "width": "image width, pixels (integer)",
    "height": "image height, pixels (integer)",
    "fx": "focal length along x, pixels",
    "fy": "focal length along y, pixels",
    "cx": "principal point x, pixels (inside the image)",
    "cy": "principal point y, pixels (inside the image)",
    "depth_scale": "depth PNG value per metre (e.g. 5000: 1 unit = 0.2 mm)",
    "format_version": f"version of this folder format (written: {FORMAT_VERSION})",
    "num_frames": "frames listed in frames.csv (checked when present)",
    "name": "the sequence's name (default: the folder's name)",
    "source": "where the frames come from (\"real\" for recordings; otherwise what generated "
              "them)",
    "pixel_convention": "where a pixel's centre lies: (u + 0.5, v + 0.5) for pixel (u, v)",
    "distortion": "lens distortion of the images (zeros or a note: they are undistorted)",
    "has_events": "whether events.h5 exists (default true)",
    "eps": "offset of the log intensity log(luma + eps) the events are defined on (> 0)",
    "event_thresholds": "contrast thresholds {pos: C+, neg: C-} in log intensity (> 0)",
    "sigma": "std of the per-pixel threshold mismatch of the event simulator, log units (>= 0)",
    "refractory_us": "refractory period of the event simulator, microseconds (>= 0)",
    "noise": "noise settings of the event simulator, e.g. {shot_noise_rate_hz}",
    "event_seed": "random seed of the event simulator",
    "exposure_us": "exposure time, microseconds (> 0)",
    "frame_rate": "frames per second (> 0)",
    "crf": "the camera response: a mapping describing the LDR response of the rgb images",
    "generator": "what wrote the folder: {name, version} and the generator's own settings",
    "sampling": "temporal sampling of the generator's latent source: its settings and statistics",
}
#: events may trail the last exposure end by this much (a sensor records continuously)
EVENT_TIME_MARGIN_US = 1_000_000


#: a camera whose field of view lies outside this range (degrees) has absurd intrinsics
FOV_RANGE_DEG = (1.0, 170.0)


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) \
        and bool(np.isfinite(value))


def read_meta(path: Path) -> dict[str, Any]:
    """Read and check ``meta.yaml``; raises :class:`InputError` naming the file.

    Checked: UTF-8 YAML mapping; the required keys are positive numbers; integer image size;
    intrinsics that describe a camera (field of view between 1 and 170 degrees, principal point
    inside the image); and, where present, ``eps``, both ``event_thresholds``, ``frame_rate``
    and ``exposure_us`` positive, ``has_events`` a boolean, ``sigma`` and ``refractory_us`` not
    negative, ``crf`` a mapping, ``name`` text.
    """
    if not path.is_file():
        raise InputError(path, "meta.yaml not found (is this a sequence folder?)")
    text = read_text(path)
    try:
        meta = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise InputError(path, f"not valid YAML ({exc})".replace("\n", " ")) from None
    if not isinstance(meta, dict):
        raise InputError(path, "expected a mapping of keys to values")
    missing = [k for k in REQUIRED_META if k not in meta]
    if missing:
        raise InputError(path, f"missing keys: {', '.join(missing)}")
    for key in REQUIRED_META:
        value = meta[key]
        if not _is_number(value) or value <= 0:
            raise InputError(path, f"{key} must be a positive number, got {value!r}")
    for key in ("width", "height"):
        if int(meta[key]) != meta[key]:
            raise InputError(path, f"{key} must be an integer")
    _check_camera(path, meta)
    _check_optional(path, meta)
    return meta


def _check_camera(path: Path, meta: dict[str, Any]) -> None:
    lo, hi = FOV_RANGE_DEG
    for f, size, axis in (("fx", "width", "horizontal"), ("fy", "height", "vertical")):
        fov = float(np.degrees(2 * np.arctan(meta[size] / (2 * meta[f]))))
        if not lo <= fov <= hi:
            raise InputError(path, f"{f} = {meta[f]!r} gives a {axis} field of view of "
                                   f"{fov:.3g} degrees for {size} {meta[size]} (plausible: "
                                   f"{lo:g} to {hi:g}); is {f} in pixels?")
    for c, size in (("cx", "width"), ("cy", "height")):
        if not 0 <= meta[c] <= meta[size]:
            raise InputError(path, f"{c} = {meta[c]!r} lies outside the image (0 to "
                                   f"{size} {meta[size]})")


def _check_optional(path: Path, meta: dict[str, Any]) -> None:
    if "has_events" in meta and not isinstance(meta["has_events"], bool):
        raise InputError(path, f"has_events must be true or false, got {meta['has_events']!r}")
    if "eps" in meta and (not _is_number(meta["eps"]) or meta["eps"] <= 0):
        raise InputError(path, f"eps (the offset of log(luma + eps)) must be a positive number, "
                               f"got {meta['eps']!r}")
    thresholds = meta.get("event_thresholds")
    if thresholds is not None:
        if not isinstance(thresholds, dict):
            raise InputError(path, "event_thresholds must be a mapping {pos: C+, neg: C-}")
        for key in ("pos", "neg"):
            value = thresholds.get(key)
            if value is not None and (not _is_number(value) or value <= 0):
                raise InputError(path, f"event_thresholds.{key} must be a positive number "
                                       f"(log-intensity contrast), got {value!r}")
    for key in ("sigma", "refractory_us"):
        value = meta.get(key)
        if value is not None and (not _is_number(value) or value < 0):
            raise InputError(path, f"{key} must be a number >= 0, got {value!r}")
    for key in ("frame_rate", "exposure_us"):
        value = meta.get(key)
        if value is not None and (not _is_number(value) or value <= 0):
            raise InputError(path, f"{key} must be a positive number, got {value!r}")
    if meta.get("crf") is not None and not isinstance(meta["crf"], dict):
        raise InputError(path, f"crf must be a mapping describing the camera response, got "
                               f"{meta['crf']!r}")
    if meta.get("name") is not None and not isinstance(meta["name"], str | int | float):
        raise InputError(path, f"name must be text, got {meta['name']!r}")


def _read_frames_csv(path: Path) -> list[dict[str, str]]:
    if not path.is_file():
        raise InputError(path, "frames.csv not found")
    try:
        with path.open(newline="", encoding="utf-8") as handle:
            reader = csv.DictReader(handle)
            missing = [c for c in FRAME_COLUMNS[:5] if c not in (reader.fieldnames or [])]
            if missing:
                raise InputError(path, f"missing columns: {', '.join(missing)}")
            rows = list(reader)
    except (UnicodeDecodeError, csv.Error) as exc:
        raise InputError(path, f"not a readable CSV table ({exc})") from None
    if not rows:
        raise InputError(path, "no frames listed")
    return rows


class Sequence:
    """A validated canonical sequence folder. Images are read lazily; see the module docstring.

    Use :meth:`open`. All times are int64 microseconds; poses are ``T_wc`` [4, 4] float64.
    """

    def __init__(self, path: Path, meta: dict[str, Any], frames: list[dict[str, str]],
                 groundtruth: Trajectory, events: EventStream | None) -> None:
        self.path = path
        self.meta = meta
        self._frames = frames
        self._groundtruth = groundtruth
        self._events = events
        self.t_start_us = np.array([int(r["t_start_us"]) for r in frames], dtype=np.int64)
        self.t_end_us = np.array([int(r["t_end_us"]) for r in frames], dtype=np.int64)

    # ---------------------------------------------------------------- opening and checks
    @classmethod
    def open(cls, path: str | Path, check_images: bool = True) -> Sequence:
        """Open and validate a sequence folder.

        Checks: required files exist; meta.yaml keys; frames.csv columns, indices, non-empty
        and non-overlapping exposure windows; one ground-truth pose per frame at exposure end;
        every listed image exists and (with ``check_images``) has the right size (header only);
        the event file's sorting, time range, coordinates and index.

        Raises:
            InputError: naming the offending file and the problem.
        """
        path = Path(path)
        if not path.is_dir():
            raise InputError(path, "sequence folder not found")
        meta = read_meta(path / "meta.yaml")
        frames = _read_frames_csv(path / "frames.csv")
        _check_frame_table(path / "frames.csv", frames)
        listed = meta.get("num_frames")
        if listed is not None and listed != len(frames):
            raise InputError(path / "meta.yaml", f"num_frames is {listed!r} but frames.csv "
                                                 f"lists {len(frames)} frames")
        gt_path = path / "groundtruth.txt"
        groundtruth = read_tum(gt_path)
        if len(groundtruth) != len(frames):
            raise InputError(gt_path, f"{len(groundtruth)} poses for {len(frames)} frames "
                                      "(need one pose per frame)")
        t_end = np.array([int(r["t_end_us"]) for r in frames], dtype=np.float64) * 1e-6
        if np.abs(groundtruth.timestamps - t_end).max() > 2e-6:
            raise InputError(gt_path, "pose timestamps differ from the frames' exposure ends")
        width, height = int(meta["width"]), int(meta["height"])
        _check_images(path, frames, width, height, check_images)
        events = None
        if meta.get("has_events", True):
            t_max = int(frames[-1]["t_end_us"]) + EVENT_TIME_MARGIN_US
            events = EventStream(path / "events.h5", width, height, t_max_us=t_max)
        return cls(path, meta, frames, groundtruth, events)

    # ---------------------------------------------------------------- properties
    def __len__(self) -> int:
        return len(self._frames)

    def __repr__(self) -> str:
        return f"Sequence({self.name!r}, {len(self)} frames, {self.width}x{self.height})"

    @property
    def name(self) -> str:
        return str(self.meta.get("name") or self.path.name)

    @property
    def width(self) -> int:
        return int(self.meta["width"])

    @property
    def height(self) -> int:
        return int(self.meta["height"])

    @functools.cached_property
    def intrinsics(self) -> Intrinsics:
        m = self.meta
        return Intrinsics(float(m["fx"]), float(m["fy"]), float(m["cx"]), float(m["cy"]),
                          self.width, self.height)

    @property
    def eps(self) -> float:
        return float(self.meta.get("eps", 1e-3))

    @property
    def pos_threshold(self) -> float:
        """Positive contrast threshold C+ (log units); 0.25 when ``meta.yaml`` has none."""
        return self._threshold("pos")

    @property
    def neg_threshold(self) -> float:
        """Negative contrast threshold C- (log units); 0.25 when ``meta.yaml`` has none."""
        return self._threshold("neg")

    def _threshold(self, key: str) -> float:
        value = (self.meta.get("event_thresholds") or {}).get(key)
        return float(value) if value is not None else 0.25

    @property
    def exposure_us(self) -> int:
        return int(np.median(self.t_end_us - self.t_start_us))

    @property
    def depth_scale(self) -> float:
        return float(self.meta["depth_scale"])

    @property
    def timestamps_s(self) -> np.ndarray:
        """Exposure ends in seconds, [N] float64 (the TUM stamps of the ground truth)."""
        return self._groundtruth.timestamps

    @property
    def poses(self) -> np.ndarray:
        """Ground-truth ``T_wc`` at each exposure end, [N, 4, 4] float64."""
        return self._groundtruth.poses

    @functools.cached_property
    def dense_trajectory(self) -> Trajectory | None:
        path = self.path / "groundtruth_dense.txt"
        return read_tum(path) if path.is_file() else None

    @property
    def has_events(self) -> bool:
        return self._events is not None

    @property
    def events(self) -> EventStream:
        if self._events is None:
            raise InputError(self.path / "meta.yaml", "this sequence has no events")
        return self._events

    @property
    def has_sharp(self) -> bool:
        return bool(self._frames[0].get("sharp"))

    # ---------------------------------------------------------------- frame data
    def _frame_file(self, i: int, column: str) -> Path | None:
        name = self._frames[i].get(column) or ""
        return self.path / name if name else None

    @overload
    def frame_path(self, i: int, column: Literal["rgb", "depth"]) -> Path: ...

    @overload
    def frame_path(self, i: int, column: str) -> Path | None: ...

    def frame_path(self, i: int, column: str) -> Path | None:
        """File of frame ``i``'s ``"rgb"``, ``"depth"`` or ``"sharp"`` image (None if absent;
        :meth:`open` refuses a frame without an rgb or depth file)."""
        return self._frame_file(i, column)

    def rgb(self, i: int) -> np.ndarray:
        """Observed (blurred) LDR frame ``i``: uint8 [H, W, 3], sRGB."""
        return _read_rgb(self._frame_file(i, "rgb"), self.width, self.height)

    def sharp(self, i: int) -> np.ndarray | None:
        """Sharp ground truth at exposure end of frame ``i``: uint8 [H, W, 3], or None."""
        path = self._frame_file(i, "sharp")
        return _read_rgb(path, self.width, self.height) if path else None

    def depth(self, i: int) -> np.ndarray:
        """Depth at exposure end of frame ``i``: float32 [H, W] metres, 0 = invalid."""
        return _read_depth(self._frame_file(i, "depth"), self.width, self.height,
                           self.depth_scale)

    def exposure(self, i: int) -> tuple[int, int]:
        """Exposure window ``(t_start_us, t_end_us)`` of frame ``i``."""
        return int(self.t_start_us[i]), int(self.t_end_us[i])

    def event_maps(self, i: int, edges_us: np.ndarray | None = None, k: int = 1) -> np.ndarray:
        """Signed event counts over sub-windows of frame ``i``'s exposure: int32 [K, H, W].

        ``edges_us`` [K+1] defaults to ``k`` equal sub-windows of the exposure.
        """
        if edges_us is None:
            t0, t1 = self.exposure(i)
            edges_us = np.round(np.linspace(t0, t1, k + 1)).astype(np.int64)
        return self.events.event_maps(edges_us)

    def validate_contents(self) -> None:
        """Decode every image and depth map (slow; ``egs-bench info`` runs it)."""
        for i in range(len(self)):
            self.rgb(i)
            self.depth(i)
            self.sharp(i)


def _check_frame_table(path: Path, frames: list[dict[str, str]]) -> None:
    try:
        index = np.array([int(r["index"]) for r in frames])
        t0 = np.array([int(r["t_start_us"]) for r in frames], dtype=np.int64)
        t1 = np.array([int(r["t_end_us"]) for r in frames], dtype=np.int64)
    except (TypeError, ValueError) as exc:
        raise InputError(path, f"index/t_start_us/t_end_us must be integers ({exc})") from None
    if (index != np.arange(len(frames))).any():
        raise InputError(path, "frame indices must be 0, 1, 2, ... in order")
    empty = t1 <= t0
    if empty.any():
        raise InputError(path, f"frame {int(np.argmax(empty))}: empty exposure window "
                               "(t_end_us <= t_start_us)")
    overlap = t0[1:] < t1[:-1]
    if overlap.any():
        i = int(np.argmax(overlap)) + 1
        raise InputError(path, f"frame {i}: exposure starts at {t0[i]} us, before frame {i - 1}'s "
                               f"exposure ends ({t1[i - 1]} us)")
    for r in frames:
        if not r.get("rgb") or not r.get("depth"):
            raise InputError(path, f"frame {r['index']}: empty rgb or depth file name")


def _check_images(root: Path, frames: list[dict[str, str]], width: int, height: int,
                  check_size: bool) -> None:
    for r in frames:
        for column in ("rgb", "depth", "sharp"):
            name = r.get(column) or ""
            if not name:
                continue
            file = root / name
            if not file.is_file():
                raise InputError(file, f"{column} image of frame {r['index']} not found")
            if check_size and file.suffix != ".npy":
                size = image_size(file)
                if size != (width, height):
                    raise InputError(file, f"image is {size[0]}x{size[1]}, expected "
                                           f"{width}x{height} (meta.yaml)")


def _check_shape(path: Path, shape: tuple[int, ...], width: int, height: int) -> None:
    if shape[:2] != (height, width):
        raise InputError(path, f"image is {shape[1]}x{shape[0]}, expected {width}x{height}")


def _read_rgb(path: Path | None, width: int, height: int) -> np.ndarray:
    if path is None:
        raise ValueError("no image")
    img = read_ldr_image(path)
    _check_shape(path, img.shape, width, height)
    return img


def _read_depth(path: Path | None, width: int, height: int, scale: float) -> np.ndarray:
    if path is None:
        raise ValueError("no depth image")
    if path.suffix == ".npy":
        try:
            depth = np.load(path, allow_pickle=False).astype(np.float32)
        except (OSError, ValueError, EOFError) as exc:
            raise InputError(path, f"unreadable depth array ({exc})") from None
    else:
        depth = read_depth_png(path).astype(np.float32) / np.float32(scale)
    if depth.ndim != 2:
        raise InputError(path, f"depth must be a 2-D array, got shape {depth.shape}")
    _check_shape(path, depth.shape, width, height)
    if not np.isfinite(depth).all():
        raise InputError(path, "depth contains NaN or infinite values")
    if (depth < 0).any():
        raise InputError(path, "depth contains negative values")
    return depth


class SequenceWriter:
    """Writes a canonical sequence folder frame by frame (use inside ``atomic_path``).

    Args:
        root: the (temporary) folder to fill; created if needed.
        meta: ``meta.yaml`` contents; must include the keys of ``REQUIRED_META``.
        t_offset_us: event time offset stored in ``events.h5`` (``None``: no event file).
        with_sharp: whether frames carry a sharp ground-truth image.
    """

    def __init__(self, root: Path, meta: dict[str, Any], t_offset_us: int | None = 0,
                 with_sharp: bool = True) -> None:
        missing = [k for k in REQUIRED_META if k not in meta]
        if missing:
            raise ValueError(f"meta lacks {missing}")
        self.root = Path(root)
        self.meta = dict(meta)
        self.meta["format_version"] = FORMAT_VERSION
        self.meta["has_events"] = t_offset_us is not None
        self.with_sharp = with_sharp
        for sub in ("rgb", "depth") + (("sharp",) if with_sharp else ()):
            (self.root / sub).mkdir(parents=True, exist_ok=True)
        self.events = EventWriter(self.root / "events.h5", t_offset_us) \
            if t_offset_us is not None else None
        self._rows: list[dict[str, Any]] = []
        self._poses: list[np.ndarray] = []

    def __enter__(self) -> SequenceWriter:
        return self

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        if exc_type is not None:
            self.abort()

    def abort(self) -> None:
        """Close the event file unfinished (the folder is being discarded after an error)."""
        if self.events is not None:
            self.events.abort()

    def add_frame(self, t_start_us: int, t_end_us: int, rgb: np.ndarray, depth: np.ndarray,
                  pose: np.ndarray, sharp: np.ndarray | None = None) -> int:
        """Write frame images; ``rgb``/``sharp`` uint8 [H, W, 3], ``depth`` float [H, W] metres,
        ``pose`` the ``T_wc`` at exposure end. Returns the frame index."""
        i = len(self._rows)
        name = f"{i:06d}.png"
        if self.with_sharp:
            if sharp is None:
                raise ValueError("sharp image required (with_sharp=True)")
            write_ldr_image(self.root / "sharp" / name, sharp)
        write_ldr_image(self.root / "rgb" / name, rgb)
        write_depth_png(self.root / "depth" / name, encode_depth(depth, self.meta["depth_scale"]))
        self._rows.append({
            "index": i, "t_start_us": int(t_start_us), "t_end_us": int(t_end_us),
            "rgb": f"rgb/{name}", "depth": f"depth/{name}",
            "sharp": f"sharp/{name}" if self.with_sharp else "",
        })
        self._poses.append(np.asarray(pose, dtype=np.float64))
        return i

    def finish(self, dense_times_us: np.ndarray | None = None,
               dense_poses: np.ndarray | None = None) -> None:
        """Write frames.csv, groundtruth(.txt, _dense.txt), meta.yaml and close events."""
        if self.events is not None:
            self.events.close()
        with (self.root / "frames.csv").open("w", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=FRAME_COLUMNS)
            writer.writeheader()
            writer.writerows(self._rows)
        t_end = np.array([r["t_end_us"] for r in self._rows], dtype=np.int64)
        write_tum(self.root / "groundtruth.txt", t_end * 1e-6, np.stack(self._poses))
        if dense_times_us is not None and dense_poses is not None:
            write_tum(self.root / "groundtruth_dense.txt",
                      np.asarray(dense_times_us, dtype=np.int64) * 1e-6, dense_poses)
        self.meta["num_frames"] = len(self._rows)
        (self.root / "meta.yaml").write_text(yaml.safe_dump(to_plain(self.meta), sort_keys=False))


def encode_depth(depth_m: np.ndarray, scale: float) -> np.ndarray:
    """Metres [H, W] -> uint16 PNG values; depths beyond the 16-bit range become 0 (invalid)."""
    scaled = np.round(np.nan_to_num(np.asarray(depth_m, dtype=np.float64), nan=0.0) * scale)
    scaled[(scaled > 65535) | (scaled < 0)] = 0
    return scaled.astype(np.uint16)
