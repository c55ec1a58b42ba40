"""Temporal interpolation between two RGB-D key frames of a static scene.

The paper upsampled Replica in time with FILM, a learned model that is not available offline.
egs-bench offers two interpolators behind one small interface (:class:`FrameInterpolator`):

``depth`` (default, :class:`DepthWarpInterpolator`)
    Pose-aware view synthesis. The scene is static and each key frame has exact depth and pose,
    so the in-between view at fraction ``alpha`` is *geometry*, not guesswork: interpolate the
    pose (slerp of rotation, lerp of translation), forward-warp both key frames' 3-D points into
    that camera with a z-buffer, blend the two warps with time weights ``(1 - alpha, alpha)``
    where both see the front surface, take the one that does where only one does, and inpaint
    the remaining holes (pixels seen by neither key frame, or without valid depth).
``flow`` (:class:`FlowInterpolator`)
    OpenCV DIS optical flow in both directions, intermediate flows by the linear-motion
    approximation of Super-SloMo (``F_t0 = -(1-t) t F01 + t^2 F10``,
    ``F_t1 = (1-t)^2 F01 - t (1-t) F10``), backward warps, blend ``(1 - t, t)``. Needs no depth
    or poses; occlusions are not reasoned about. Use it when depth is unreliable.

Both interpolators return the key frames themselves at ``alpha = 0`` and ``alpha = 1``.
Colour is linear light throughout (blending sRGB values would bias the blur and the events).
To add another method, implement :class:`FrameInterpolator` and register it in
:data:`INTERPOLATORS`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal, Protocol

import cv2
import numpy as np

from egs_bench.color import linear_to_srgb, luma, to_uint8
from egs_bench.datasets.eventreplica.splat_kernels import splat_points
from egs_bench.errors import ConfigError
from egs_bench.geometry import Intrinsics, interpolate_pose, invert_pose


@dataclass(frozen=True)
class KeyFrame:
    """One original (resized, cropped) frame.

    Attributes:
        rgb: [H, W, 3] float32 linear colour (sRGB-decoded), >= 0.
        depth: [H, W] float32 metres, 0 = invalid.
        pose: [4, 4] float64 camera-to-world ``T_wc``.
    """

    rgb: np.ndarray
    depth: np.ndarray
    pose: np.ndarray


class PairInterpolator(Protocol):
    """Interpolation state for one pair of key frames (flows, back-projected points...)."""

    def __call__(self, alpha: float) -> tuple[np.ndarray, np.ndarray]:
        """Frame at fraction ``alpha`` in [0, 1]: ``(rgb [H, W, 3] linear, depth [H, W] m)``."""
        ...


class FrameInterpolator(Protocol):
    """Builds a :class:`PairInterpolator` for consecutive key frames ``a`` and ``b``."""

    @property
    def name(self) -> str:
        """The interpolator's registry name (recorded in ``meta.yaml``)."""
        ...

    def prepare(self, a: KeyFrame, b: KeyFrame, intrinsics: Intrinsics) -> PairInterpolator:
        ...


# --- pose-aware depth-based view synthesis ------------------------------------------------------


@dataclass(frozen=True)
class DepthWarpInterpolator:
    """Forward-warp both neighbours into the interpolated camera (see the module docstring).

    Attributes:
        rel_depth_tol: relative depth tolerance for "same surface" (z-buffer and blending).
        min_coverage: minimum accumulated splat weight for a warped pixel to count as covered.
        inpaint_radius: OpenCV inpainting radius (pixels) for holes (Navier-Stokes method; the
            Telea method returns garbage on float32 images in OpenCV 5.0).
    """

    rel_depth_tol: float = 0.03
    min_coverage: float = 0.2
    inpaint_radius: float = 3.0
    name: str = "depth"

    def prepare(self, a: KeyFrame, b: KeyFrame, intrinsics: Intrinsics) -> PairInterpolator:
        return _DepthWarpPair(self, a, b, intrinsics)


