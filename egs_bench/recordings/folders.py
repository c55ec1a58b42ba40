"""Recordings stored as plain files: an image folder with a times file, a 16-bit depth PNG
folder with a times file, and a TUM trajectory of mocap poses.

Times files hold one row per image, in the images' name order; ``#`` starts a comment. Frame
times: two columns ``t_start t_end`` (the exposure window) or one column (a stamp whose meaning
and exposure are given separately). Depth times: one column. The unit is chosen by the caller
(microseconds by default; ``s`` and ``ns`` accepted).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Literal

import numpy as np

from egs_bench.errors import InputError
from egs_bench.fileio import read_text
from egs_bench.geometry import read_tum
from egs_bench.images import read_depth_png, read_ldr_image
from egs_bench.recordings.streams import (
    DepthStream,
    FrameStamp,
    FrameStream,
    PoseTrack,
    exposure_windows,
)

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")
TimesUnit = Literal["us", "ms", "s", "ns"]
UNIT_TO_US: dict[TimesUnit, float] = {"us": 1.0, "s": 1e6, "ms": 1e3, "ns": 1e-3}


def list_images(folder: Path) -> list[Path]:
    """Image files of ``folder`` sorted by name."""
    if not folder.is_dir():
        raise InputError(folder, "image folder not found")
    files = sorted(p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
    if not files:
        raise InputError(folder, f"holds no image ({', '.join(IMAGE_SUFFIXES)})")
    return files


def read_times(path: Path, columns: tuple[int, ...], unit: TimesUnit = "us") -> np.ndarray:
    """A whitespace/comma separated times file -> int64 microseconds [N, C].

    Raises:
        InputError: missing file, wrong column count, non-numbers, unsorted times.
    """
    if unit not in UNIT_TO_US:
        raise InputError(path, f"unknown time unit {unit!r} (us, ms, s, ns)")
    if not path.is_file():
        raise InputError(path, "times file not found")
    rows = []
    for lineno, line in enumerate(read_text(path, "times file").splitlines(), start=1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        parts = line.replace(",", " ").split()
        if len(parts) not in columns:
            raise InputError(path, f"line {lineno}: expected {' or '.join(map(str, columns))} "
                                   f"columns, found {len(parts)}")
        try:
            rows.append([float(v) for v in parts])
        except ValueError as exc:
            raise InputError(path, f"line {lineno}: not a number ({exc})") from None
    if not rows:
        raise InputError(path, "no times listed")
    if len({len(r) for r in rows}) != 1:
        raise InputError(path, "rows have different numbers of columns")
    t = np.round(np.asarray(rows, dtype=np.float64) * UNIT_TO_US[unit]).astype(np.int64)
    if (np.diff(t[:, 0]) < 0).any():
        raise InputError(path, "times are not sorted")
    return t


def frame_folder(folder: Path, times: Path, unit: TimesUnit, stamp: FrameStamp,
                 exposure_us: int | None) -> FrameStream:
    """Frames from an image folder and a times file (see the module docstring)."""
    files = list_images(folder)
    t = read_times(times, (1, 2), unit)
    if len(t) != len(files):
        raise InputError(times, f"{len(t)} times for {len(files)} images in {folder}")
    if t.shape[1] == 2:
        t0, t1 = t[:, 0], t[:, 1]
    elif exposure_us is None:
        raise InputError(times, "one time per frame: also give the exposure time (and what the "
                                "time marks: start, mid or end)")
    else:
        t0, t1 = exposure_windows(t[:, 0], int(exposure_us), stamp)
    return image_frames(str(folder), files, t0, t1)


def image_frames(label: str, files: list[Path], t_start_us: np.ndarray, t_end_us: np.ndarray
                 ) -> FrameStream:
    """Frames from image files and their exposure windows ([N] int64 us each); every image
    must have the first one's size."""
    first = read_ldr_image(files[0])
    h, w = first.shape[:2]

    def load(indices: list[int]) -> Iterator[tuple[int, np.ndarray]]:
        for i in indices:
            img = read_ldr_image(files[i])
            if img.shape[:2] != (h, w):
                raise InputError(files[i], f"image is {img.shape[1]}x{img.shape[0]}, the first "
                                           f"is {w}x{h}")
            yield i, img

    return FrameStream(label, t_start_us, t_end_us, w, h, load)


def depth_folder(folder: Path, times: Path, unit: TimesUnit, depth_scale: float
                 ) -> DepthStream:
    """16-bit depth PNGs (``value / depth_scale`` metres, 0 = invalid) and their times."""
    files = list_images(folder)
    t = read_times(times, (1,), unit)[:, 0]
    if len(t) != len(files):
        raise InputError(times, f"{len(t)} times for {len(files)} depth images in {folder}")
    return depth_images(str(folder), files, t, depth_scale)


def depth_images(label: str, files: list[Path], t_us: np.ndarray, depth_scale: float
                 ) -> DepthStream:
    """Depth maps from 16-bit PNGs (``value / depth_scale`` metres) and their times ([N] int64
    us); every map must have the first one's size."""
    first = _read_depth(files[0], depth_scale)
    h, w = first.shape

    def load(indices: list[int]) -> Iterator[tuple[int, np.ndarray]]:
        for i in indices:
            d = _read_depth(files[i], depth_scale)
            if d.shape != (h, w):
                raise InputError(files[i], f"depth is {d.shape[1]}x{d.shape[0]}, the first is "
                                           f"{w}x{h}")
            yield i, d

    return DepthStream(label, t_us, w, h, load)


def tum_track(path: Path) -> PoseTrack:
    """Mocap poses from a TUM file (``t tx ty tz qx qy qz qw``, seconds, body-to-world)."""
    traj = read_tum(path, min_poses=2)
    t = np.round(traj.timestamps * 1e6).astype(np.int64)
    return PoseTrack(str(path), t, traj.poses)


def _read_depth(path: Path, depth_scale: float) -> np.ndarray:
    raw = read_depth_png(path)
    return (raw.astype(np.float64) / depth_scale).astype(np.float32)
