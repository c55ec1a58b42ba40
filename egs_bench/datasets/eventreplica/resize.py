"""Resize + centre-crop of RGB-D frames with consistently updated intrinsics.

EventReplica (paper §V.A) resizes Replica's 1200x680 frames to 459x260 and centre-crops them to
448x256. The default size rule, ``"auto"``, keeps exactly that for 1200x680 input (the two axes
scale by 0.3825 and 0.3824, as in the paper) and otherwise scales both axes by one factor, the
smallest that covers the crop, so other cameras keep their aspect ratio (640x480 7-Scenes frames
become 448x336, cropped to 448x256, with the ratio fx / fy unchanged).

In egs-bench's pixel convention (pixel ``u`` covers ``[u, u+1)``, centre ``u + 0.5``)
continuous image coordinates scale with the image, so a point at ``x`` maps to ``x * W'/W``
(``Intrinsics.resized``) and cropping subtracts the offset (``Intrinsics.cropped``).

Colour is resized in *linear* light with area averaging (the physically right way to merge
pixels: sensor pixels integrate irradiance). Depth is resampled by nearest neighbour at each new
pixel centre, because averaging depth across an object boundary invents 3-D points that lie on
neither surface ("flying pixels").
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np

from egs_bench.errors import ConfigError
from egs_bench.geometry import Intrinsics

#: the paper's resize of Replica frames (input size -> resized size, before the 448x256 crop)
PAPER_RESIZE = {(1200, 680): (459, 260)}


def auto_resize(in_width: int, in_height: int, width: int, height: int) -> tuple[int, int]:
    """The ``"auto"`` resize of an ``in_width x in_height`` image before a ``width x height``
    centre crop: the paper's size for Replica frames cropped to 448x256, otherwise one scale
    factor for both axes, the smallest whose result covers the crop (sizes rounded to the
    nearest pixel, never below the crop)."""
    if (width, height) == (448, 256) and (in_width, in_height) in PAPER_RESIZE:
        return PAPER_RESIZE[(in_width, in_height)]
    scale = max(width / in_width, height / in_height)
    return (max(width, int(math.floor(in_width * scale + 0.5))),
            max(height, int(math.floor(in_height * scale + 0.5))))


@dataclass(frozen=True)
class ResizeCrop:
    """Resize to ``resize = (width, height)``, then centre-crop to ``width x height``.

    ``resize="auto"`` picks the size with :func:`auto_resize` (the paper's 459x260 for Replica,
    the input's aspect ratio otherwise); ``resize=None`` skips resizing (crop only).
    """

    width: int = 448
    height: int = 256
    resize: tuple[int, int] | Literal["auto"] | None = "auto"

    def __post_init__(self) -> None:
        if self.width <= 0 or self.height <= 0:
            raise ConfigError(f"output size must be positive, got {self.width}x{self.height}")
        if self.resize is not None and self.resize != "auto":
            rw, rh = self.resize
            if rw < self.width or rh < self.height:
                raise ConfigError(
                    f"resize {rw}x{rh} is smaller than the crop {self.width}x{self.height}"
                )

    def intrinsics(self, source: Intrinsics) -> Intrinsics:
        """Intrinsics of the output image given those of the input (egs-bench convention)."""
        resized = self._resized_intrinsics(source)
        x0, y0 = self._offsets(resized)
        return resized.cropped(x0, y0, self.width, self.height)

    def rgb(self, image: np.ndarray, source: Intrinsics) -> np.ndarray:
        """Resize (area average) and crop a linear colour image [H, W, C] float32."""
        resized = self._resized_intrinsics(source)
        img: np.ndarray = np.asarray(image, dtype=np.float32)
        if (resized.width, resized.height) != (source.width, source.height):
            img = cv2.resize(img, (resized.width, resized.height), interpolation=cv2.INTER_AREA)
        x0, y0 = self._offsets(resized)
        return np.ascontiguousarray(img[y0 : y0 + self.height, x0 : x0 + self.width])

    def depth(self, depth: np.ndarray, source: Intrinsics) -> np.ndarray:
        """Resample depth [H, W] (metres, 0 = invalid) by nearest neighbour at pixel centres."""
        resized = self._resized_intrinsics(source)
        x0, y0 = self._offsets(resized)
        # Output pixel centre (i + 0.5) in resized coordinates -> source coordinate (i + 0.5) * s;
        # the source pixel containing it is floor of that.
        cols = np.floor((np.arange(x0, x0 + self.width) + 0.5) * source.width / resized.width)
        rows = np.floor((np.arange(y0, y0 + self.height) + 0.5) * source.height / resized.height)
        cols = np.minimum(cols.astype(np.int64), source.width - 1)
        rows = np.minimum(rows.astype(np.int64), source.height - 1)
        return np.ascontiguousarray(np.asarray(depth, dtype=np.float32)[np.ix_(rows, cols)])

    def resized_size(self, source: Intrinsics) -> tuple[int, int]:
        """The size the input is resized to before the crop."""
        if self.resize is None:
            return source.width, source.height
        if self.resize == "auto":
            return auto_resize(source.width, source.height, self.width, self.height)
        return self.resize

    def _resized_intrinsics(self, source: Intrinsics) -> Intrinsics:
        size = self.resized_size(source)
        if size == (source.width, source.height):
            return source
        return source.resized(*size)

    def _offsets(self, resized: Intrinsics) -> tuple[int, int]:
        try:
            return resized.center_crop_offsets(self.width, self.height)
        except ValueError as exc:
            raise ConfigError(str(exc)) from None
