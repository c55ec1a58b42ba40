"""Poses (SE(3)/SO(3)), trajectories (TUM files) and pinhole intrinsics.

Conventions (docs/design.md §2): poses are 4x4 float64 matrices, ``T_wc`` camera-to-world,
OpenCV camera axes; quaternions in TUM files are ``qx qy qz qw``; time is int64 microseconds
inside the toolkit and seconds in TUM files; pixel ``(u, v)`` has its centre at ``u + 0.5``.
"""

from egs_bench.geometry.camera import Intrinsics
from egs_bench.geometry.se3 import (
    interpolate_pose,
    interpolate_trajectory,
    invert_pose,
    pose_from_tq,
    pose_to_tq,
    rotation_angle,
)
from egs_bench.geometry.tum import Trajectory, read_tum, write_tum

__all__ = [
    "Intrinsics",
    "Trajectory",
    "interpolate_pose",
    "interpolate_trajectory",
    "invert_pose",
    "pose_from_tq",
    "pose_to_tq",
    "read_tum",
    "rotation_angle",
    "write_tum",
]
