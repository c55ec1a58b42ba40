"""TUM trajectory files: ``timestamp tx ty tz qx qy qz qw`` per line (seconds, camera-to-world)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from egs_bench.errors import InputError
from egs_bench.fileio import read_text, write_text_atomic
from egs_bench.geometry.se3 import pose_from_tq, pose_to_tq


@dataclass(frozen=True)
class Trajectory:
    """A timed sequence of camera-to-world poses.

    Attributes:
        timestamps: times in seconds, shape [N], float64, non-decreasing.
        poses: camera-to-world poses ``T_wc``, shape [N, 4, 4], float64.
    """

    timestamps: np.ndarray
    poses: np.ndarray

    def __len__(self) -> int:
        return len(self.timestamps)

    @property
    def positions(self) -> np.ndarray:
        """Camera centres in metres, shape [N, 3]."""
        return self.poses[:, :3, 3]


def read_tum(path: str | Path, min_poses: int = 1) -> Trajectory:
    """Read a TUM trajectory file, validating it.

    Lines starting with ``#`` and blank lines are ignored; commas are accepted as separators.

    Raises:
        InputError: the file is missing or not text, a line does not hold 8 numbers, a value is
            not finite,
            a quaternion has zero norm, timestamps decrease, or fewer than ``min_poses`` poses.
    """
    path = Path(path)
    rows: list[list[float]] = []
    for lineno, line in enumerate(read_text(path, "trajectory file").splitlines(), start=1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        parts = line.replace(",", " ").split()
        if len(parts) != 8:
            raise InputError(path, f"line {lineno}: expected 8 numbers "
                                   f"(t tx ty tz qx qy qz qw), found {len(parts)}")
        try:
            rows.append([float(v) for v in parts])
        except ValueError as exc:
            raise InputError(path, f"line {lineno}: not a number ({exc})") from None
    if len(rows) < min_poses:
        raise InputError(path, f"holds {len(rows)} poses, at least {min_poses} needed")
    data = np.asarray(rows, dtype=np.float64).reshape(-1, 8)
    bad = ~np.isfinite(data).all(axis=1)
    if bad.any():
        raise InputError(path, f"NaN or infinite value in pose {int(np.argmax(bad))}")
    norms = np.linalg.norm(data[:, 4:], axis=1)
    if (norms < 1e-6).any():
        raise InputError(path, f"zero quaternion in pose {int(np.argmax(norms < 1e-6))}")
    if (np.diff(data[:, 0]) < 0).any():
        raise InputError(path, "timestamps are not sorted")
    return Trajectory(data[:, 0].copy(), pose_from_tq(data[:, 1:4], data[:, 4:]))


def write_tum(path: str | Path, timestamps: np.ndarray, poses: np.ndarray) -> None:
    """Write poses [N, 4, 4] (camera-to-world) at ``timestamps`` [N] (seconds), atomically."""
    timestamps = np.asarray(timestamps, dtype=np.float64)
    poses = np.asarray(poses, dtype=np.float64)
    if len(timestamps) != len(poses):
        raise ValueError(f"{len(timestamps)} timestamps for {len(poses)} poses")
    if not np.isfinite(poses).all():
        raise ValueError(f"refusing to write non-finite poses to {path}")
    t, q = pose_to_tq(poses)
    lines = ["# timestamp tx ty tz qx qy qz qw"]
    for ts, ti, qi in zip(timestamps, t, q, strict=True):
        lines.append(f"{ts:.6f} " + " ".join(f"{v:.9f}" for v in (*ti, *qi)))
    write_text_atomic(path, "\n".join(lines) + "\n")
