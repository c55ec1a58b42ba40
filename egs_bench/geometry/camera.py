"""Pinhole intrinsics with gsplat's pixel convention: pixel ``(u, v)`` has its centre at
``(u + 0.5, v + 0.5)`` and a point projects to ``u = fx * X / Z + cx``.

In this convention continuous image coordinates have their origin at the top-left *corner*, so
resizing by ``s`` scales ``fx, fy, cx, cy`` by ``s`` and cropping at ``(x0, y0)`` subtracts the
offset from ``cx, cy``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole camera: focal lengths and principal point in pixels, image size in pixels."""

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int

    @property
    def K(self) -> np.ndarray:  # the conventional name
        """The 3x3 calibration matrix, float64."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def to_dict(self) -> dict[str, float | int]:
        return asdict(self)

    def resized(self, width: int, height: int) -> Intrinsics:
        """Intrinsics after resizing the image to ``width x height`` (axes scale separately)."""
        sx, sy = width / self.width, height / self.height
        return Intrinsics(self.fx * sx, self.fy * sy, self.cx * sx, self.cy * sy, width, height)

    def cropped(self, x0: int, y0: int, width: int, height: int) -> Intrinsics:
        """Intrinsics of the ``width x height`` window whose top-left pixel is ``(x0, y0)``."""
        return replace(self, cx=self.cx - x0, cy=self.cy - y0, width=width, height=height)

    def center_crop_offsets(self, width: int, height: int) -> tuple[int, int]:
        """Top-left pixel of a centred ``width x height`` crop (floor of half the margin)."""
        if width > self.width or height > self.height:
            raise ValueError(f"crop {width}x{height} larger than image {self.width}x{self.height}")
        return (self.width - width) // 2, (self.height - height) // 2

    def project(self, points_cam: np.ndarray) -> np.ndarray:
        """Project camera-frame points [N, 3] (z > 0) to continuous pixel coordinates [N, 2]."""
        z = points_cam[:, 2]
        return np.stack(
            [self.fx * points_cam[:, 0] / z + self.cx, self.fy * points_cam[:, 1] / z + self.cy],
            axis=1,
        )

    def backproject(self, depth: np.ndarray) -> np.ndarray:
        """Back-project a depth map [H, W] (metres) through pixel centres to points [H, W, 3]."""
        v, u = np.mgrid[0 : self.height, 0 : self.width].astype(np.float64)
        z = depth.astype(np.float64)
        x = (u + 0.5 - self.cx) / self.fx * z
        y = (v + 0.5 - self.cy) / self.fy * z
        return np.stack([x, y, z], axis=-1)
