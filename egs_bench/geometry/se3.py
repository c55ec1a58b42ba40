"""SE(3) helpers in numpy (float64): construction, inversion and interpolation of 4x4 poses."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation, Slerp


def pose_from_tq(t: np.ndarray, q_xyzw: np.ndarray) -> np.ndarray:
    """Build 4x4 poses from translations and quaternions.

    Args:
        t: translations, shape [..., 3] (metres).
        q_xyzw: unit quaternions ``qx qy qz qw`` (TUM order), shape [..., 4]; normalised here.

    Returns:
        Poses, shape [..., 4, 4], float64.
    """
    t = np.asarray(t, dtype=np.float64)
    q = np.asarray(q_xyzw, dtype=np.float64)
    batch = t.shape[:-1]
    rot = Rotation.from_quat(q.reshape(-1, 4)).as_matrix().reshape(*batch, 3, 3)
    out = np.zeros((*batch, 4, 4))
    out[..., :3, :3] = rot
    out[..., :3, 3] = t
    out[..., 3, 3] = 1.0
    return out


def pose_to_tq(poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Split 4x4 poses [..., 4, 4] into translations [..., 3] and quaternions ``xyzw`` [..., 4].

    Quaternions are returned with ``qw >= 0`` so that files are reproducible.
    """
    poses = np.asarray(poses, dtype=np.float64)
    batch = poses.shape[:-2]
    q = Rotation.from_matrix(poses[..., :3, :3].reshape(-1, 3, 3)).as_quat()
    q = np.where(q[:, 3:4] < 0, -q, q).reshape(*batch, 4)
    return poses[..., :3, 3].copy(), q


def invert_pose(pose: np.ndarray) -> np.ndarray:
    """Invert rigid transforms [..., 4, 4] without a general matrix inverse."""
    pose = np.asarray(pose, dtype=np.float64)
    rot_t = np.swapaxes(pose[..., :3, :3], -1, -2)
    out = np.zeros_like(pose)
    out[..., :3, :3] = rot_t
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", rot_t, pose[..., :3, 3])
    out[..., 3, 3] = 1.0
    return out


def interpolate_pose(
    pose_a: np.ndarray, pose_b: np.ndarray, alpha: float | np.ndarray
) -> np.ndarray:
    """Interpolate between two poses: slerp of the rotation, lerp of the translation.

    This is the exposure-trajectory model of EGS-SLAM, ``T(eta)`` with ``alpha = eta / tau``.

    Args:
        pose_a: pose at ``alpha = 0``, shape [4, 4].
        pose_b: pose at ``alpha = 1``, shape [4, 4].
        alpha: scalar or array [M] of interpolation fractions (extrapolation allowed).

    Returns:
        Pose [4, 4] for a scalar ``alpha``, else poses [M, 4, 4].
    """
    alphas = np.atleast_1d(np.asarray(alpha, dtype=np.float64))
    rot_a = Rotation.from_matrix(pose_a[:3, :3])
    rel = rot_a.inv() * Rotation.from_matrix(pose_b[:3, :3])
    rotvec = rel.as_rotvec()
    rots = (rot_a * Rotation.from_rotvec(alphas[:, None] * rotvec[None])).as_matrix()
    out = np.zeros((len(alphas), 4, 4))
    out[:, :3, :3] = rots
    out[:, :3, 3] = (1 - alphas)[:, None] * pose_a[:3, 3] + alphas[:, None] * pose_b[:3, 3]
    out[:, 3, 3] = 1.0
    return out[0] if np.ndim(alpha) == 0 else out


def interpolate_trajectory(
    times: np.ndarray, poses: np.ndarray, query_times: np.ndarray
) -> np.ndarray:
    """Sample a trajectory at new times (slerp/lerp between the bracketing samples).

    Args:
        times: sample times, shape [N], strictly increasing (any unit, same as ``query_times``).
        poses: poses at ``times``, shape [N, 4, 4].
        query_times: times to sample, shape [M], inside ``[times[0], times[-1]]``.

    Returns:
        Poses, shape [M, 4, 4].
    """
    times = np.asarray(times, dtype=np.float64)
    query = np.asarray(query_times, dtype=np.float64)
    if query.min() < times[0] - 1e-9 or query.max() > times[-1] + 1e-9:
        raise ValueError("query times outside the trajectory's time range")
    query = np.clip(query, times[0], times[-1])
    slerp = Slerp(times, Rotation.from_matrix(poses[:, :3, :3]))
    out = np.zeros((len(query), 4, 4))
    out[:, :3, :3] = slerp(query).as_matrix()
    for axis in range(3):
        out[:, axis, 3] = np.interp(query, times, poses[:, axis, 3])
    out[:, 3, 3] = 1.0
    return out


def rotation_angle(pose_a: np.ndarray, pose_b: np.ndarray) -> float:
    """Angle in radians of the relative rotation between two poses [4, 4]."""
    rel = pose_a[:3, :3].T @ pose_b[:3, :3]
    return float(np.arccos(np.clip((np.trace(rel) - 1) / 2, -1.0, 1.0)))
