"""Keyframe selection and window removal (slam/keyframes.py), MonoGS's rules."""

from __future__ import annotations

import numpy as np

from egs_bench.slam import keyframes


def _vis(idx: list[int], n: int = 10) -> np.ndarray:
    v = np.zeros(n, bool)
    v[idx] = True
    return v


def _pose_at(x: float) -> np.ndarray:
    p = np.eye(4)
    p[0, 3] = -x  # world-to-camera of a camera at (x, 0, 0)
    return p


def test_keyframe_selection_rules() -> None:
    from egs_bench.slam.config import KeyframeConfig

    r = KeyframeConfig(interval=4, overlap=0.9, min_translation=0.02, translation=0.04)
    same = _vis(list(range(10)))
    half = _vis(list(range(5)))
    policy = keyframes.MonoGSKeyframes(r, window_size=3)

    def wanted(frame: int, x: float, vis: np.ndarray, window_len: int) -> bool:
        return policy.is_keyframe(keyframes.KeyframeCandidate(
            frame, 0, _pose_at(x), _pose_at(0.0), vis, same, 1.0, window_len))

    assert not wanted(3, 1.0, half, 1)  # too soon
    # window not full: overlap decides
    assert wanted(4, 0.0, half, 1)
    assert not wanted(4, 1.0, same, 1)
    # window full: large translation alone, small translation needs low overlap
    assert wanted(4, 0.05, same, 3)
    assert not wanted(4, 0.03, same, 3)
    assert wanted(4, 0.03, half, 3)
    assert not wanted(4, 0.01, half, 3)


def test_window_removal_overlap_then_dso() -> None:
    from egs_bench.slam.config import KeyframeConfig

    r = KeyframeConfig(cutoff=0.4)
    vis = {0: _vis([0, 1]), 1: _vis([1, 2, 3]), 2: _vis([2, 3, 4]), 3: _vis([3, 4, 5]),
           4: _vis([3, 4, 5])}
    poses = {k: _pose_at(float(k)) for k in range(5)}
    # New KF 4; window [3, 2, 1, 0]; unprotected 2, 1, 0. Overlap with 4: kf2 2/3, kf1 1/3,
    # kf0 0 -> candidates 1 and 0, the oldest (0) goes; window [4,3,2,1] still > 3 -> DSO.
    win, removed = keyframes.update_window([3, 2, 1, 0], 4, vis, poses, r, 3)
    assert removed[0] == 0 and len(win) == 3 and win[:2] == [4, 3]
    # DSO among {2, 1}: score(2) = sqrt(2) * 1/1, score(1) = sqrt(3) * 1/1 -> remove 1.
    assert removed[1] == 1 and win == [4, 3, 2]
    # Nothing removed while the window has room and overlaps are high.
    vis_all = {k: _vis(list(range(10))) for k in range(5)}
    win2, removed2 = keyframes.update_window([3, 2, 1, 0], 4, vis_all, poses, r, 10)
    assert removed2 == [] and win2 == [4, 3, 2, 1, 0]