class _DepthWarpPair:
    def __init__(
        self, cfg: DepthWarpInterpolator, a: KeyFrame, b: KeyFrame, intrinsics: Intrinsics
    ) -> None:
        self.cfg, self.a, self.b, self.intr = cfg, a, b, intrinsics
        self.clouds = [_world_cloud(f, intrinsics) for f in (a, b)]

    def __call__(self, alpha: float) -> tuple[np.ndarray, np.ndarray]:
        if alpha <= 0.0:
            return self.a.rgb.copy(), self.a.depth.copy()
        if alpha >= 1.0:
            return self.b.rgb.copy(), self.b.depth.copy()
        pose = interpolate_pose(self.a.pose, self.b.pose, alpha)
        t_cw = invert_pose(pose)
        intr, cfg = self.intr, self.cfg
        warps = []
        for points, colors in self.clouds:
            acc_c, acc_w, acc_z = splat_points(
                points, colors, t_cw[:3, :3].copy(), t_cw[:3, 3].copy(),
                intr.fx, intr.fy, intr.cx, intr.cy, intr.width, intr.height,
                cfg.rel_depth_tol, 0.1,
            )
            covered = acc_w >= cfg.min_coverage
            inv_w = np.where(covered, 1.0 / np.maximum(acc_w, 1e-12), 0.0).astype(np.float32)
            warps.append((acc_c * inv_w[..., None], acc_z * inv_w, covered))
        (rgb_a, z_a, cov_a), (rgb_b, z_b, cov_b) = warps
        # front surface per pixel; each warp counts only where it shows that surface
        z_front = np.fmin(np.where(cov_a, z_a, np.nan), np.where(cov_b, z_b, np.nan))
        limit = z_front * (1.0 + cfg.rel_depth_tol)
        use_a = cov_a & (z_a <= limit)
        use_b = cov_b & (z_b <= limit)
        w_a = np.where(use_a, 1.0 - alpha, 0.0).astype(np.float32)
        w_b = np.where(use_b, alpha, 0.0).astype(np.float32)
        total = w_a + w_b
        holes = total <= 0.0
        inv = np.where(holes, 0.0, 1.0 / np.where(holes, 1.0, total)).astype(np.float32)
        rgb = (rgb_a * (w_a * inv)[..., None] + rgb_b * (w_b * inv)[..., None]).astype(np.float32)
        depth = (z_a * w_a * inv + z_b * w_b * inv).astype(np.float32)
        if holes.any():
            rgb = _inpaint(rgb, holes, cfg.inpaint_radius)
        return rgb, depth


def _world_cloud(frame: KeyFrame, intr: Intrinsics) -> tuple[np.ndarray, np.ndarray]:
    """Valid-depth pixels of a key frame as world points [M, 3] and colours [M, 3]."""
    pts_cam = intr.backproject(frame.depth).reshape(-1, 3)
    valid = frame.depth.reshape(-1) > 0
    pts_cam = pts_cam[valid]
    pts_w = pts_cam @ frame.pose[:3, :3].T + frame.pose[:3, 3]
    colors = np.ascontiguousarray(frame.rgb.reshape(-1, 3)[valid], dtype=np.float32)
    return np.ascontiguousarray(pts_w), colors


def _inpaint(rgb: np.ndarray, holes: np.ndarray, radius: float) -> np.ndarray:
    """Fill ``holes`` [H, W] bool of a float32 image [H, W, 3] by OpenCV inpainting."""
    mask = holes.astype(np.uint8)
    out = np.empty_like(rgb)
    for c in range(rgb.shape[2]):
        out[..., c] = cv2.inpaint(np.ascontiguousarray(rgb[..., c]), mask, radius,
                                  cv2.INPAINT_NS)
    return np.maximum(out, 0.0)


# --- optical-flow interpolation (fallback) ------------------------------------------------------

