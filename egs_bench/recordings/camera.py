"""Calibrated cameras of a recording rig: OpenCV distortion models, rays, undistortion.

A real sensor's calibration (Kalibr, ROS ``camera_info``, OpenCV) puts pixel ``(u, v)``'s
centre at the integer ``(u, v)``; egs-bench's pinhole :class:`~egs_bench.geometry.Intrinsics`
puts it at ``(u + 0.5, v + 0.5)``. :class:`CameraModel` keeps the calibration's convention
(it is what OpenCV's functions expect) and :meth:`CameraModel.pinhole` converts.

The distortion models are OpenCV's: ``radtan`` (Brown-Conrady / ROS ``plumb_bob``: 4, 5 or
8 coefficients ``k1 k2 p1 p2 [k3 [k4 k5 k6]]``, the last form being ROS
``rational_polynomial``) through ``cv2.undistortPoints`` / ``cv2.projectPoints``, and
``equidistant`` (Kalibr's name for the fisheye model, 4 coefficients ``k1..k4``) through
``cv2.fisheye``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from egs_bench.geometry import Intrinsics

DISTORTION_MODELS = ("none", "radtan", "equidistant")
#: names other tools use for the same models
MODEL_ALIASES = {"plumb_bob": "radtan", "rational_polynomial": "radtan", "pinhole": "none",
                 "fisheye": "equidistant", "equi": "equidistant", "": "none"}


@dataclass(frozen=True)
class CameraModel:
    """A calibrated camera: size, focal lengths and principal point (pixels, OpenCV's
    integer-centre convention) and a distortion model with its coefficients."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    model: str = "none"
    coeffs: tuple[float, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        model = MODEL_ALIASES.get(self.model, self.model)
        if not self.coeffs and model in ("radtan", "equidistant"):
            model = "none"  # ROS camera_info of a rectified camera: plumb_bob with D = []
        object.__setattr__(self, "model", model)
        object.__setattr__(self, "coeffs", tuple(float(c) for c in self.coeffs))
        if model not in DISTORTION_MODELS:
            raise ValueError(f"unknown distortion model {self.model!r} "
                             f"(choose from {', '.join(DISTORTION_MODELS)})")
        n = len(self.coeffs)
        if model == "radtan" and n not in (4, 5, 8):
            raise ValueError(f"radtan distortion needs 4, 5 or 8 coefficients, got {n}")
        if model == "equidistant" and n != 4:
            raise ValueError(f"equidistant distortion needs 4 coefficients, got {n}")
        if model == "none" and any(self.coeffs):
            raise ValueError("distortion_model none with non-zero coefficients")
        if self.width <= 0 or self.height <= 0 or self.fx <= 0 or self.fy <= 0:
            raise ValueError("width, height, fx and fy must be positive")

    # ------------------------------------------------------------------ basics
    @property
    def K(self) -> np.ndarray:  # the conventional name
        """3x3 calibration matrix in OpenCV's convention, float64."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def distorted(self) -> bool:
        return self.model != "none" and any(self.coeffs)

    def _dist(self) -> np.ndarray:
        return np.asarray(self.coeffs, dtype=np.float64)

    def pinhole(self) -> Intrinsics:
        """The undistorted pinhole camera with the same ``K`` and size, in egs-bench's
        convention (``cx + 0.5``, ``cy + 0.5``): the camera every imported stream ends up in."""
        return Intrinsics(self.fx, self.fy, self.cx + 0.5, self.cy + 0.5, self.width,
                          self.height)

    # ------------------------------------------------------------------ geometry
    def undistort_points(self, uv: np.ndarray) -> np.ndarray:
        """Pixel coordinates [N, 2] (OpenCV convention) -> normalised coordinates ``(X/Z, Y/Z)``
        [N, 2] of the rays through them, float64."""
        pts = np.ascontiguousarray(np.asarray(uv, dtype=np.float64).reshape(-1, 1, 2))
        if not self.distorted:
            return (pts.reshape(-1, 2) - [self.cx, self.cy]) / [self.fx, self.fy]
        out: np.ndarray
        if self.model == "equidistant":
            out = cv2.fisheye.undistortPoints(pts, self.K, self._dist())
        else:
            # iterate well past OpenCV's default 5 steps: strong radial terms need more
            crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
            out = cv2.undistortPoints(pts, self.K, self._dist(), None, None, None, crit)
        return out.reshape(-1, 2).astype(np.float64)

    def pixel_rays(self) -> np.ndarray:
        """Normalised coordinates of every pixel centre, [H, W, 2] float64."""
        v, u = np.mgrid[0 : self.height, 0 : self.width].astype(np.float64)
        uv = np.stack([u.ravel(), v.ravel()], axis=1)
        return self.undistort_points(uv).reshape(self.height, self.width, 2)

    def project(self, points: np.ndarray) -> np.ndarray:
        """Camera-frame points [N, 3] (Z > 0) -> distorted pixel coordinates [N, 2] (OpenCV
        convention), float64."""
        pts = np.ascontiguousarray(np.asarray(points, dtype=np.float64).reshape(-1, 1, 3))
        if len(pts) == 0:
            return np.zeros((0, 2))
        zero = np.zeros(3)
        if self.model == "equidistant":
            out, _ = cv2.fisheye.projectPoints(pts, zero, zero, self.K, self._dist())
        else:
            out, _ = cv2.projectPoints(pts, zero, zero, self.K,
                                       self._dist() if self.distorted else None)
        return out.reshape(-1, 2)

    # ------------------------------------------------------------------ undistortion
    def undistort_maps(self) -> tuple[np.ndarray, np.ndarray]:
        """``cv2.remap`` maps [H, W] float32 from the undistorted image (same ``K`` and size,
        :meth:`pinhole`) to this camera's distorted pixels."""
        size = (self.width, self.height)
        if self.model == "equidistant":
            return cv2.fisheye.initUndistortRectifyMap(self.K, self._dist(), np.eye(3), self.K,
                                                       size, cv2.CV_32FC1)
        return cv2.initUndistortRectifyMap(self.K, self._dist(), np.eye(3), self.K, size,
                                           cv2.CV_32FC1)

    def undistort_image(self, image: np.ndarray, interpolation: int = cv2.INTER_LINEAR
                        ) -> np.ndarray:
        """The image as the undistorted pinhole camera sees it (pixels mapping outside the
        sensor become 0). ``INTER_NEAREST`` for depth maps (no mixing across edges)."""
        if not self.distorted:
            return image
        map_x, map_y = self.undistort_maps()
        return cv2.remap(image, map_x, map_y, interpolation, borderMode=cv2.BORDER_CONSTANT,
                         borderValue=0)

    def event_lookup(self) -> np.ndarray:
        """For every sensor pixel, the flat index ``y * W + x`` of the undistorted pixel its
        centre maps to (nearest), or -1 outside the image: int64 [H * W].

        Events carry no intensity to resample, so each is moved to the nearest undistorted
        pixel. Where undistortion stretches the image (barrel distortion towards the border)
        some undistorted pixels receive no sensor pixel and never see an event
        (:meth:`event_coverage` counts them)."""
        n = self.width * self.height
        if not self.distorted:
            return np.arange(n, dtype=np.int64)
        rays = self.pixel_rays().reshape(-1, 2)
        u = np.floor(self.fx * rays[:, 0] + self.cx + 0.5)
        v = np.floor(self.fy * rays[:, 1] + self.cy + 0.5)
        inside = (u >= 0) & (u < self.width) & (v >= 0) & (v < self.height) \
            & np.isfinite(rays).all(axis=1)
        out = np.full(n, -1, dtype=np.int64)
        out[inside] = (v[inside] * self.width + u[inside]).astype(np.int64)
        return out

    def event_coverage(self, lookup: np.ndarray | None = None) -> float:
        """Fraction of undistorted pixels that some sensor pixel maps to (1 = no dead pixels)."""
        lut = self.event_lookup() if lookup is None else lookup
        hit = np.zeros(self.width * self.height, dtype=bool)
        hit[lut[lut >= 0]] = True
        return float(hit.mean())

    def to_dict(self) -> dict:
        return {"width": self.width, "height": self.height,
                "intrinsics": [self.fx, self.fy, self.cx, self.cy],
                "distortion_model": self.model, "distortion": list(self.coeffs)}
