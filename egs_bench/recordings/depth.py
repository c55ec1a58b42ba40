"""Depth from a second camera: reprojection into the event camera, and image warping.

A depth camera that is not the event camera (RealSense, Azure Kinect, a LiDAR's depth map on
another grid) sees the scene from elsewhere. :func:`reproject_depth` moves its depth into the
event camera: back-project every valid depth pixel through its ray, transform the point with
``T_event_depth``, project it into the (undistorted, pinhole) event camera and keep the nearest
point per pixel (z-buffer). Pixels no point lands on stay 0 (invalid): nothing is filled or
interpolated, so every non-zero output value is a measured depth moved by the calibration.

Hand-written in numpy because no library of the field does it without a device SDK (the
Azure Kinect SDK's ``k4a_transformation`` is tied to that camera): it is a handful of array
operations (``np.minimum.at`` is the z-buffer).
"""

from __future__ import annotations

import cv2
import numpy as np

from egs_bench.geometry import Intrinsics
from egs_bench.recordings.camera import CameraModel

#: points closer than this to the destination camera are dropped (metres)
MIN_DEPTH_M = 1e-3


def reproject_depth(depth: np.ndarray, rays: np.ndarray, T_dst_src: np.ndarray,
                    dst: Intrinsics) -> np.ndarray:
    """Reproject a depth map into another camera with a z-buffer; fills nothing.

    Args:
        depth: source z-depth, [Hs, Ws] metres, 0 (or non-finite) = invalid.
        rays: normalised coordinates ``(X/Z, Y/Z)`` of every source pixel centre,
            [Hs, Ws, 2] (:meth:`CameraModel.pixel_rays`, which removes lens distortion).
        T_dst_src: [4, 4] rigid transform from the source to the destination camera frame.
        dst: the destination pinhole camera (egs-bench's pixel convention: pixel ``(u, v)``
            covers ``[u, u+1) x [v, v+1)`` of ``u = fx X / Z + cx``).

    Returns:
        Destination z-depth [H, W] float32 metres; 0 where no source point projects. Where
        several points land in one pixel the nearest wins.

    Example:
        >>> d = np.full((4, 4), 2.0, np.float32)
        >>> cam = CameraModel(4, 4, 4.0, 4.0, 1.5, 1.5)
        >>> out = reproject_depth(d, cam.pixel_rays(), np.eye(4), cam.pinhole())
        >>> float(out.min()), float(out.max())
        (2.0, 2.0)
    """
    depth = np.asarray(depth, dtype=np.float64)
    if rays.shape != (*depth.shape, 2):
        raise ValueError(f"rays {rays.shape} do not match depth {depth.shape}")
    valid = np.isfinite(depth) & (depth > 0)
    z = depth[valid]
    pts = np.concatenate([rays[valid] * z[:, None], z[:, None]], axis=1)  # [N, 3] source
    pts = pts @ T_dst_src[:3, :3].T + T_dst_src[:3, 3]
    zd = pts[:, 2]
    front = zd > MIN_DEPTH_M
    pts, zd = pts[front], zd[front]
    u = np.floor(dst.fx * pts[:, 0] / zd + dst.cx)
    v = np.floor(dst.fy * pts[:, 1] / zd + dst.cy)
    inside = (u >= 0) & (u < dst.width) & (v >= 0) & (v < dst.height)
    flat = (v[inside] * dst.width + u[inside]).astype(np.int64)
    zbuf = np.full(dst.width * dst.height, np.inf)
    np.minimum.at(zbuf, flat, zd[inside])
    zbuf[~np.isfinite(zbuf)] = 0.0
    return zbuf.reshape(dst.height, dst.width).astype(np.float32)


def warp_to_depth_camera(image: np.ndarray, src: CameraModel, depth_dst: np.ndarray,
                         dst: Intrinsics, T_src_dst: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray]:
    """Resample an image of camera ``src`` into camera ``dst`` using ``dst``'s depth.

    Every ``dst`` pixel with depth is back-projected, moved into ``src`` with ``T_src_dst`` and
    projected through ``src``'s lens model; the image is sampled there bilinearly. Pixels
    without depth, or whose point falls outside ``src``'s image or behind it, become 0.
    Occlusions as seen from ``src`` are not detected (its depth is not known here).

    Args:
        image: ``src``'s image, [Hs, Ws] or [Hs, Ws, C] uint8.
        src: the camera that took ``image``.
        depth_dst: ``dst``'s z-depth [H, W] metres (0 = unknown).
        dst: destination pinhole camera (egs-bench's convention).
        T_src_dst: [4, 4] from ``dst``'s frame to ``src``'s frame.

    Returns:
        ``(warped, valid)``: the image in ``dst`` ([H, W] or [H, W, C], same dtype) and the
        bool mask [H, W] of pixels that received a sample.
    """
    pts = dst.backproject(depth_dst).reshape(-1, 3)
    has = (np.asarray(depth_dst) > 0).reshape(-1)
    pts = pts @ T_src_dst[:3, :3].T + T_src_dst[:3, 3]
    ok = has & (pts[:, 2] > MIN_DEPTH_M)
    uv = np.full((len(pts), 2), -1e6, dtype=np.float64)
    uv[ok] = src.project(pts[ok])
    inside = ok & (uv[:, 0] >= -0.5) & (uv[:, 0] <= src.width - 0.5) \
        & (uv[:, 1] >= -0.5) & (uv[:, 1] <= src.height - 0.5)
    uv[~inside] = -1e6
    map_x = uv[:, 0].reshape(dst.height, dst.width).astype(np.float32)
    map_y = uv[:, 1].reshape(dst.height, dst.width).astype(np.float32)
    warped = cv2.remap(image, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                       borderValue=0)
    return warped, inside.reshape(dst.height, dst.width)