_DIS_PRESETS = {
    "ultrafast": cv2.DISOPTICAL_FLOW_PRESET_ULTRAFAST,
    "fast": cv2.DISOPTICAL_FLOW_PRESET_FAST,
    "medium": cv2.DISOPTICAL_FLOW_PRESET_MEDIUM,
}


@dataclass(frozen=True)
class FlowInterpolator:
    """Bidirectional DIS optical flow + backward warping (see the module docstring).

    Attributes:
        preset: DIS preset, ``ultrafast``, ``fast`` (default; best accuracy/speed trade-off in
            our measurements) or ``medium``.
    """

    preset: str = "fast"
    name: str = "flow"

    def __post_init__(self) -> None:
        if self.preset not in _DIS_PRESETS:
            raise ConfigError(f"DIS preset must be one of {sorted(_DIS_PRESETS)}, "
                              f"not {self.preset!r}")

    def prepare(self, a: KeyFrame, b: KeyFrame, intrinsics: Intrinsics) -> PairInterpolator:
        return _FlowPair(self, a, b)


class _FlowPair:
    def __init__(self, cfg: FlowInterpolator, a: KeyFrame, b: KeyFrame) -> None:
        self.a, self.b = a, b
        dis = cv2.DISOpticalFlow_create(_DIS_PRESETS[cfg.preset])  # type: ignore[attr-defined]
        # DIS works on 8-bit grey; sRGB-encoded luma spreads the codes perceptually.
        g0, g1 = (to_uint8(linear_to_srgb(luma(f.rgb))) for f in (a, b))
        self.f01 = dis.calc(g0, g1, None)
        self.f10 = dis.calc(g1, g0, None)
        h, w = g0.shape
        self.grid_x, self.grid_y = np.meshgrid(
            np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32)
        )

    def __call__(self, alpha: float) -> tuple[np.ndarray, np.ndarray]:
        if alpha <= 0.0:
            return self.a.rgb.copy(), self.a.depth.copy()
        if alpha >= 1.0:
            return self.b.rgb.copy(), self.b.depth.copy()
        t = float(alpha)
        flow_t0 = -(1 - t) * t * self.f01 + t * t * self.f10
        flow_t1 = (1 - t) ** 2 * self.f01 - t * (1 - t) * self.f10
        rgb0, d0 = self._warp(self.a, flow_t0)
        rgb1, d1 = self._warp(self.b, flow_t1)
        rgb = ((1 - t) * rgb0 + t * rgb1).astype(np.float32)
        # Depth is not blended (averaging across an edge invents surfaces): take the nearer-in-
        # time neighbour's warped depth, the other where that one is invalid.
        near, far = (d0, d1) if t < 0.5 else (d1, d0)
        depth = np.where(near > 0, near, far).astype(np.float32)
        return np.maximum(rgb, 0.0), depth

    def _warp(self, frame: KeyFrame, flow: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        map_x = self.grid_x + flow[..., 0]
        map_y = self.grid_y + flow[..., 1]
        rgb = cv2.remap(frame.rgb, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        depth = cv2.remap(frame.depth, map_x, map_y, cv2.INTER_NEAREST,
                          borderMode=cv2.BORDER_REPLICATE)
        return rgb, depth


InterpolatorName = Literal["depth", "flow"]
INTERPOLATORS: dict[InterpolatorName, Callable[[], FrameInterpolator]] = {
    "depth": DepthWarpInterpolator,
    "flow": FlowInterpolator,
}


def make_interpolator(name: InterpolatorName) -> FrameInterpolator:
    """The interpolator registered under ``name`` (``depth`` or ``flow``) with default settings."""
    try:
        return INTERPOLATORS[name]()
    except KeyError:
        raise ConfigError(
            f"unknown interpolator {name!r}; choose one of {', '.join(sorted(INTERPOLATORS))}"
        ) from None
