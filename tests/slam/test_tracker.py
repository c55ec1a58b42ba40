"""Motion prediction of the tracker (slam/tracker.py)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from egs_bench.geometry import invert_pose


def _pose_cw(t: tuple[float, float, float], yaw_deg: float = 0.0) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, :3] = Rotation.from_euler("z", yaw_deg, degrees=True).as_matrix()
    pose[:3, 3] = t
    return pose


def test_last_motion_and_constant_velocity_prediction() -> None:
    """No velocity before two end poses exist (unless frame 0's exposure trajectory is
    non-degenerate); with two, the prediction extrapolates the last motion by the time gap."""
    from egs_bench.slam.frames import FrameState
    from egs_bench.slam.tracker import last_motion, predict_initial

    p0 = _pose_cw((0.0, 0.0, 0.0))
    first = [FrameState(0, p0, p0.copy())]
    assert last_motion(first, "constant-velocity", 30_000, None, 10_000) is None
    start = predict_initial(1, first, "constant-velocity", 40_000, 60_000, 30_000, None, 10_000)
    np.testing.assert_allclose(start.pose1_cw, p0)
    p1 = _pose_cw((0.02, 0.0, 0.0), 1.0)
    two = [first[0], FrameState(1, p1, p1.copy())]
    motion = last_motion(two, "constant-velocity", 60_000, 30_000, 40_000)
    assert motion is not None
    rel, span = motion
    np.testing.assert_allclose(rel, p1 @ invert_pose(p0), atol=1e-12)
    assert span == 30_000
    assert last_motion(two, "constant-position", 60_000, 30_000, 40_000) is None
    # Twice the gap: twice the translation and the yaw (a pure yaw with t along x composes
    # to these within the small-motion twist approximation of predict_initial).
    pred = predict_initial(2, two, "constant-velocity", 100_000, 120_000, 60_000, 30_000, 80_000)
    step = pred.pose1_cw @ invert_pose(p1)
    yaw = Rotation.from_matrix(step[:3, :3]).as_euler("zyx", degrees=True)[0]
    assert yaw == pytest.approx(2.0, abs=1e-9)
    assert np.linalg.norm(step[:3, 3]) == pytest.approx(0.04, rel=0.02)
    # A non-degenerate frame-0 exposure trajectory is itself a velocity.
    moving = [FrameState(0, p0, _pose_cw((0.01, 0.0, 0.0)))]
    assert last_motion(moving, "constant-velocity", 30_000, None, 10_000) is not None
