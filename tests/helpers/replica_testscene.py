"""Analytic textured scene for the EventReplica tests: ray-cast in numpy, exact depth.

A room (inside of an axis-aligned box) whose walls carry scikit-image's bundled photographs,
plus a box floating in it (occlusions). Lambertian, static, no view-dependent shading, so the
in-between view of two key frames is exactly a direct render at the interpolated pose.
Independent of the code under test (no shared warping or projection code).
"""

from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np
import skimage.data

ROOM_LO = np.array([-3.0, -2.0, -3.0])
ROOM_HI = np.array([3.0, 2.0, 4.5])
BOX_LO = np.array([-0.7, -0.3, 1.6])
BOX_HI = np.array([0.5, 0.9, 2.4])
TEXEL_M = 0.006  # metres per texel


@lru_cache(maxsize=1)
def _textures() -> list[np.ndarray]:
    """Six linear-colour float32 textures [512, 512, 3]."""
    out = []
    textures: tuple[tuple[str, tuple[float, float, float] | None], ...] = (
        ("astronaut", None), ("brick", (1.0, 0.7, 0.5)), ("coffee", None),
        ("gravel", (0.6, 0.8, 1.0)), ("chelsea", None), ("grass", (0.5, 1.0, 0.6)))
    for name, tint in textures:
        img = getattr(skimage.data, name)()
        if img.ndim == 2:
            assert tint is not None  # the grey photographs are tinted
            img = np.stack([img * t for t in tint], axis=-1)
        img = cv2.resize(img.astype(np.float32), (512, 512), interpolation=cv2.INTER_AREA) / 255.0
        out.append(np.clip(img, 0, 1) ** 2.2)  # roughly linearise the photographs
    return out


def _sample(tex: np.ndarray, s: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Bilinear, wrapping texture lookup at metric surface coordinates -> [..., 3]."""
    h, w = tex.shape[:2]
    x = (s / TEXEL_M) % w - 0.5
    y = (t / TEXEL_M) % h - 0.5
    x0 = np.floor(x).astype(np.int64)
    y0 = np.floor(y).astype(np.int64)
    ax = (x - x0)[..., None]
    ay = (y - y0)[..., None]
    x0, y0 = x0 % w, y0 % h
    x1, y1 = (x0 + 1) % w, (y0 + 1) % h
    return ((1 - ay) * ((1 - ax) * tex[y0, x0] + ax * tex[y0, x1])
            + ay * ((1 - ax) * tex[y1, x0] + ax * tex[y1, x1]))


def _shade(points: np.ndarray, axis: np.ndarray, sign: np.ndarray, inner: np.ndarray) -> np.ndarray:
    textures = _textures()
    out = np.zeros(points.shape, dtype=np.float64)
    light = {0: 0.8, 1: 1.0, 2: 0.65}
    for k in range(3):
        others = [a for a in range(3) if a != k]
        for sgn in (-1, 1):
            for is_inner in (False, True):
                m = (axis == k) & (sign == sgn) & (inner == is_inner)
                if not m.any():
                    continue
                tex = textures[(2 * k + (sgn > 0) + 3 * is_inner) % 6]
                p = points[m]
                out[m] = _sample(tex, p[:, others[0]] + 0.37 * k, p[:, others[1]]) * (
                    light[k] * (0.9 if sgn > 0 else 1.0) * (1.3 if is_inner else 1.0))
    return out


def _cast(origin: np.ndarray, dirs: np.ndarray
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Hit distance (along dirs), point, face axis, face sign, inner-box flag for each ray."""
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / dirs
        # room: exit of the box from inside
        t1 = (ROOM_LO - origin) * inv
        t2 = (ROOM_HI - origin) * inv
        tmax = np.maximum(t1, t2)
        axis = np.argmin(tmax, axis=1)
        t_hit = np.take_along_axis(tmax, axis[:, None], 1)[:, 0]
        sign = -np.sign(np.take_along_axis(dirs, axis[:, None], 1)[:, 0])
        inner = np.zeros(len(dirs), dtype=bool)
        # floating box: slab test
        b1 = (BOX_LO - origin) * inv
        b2 = (BOX_HI - origin) * inv
        bmin = np.minimum(b1, b2)
        bmax = np.maximum(b1, b2)
        t_near = bmin.max(axis=1)
        t_far = bmax.min(axis=1)
        hit_box = (t_near <= t_far) & (t_near > 1e-6) & (t_near < t_hit)
    b_axis = np.argmax(bmin, axis=1)
    b_sign = -np.sign(np.take_along_axis(dirs, b_axis[:, None], 1)[:, 0])
    t_hit = np.where(hit_box, t_near, t_hit)
    axis = np.where(hit_box, b_axis, axis)
    sign = np.where(hit_box, b_sign, sign)
    inner = inner | hit_box
    points = origin + t_hit[:, None] * dirs
    return t_hit, points, axis, sign, inner


def render(
    pose_wc: np.ndarray, fx: float, fy: float, cx: float, cy: float, width: int, height: int,
    supersample: int = 2,
) -> tuple[np.ndarray, np.ndarray]:
    """Render linear RGB [H, W, 3] float32 (box-filtered over each pixel) and depth [H, W] (m).

    Intrinsics in egs-bench's convention (pixel centre at u + 0.5). Depth is the z of the ray
    through each pixel centre.
    """
    rot, origin = pose_wc[:3, :3], pose_wc[:3, 3]
    acc = np.zeros((height, width, 3))
    offsets = (np.arange(supersample) + 0.5) / supersample
    v, u = np.mgrid[0:height, 0:width].astype(np.float64)
    for oy in offsets:
        for ox in offsets:
            d_cam = np.stack([(u + ox - cx) / fx, (v + oy - cy) / fy, np.ones_like(u)], -1)
            dirs = d_cam.reshape(-1, 3) @ rot.T
            _, pts, axis, sign, inner = _cast(origin, dirs)
            acc += _shade(pts, axis, sign, inner).reshape(height, width, 3)
    rgb = (acc / supersample**2).astype(np.float32)
    d_cam = np.stack([(u + 0.5 - cx) / fx, (v + 0.5 - cy) / fy, np.ones_like(u)], -1)
    t_hit, *_ = _cast(origin, d_cam.reshape(-1, 3) @ rot.T)
    depth = t_hit.reshape(height, width).astype(np.float32)  # d_cam has z = 1: t is the z depth
    return rgb, depth


def look_pose(position: list[float], yaw_deg: float = 0.0, pitch_deg: float = 0.0,
              roll_deg: float = 0.0) -> np.ndarray:
    """Camera-to-world pose at ``position`` looking along +z rotated by yaw/pitch/roll (deg)."""
    from scipy.spatial.transform import Rotation

    rot = Rotation.from_euler("yxz", [yaw_deg, pitch_deg, roll_deg], degrees=True).as_matrix()
    pose = np.eye(4)
    pose[:3, :3] = rot
    pose[:3, 3] = position
    return pose
