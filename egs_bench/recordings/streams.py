"""What the readers (AEDAT4, ROS bags, folders) hand to the importer.

Times are int64 microseconds on the recording sensor's own clock; the importer moves them onto
the event camera's clock with ``calib.yaml``'s offsets. Images are loaded lazily and in order,
so a long recording is never held in memory at once.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np

from egs_bench.datasets.events import Events

#: What a frame's one time stamp marks in its exposure.
FrameStamp = Literal["start", "mid", "end"]


@dataclass
class FrameStream:
    """Intensity frames with their exposure windows.

    Attributes:
        label: where they come from (``file`` or ``file:topic``), for messages.
        t_start_us, t_end_us: exposure begin and end, [N] int64 (source clock).
        width, height: image size in pixels.
        load: ``load(indices)`` yields ``(index, image)`` for increasing ``indices``;
            ``image`` is uint8 [H, W, 3] RGB.
        sensor: the camera as the recording names it (AEDAT4: model and serial), if it does.
    """

    label: str
    t_start_us: np.ndarray
    t_end_us: np.ndarray
    width: int
    height: int
    load: Callable[[list[int]], Iterator[tuple[int, np.ndarray]]]
    sensor: str | None = None

    def __len__(self) -> int:
        return len(self.t_end_us)


@dataclass
class DepthStream:
    """Depth maps of the depth camera.

    Attributes:
        label: source, for messages.
        t_us: capture time of each map, [N] int64 (source clock).
        width, height: map size in pixels.
        load: ``load(indices)`` yields ``(index, depth)`` with depth float32 [H, W] metres,
            0 = invalid.
        integer_units: whether the maps are integers that need ``depth_scale`` (16-bit PNGs,
            16UC1) rather than float metres.
    """

    label: str
    t_us: np.ndarray
    width: int
    height: int
    load: Callable[[list[int]], Iterator[tuple[int, np.ndarray]]]
    integer_units: bool = True

    def __len__(self) -> int:
        return len(self.t_us)


@dataclass
class EventSource:
    """A stream of events of a ``width x height`` sensor.

    Attributes:
        label: source, for messages.
        width, height: sensor size the file declares.
        batches: ``batches()`` yields time-ordered :class:`Events` batches (whole file).
        sensor: the camera as the recording names it (AEDAT4: model and serial), if it does.
    """

    label: str
    width: int
    height: int
    batches: Callable[[], Iterable[Events]]
    sensor: str | None = None


@dataclass
class PoseTrack:
    """Ground-truth poses of the tracked rigid body.

    Attributes:
        label: source, for messages.
        t_us: [N] int64, strictly increasing (mocap clock).
        poses: ``T_world_body`` [N, 4, 4] float64.
    """

    label: str
    t_us: np.ndarray
    poses: np.ndarray


def to_rgb8(image: np.ndarray, encoding: str) -> np.ndarray:
    """An 8-bit frame in a ROS / AEDAT4 encoding -> uint8 [H, W, 3] RGB.

    ``mono8``/``L`` are replicated to three channels (grey sensors: DAVIS APS, VECtor's
    regular cameras); ``bayer_*8`` are demosaiced with OpenCV; alpha is dropped.

    Raises:
        ValueError: an encoding this function does not convert.
    """
    enc = encoding.lower()
    img = np.asarray(image)
    if enc in ("mono8", "8uc1", "l") and img.ndim == 2:
        return np.repeat(img[:, :, None], 3, axis=2).astype(np.uint8)
    if enc in ("mono16", "16uc1") and img.ndim == 2:
        return np.repeat((img >> 8).astype(np.uint8)[:, :, None], 3, axis=2)
    if enc in ("rgb8", "rgb") and img.ndim == 3 and img.shape[2] == 3:
        return img.astype(np.uint8)
    if enc == "bgr8" and img.ndim == 3 and img.shape[2] == 3:
        return np.ascontiguousarray(img[:, :, ::-1])
    if enc in ("rgba8", "rgba") and img.ndim == 3 and img.shape[2] == 4:
        return np.ascontiguousarray(img[:, :, :3])
    if enc == "bgra8" and img.ndim == 3 and img.shape[2] == 4:
        return np.ascontiguousarray(img[:, :, 2::-1])
    bayer = {"bayer_rggb8": cv2.COLOR_BayerRG2RGB, "bayer_bggr8": cv2.COLOR_BayerBG2RGB,
             "bayer_gbrg8": cv2.COLOR_BayerGB2RGB, "bayer_grbg8": cv2.COLOR_BayerGR2RGB}
    if enc in bayer and img.ndim == 2:
        return cv2.cvtColor(img.astype(np.uint8), bayer[enc])
    raise ValueError(f"unsupported image encoding {encoding!r} with shape {img.shape} "
                     "(mono8, mono16, rgb8, bgr8, rgba8, bgra8, bayer_*8)")


def exposure_windows(stamps_us: np.ndarray, exposure_us: np.ndarray | int, stamp: FrameStamp
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Exposure ``(t_start, t_end)`` [N] int64 from one stamp per frame and the exposure time.

    ``stamp`` says what the stamp marks: ``start``, ``mid`` (the DAVIS ROS driver: libcaer's
    frame timestamp is the middle of the exposure) or ``end``.
    """
    t = np.asarray(stamps_us, dtype=np.int64)
    exp = np.broadcast_to(np.asarray(exposure_us, dtype=np.int64), t.shape)
    if stamp == "start":
        t0 = t
    elif stamp == "mid":
        t0 = t - exp // 2
    elif stamp == "end":
        t0 = t - exp
    else:
        raise ValueError(f"frame stamp must be start, mid or end, not {stamp!r}")
    return t0, t0 + exp
