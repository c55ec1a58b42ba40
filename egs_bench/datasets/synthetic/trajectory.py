"""Camera trajectories for synthetic scenes: seeded hand-held motion, or a re-timed TUM file.

Hand-held model (:class:`HandheldTrajectory`), all components smooth (sums of sinusoids):

* camera centre ``p(s) = c + (h - a) * sum_k w_k sin(2 pi f_k s + phi_k) + a * shake(s)`` per
  axis, where ``c, h`` are the centre and half size of the scene's camera box, ``sum_k w_k = 1``
  and ``|shake| <= 1``, so ``p`` never leaves the box (``a`` = shake amplitude);
* the camera looks at ``q(s)``, built the same way inside the scene's target box, with world
  ``+z`` as up; then a small roll and a rotational hand shake are applied in the camera frame;
* ``s = speed * t``: ``speed`` re-times the same path, so every velocity scales by ``speed``
  (and motion blur with it) while the visited places stay the same.

Frequencies and phases come from ``seed``. Path frequencies are 0.12-1 Hz, shake 2-6 Hz (at
``speed = 1``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from egs_bench.geometry import Trajectory, interpolate_trajectory, invert_pose

_UP = np.array([0.0, 0.0, 1.0])


def look_at(eye: np.ndarray, target: np.ndarray, up: np.ndarray = _UP) -> np.ndarray:
    """``T_wc`` [4, 4] (OpenCV axes) of a camera at ``eye`` [3] looking at ``target`` [3].

    Camera ``z`` points at the target, ``x`` to the right and ``y`` down relative to ``up``.
    Batched: ``eye``, ``target`` may be [N, 3], giving [N, 4, 4].
    """
    eye = np.asarray(eye, dtype=np.float64)
    target = np.asarray(target, dtype=np.float64)
    z = target - eye
    z = z / np.linalg.norm(z, axis=-1, keepdims=True)
    x = np.cross(z, np.broadcast_to(up, z.shape))
    x = x / np.linalg.norm(x, axis=-1, keepdims=True)
    y = np.cross(z, x)
    pose = np.zeros((*eye.shape[:-1], 4, 4))
    pose[..., :3, 0], pose[..., :3, 1], pose[..., :3, 2] = x, y, z
    pose[..., :3, 3] = eye
    pose[..., 3, 3] = 1.0
    return pose


@dataclass(frozen=True)
class _SinusoidSum:
    """``sum_k w_k sin(2 pi f_k s + phi_k)`` per channel; ``freqs, phases, weights``: [C, K]."""

    freqs: np.ndarray
    phases: np.ndarray
    weights: np.ndarray

    @staticmethod
    def random(
        rng: np.random.Generator, channels: int, bands: list[tuple[float, float]], decay: float
    ) -> _SinusoidSum:
        k = len(bands)
        lo = np.array([b[0] for b in bands])
        hi = np.array([b[1] for b in bands])
        freqs = rng.uniform(lo, hi, size=(channels, k))
        phases = rng.uniform(0, 2 * np.pi, size=(channels, k))
        weights = np.broadcast_to(decay ** np.arange(k), (channels, k)).copy()
        weights /= weights.sum(axis=1, keepdims=True)
        return _SinusoidSum(freqs, phases, weights)

    def __call__(self, s: np.ndarray) -> np.ndarray:
        """Values [N, C] at times ``s`` [N]; each channel is in [-1, 1]."""
        arg = 2 * np.pi * self.freqs[None] * s[:, None, None] + self.phases[None]
        return (self.weights[None] * np.sin(arg)).sum(axis=-1)


# Frequency bands (Hz at speed 1). Chosen so that speed 1 gives a mean image motion of about
# 4 px per 20 ms at 448 px width in the office / living room / studio (moderate blur); the
# corridor, seen from farther away, moves about half as much in the image.
_PATH_BANDS = [(0.12, 0.25), (0.25, 0.5), (0.5, 1.0)]
_SHAKE_BANDS = [(2.0, 3.5), (3.5, 6.0)]


class HandheldTrajectory:
    """Smooth seeded hand-held 6-DoF motion inside a box, looking into a target box.

    Args:
        camera_box: ``(lo, hi)`` world corners the camera centre stays in.
        target_box: ``(lo, hi)`` world corners of the look-at point.
        speed: time scale of the motion (velocities scale by it; 0 = static camera).
        seed: seeds frequencies and phases.
        roll_deg: amplitude of the slow roll about the viewing axis.
        shake_deg: amplitude of the rotational hand shake (per axis).
        shake_m: amplitude of the positional hand shake (per axis, metres).
    """

    def __init__(
        self,
        camera_box: tuple,
        target_box: tuple,
        speed: float = 1.0,
        seed: int = 0,
        roll_deg: float = 4.0,
        shake_deg: float = 0.4,
        shake_m: float = 0.003,
    ) -> None:
        if not speed >= 0 or not np.isfinite(speed):
            raise ValueError(f"speed must be finite and >= 0, got {speed}")
        self.cam_lo, self.cam_hi = (np.asarray(b, dtype=np.float64) for b in camera_box)
        self.tgt_lo, self.tgt_hi = (np.asarray(b, dtype=np.float64) for b in target_box)
        half = (self.cam_hi - self.cam_lo) / 2
        if (half < shake_m).any():
            raise ValueError("camera box is smaller than the shake amplitude")
        self.speed = float(speed)
        self.shake_m = shake_m
        self.roll = np.deg2rad(roll_deg)
        self.shake_rad = np.deg2rad(shake_deg)
        rng = np.random.default_rng(seed)
        self._pos = _SinusoidSum.random(rng, 3, _PATH_BANDS, 0.6)
        self._tgt = _SinusoidSum.random(rng, 3, _PATH_BANDS, 0.6)
        self._roll = _SinusoidSum.random(rng, 1, _PATH_BANDS, 0.6)
        self._pos_shake = _SinusoidSum.random(rng, 3, _SHAKE_BANDS, 0.7)
        self._rot_shake = _SinusoidSum.random(rng, 3, _SHAKE_BANDS, 0.7)

    def positions_targets(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Camera centres [N, 3] and look-at points [N, 3] at times ``t_s`` [N] (seconds)."""
        s = self.speed * np.atleast_1d(np.asarray(t_s, dtype=np.float64))
        c = (self.cam_lo + self.cam_hi) / 2
        h = (self.cam_hi - self.cam_lo) / 2
        eye = c + (h - self.shake_m) * self._pos(s) + self.shake_m * self._pos_shake(s)
        tc = (self.tgt_lo + self.tgt_hi) / 2
        th = (self.tgt_hi - self.tgt_lo) / 2
        return eye, tc + th * self._tgt(s)

    def poses(self, t_s: np.ndarray) -> np.ndarray:
        """``T_wc`` [N, 4, 4] at times ``t_s`` [N] (seconds)."""
        s = self.speed * np.atleast_1d(np.asarray(t_s, dtype=np.float64))
        eye, target = self.positions_targets(t_s)
        base = look_at(eye, target)
        rotvec = self.shake_rad * self._rot_shake(s)
        rotvec[:, 2] += self.roll * self._roll(s)[:, 0]
        out = base.copy()
        out[:, :3, :3] = base[:, :3, :3] @ Rotation.from_rotvec(rotvec).as_matrix()
        return out

    def pose(self, t_s: float) -> np.ndarray:
        """``T_wc`` [4, 4] at time ``t_s`` (seconds)."""
        return self.poses(np.array([t_s]))[0]


