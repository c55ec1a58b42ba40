"""Exposure trajectory and sub-pose split (slam/exposure.py) against scipy and event counts."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from egs_bench.geometry import interpolate_pose, invert_pose
from egs_bench.slam import exposure


def _random_pose(rng: np.random.Generator, rot_scale: float = 1.0) -> np.ndarray:
    p = np.eye(4)
    p[:3, :3] = Rotation.from_rotvec(rng.normal(size=3) * rot_scale).as_matrix()
    p[:3, 3] = rng.normal(size=3)
    return p


def test_exposure_path_matches_numpy_slerp_lerp() -> None:
    """Sub-poses equal geometry.interpolate_pose (scipy slerp + lerp of camera-to-world poses);
    their Jacobians are tested in test_pose_algebra.py."""
    rng = np.random.default_rng(2)
    a_wc = _random_pose(rng)
    b_wc = a_wc @ _random_pose(rng, 0.2)
    fr = np.array([0.0, 0.25, 0.5, 0.9, 1.0])
    expect_wc = interpolate_pose(a_wc, b_wc, fr)
    got_cw, _ = exposure.exposure_path(invert_pose(a_wc), invert_pose(b_wc), fr)
    np.testing.assert_allclose(invert_pose(got_cw), expect_wc, atol=1e-10)


def test_subpose_fractions_equal_event_counts_and_uniform_fallback() -> None:
    # Events dense in the first half of [0, 1000) us: boundaries must crowd there.
    t = np.concatenate([np.linspace(0, 499, 900), np.linspace(500, 999, 100)]).astype(np.int64)
    fr = exposure.subpose_fractions(t, 0, 1000, 4)
    assert fr[0] == 0 and fr[-1] == 1 and np.all(np.diff(fr) > 0)
    edges = exposure.segment_edges_us(fr, 0, 1000)
    counts = np.histogram(t, bins=edges)[0]
    assert counts.max() - counts.min() <= 0.05 * len(t)
    np.testing.assert_allclose(exposure.subpose_fractions(np.array([], np.int64), 0, 1000, 4),
                               np.linspace(0, 1, 5))
    # One instant burst: still strictly increasing.
    burst = exposure.subpose_fractions(np.full(100, 10, np.int64), 0, 1000, 4)
    assert np.all(np.diff(burst) > 0) and burst[-1] == 1