class TumTrajectoryInRoom:
    """A recorded trajectory re-timed and moved into a scene.

    The file's motion relative to its first pose is replayed from the scene's anchor pose:
    ``T_wc(t) = A * inv(T_0) * T_file(t_0 + t * speed / time_scale)``, where ``A`` is the
    anchor (camera-box centre looking at the target-box centre), ``T_0`` the file's first pose
    and ``t_0`` its first time stamp. ``time_scale > 1`` slows the motion (less blur).

    Args:
        trajectory: the file's poses (seconds, ``T_wc``).
        anchor: ``T_wc`` [4, 4] where the file's first pose is placed.
        speed, time_scale: re-timing factors (see above).
    """

    def __init__(
        self, trajectory: Trajectory, anchor: np.ndarray, speed: float = 1.0,
        time_scale: float = 1.0,
    ) -> None:  # fmt: skip
        if not (np.isfinite(speed) and speed > 0 and np.isfinite(time_scale) and time_scale > 0):
            raise ValueError("speed and time_scale must be finite and > 0")
        self.trajectory = trajectory
        self.rate = speed / time_scale
        self._align = np.asarray(anchor, np.float64) @ invert_pose(trajectory.poses[0])

    @property
    def duration_s(self) -> float:
        """Length in sequence seconds that the file covers after re-timing."""
        ts = self.trajectory.timestamps
        return float(ts[-1] - ts[0]) / self.rate

    def poses(self, t_s: np.ndarray) -> np.ndarray:
        """``T_wc`` [N, 4, 4] at sequence times ``t_s`` [N] (seconds, within the duration)."""
        ts = self.trajectory.timestamps
        query = ts[0] + np.atleast_1d(np.asarray(t_s, dtype=np.float64)) * self.rate
        raw = interpolate_trajectory(ts, self.trajectory.poses, query)
        return self._align[None] @ raw

    def pose(self, t_s: float) -> np.ndarray:
        return self.poses(np.array([t_s]))[0]
