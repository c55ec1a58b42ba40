"""Keyframe selection and window maintenance (MonoGS RGB-D rules, DSO-style removal).

Visibility sets are boolean arrays [N] over the Gaussians of the map (True = the Gaussian
contributes to the keyframe's render). Poses are world-to-camera 4x4 numpy float64 arrays.
The window is ordered newest first, as in MonoGS.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from egs_bench.slam.config import KeyframeConfig


def _padded(a: np.ndarray, n: int) -> np.ndarray:
    """Visibility arrays grow with the map; missing (newer) Gaussians count as invisible."""
    if len(a) >= n:
        return a[:n]
    return np.concatenate([a, np.zeros(n - len(a), dtype=bool)])


def visibility_iou(vis_a: np.ndarray, vis_b: np.ndarray) -> float:
    """|A & B| / |A | B| of two visibility masks (0 when both are empty)."""
    n = max(len(vis_a), len(vis_b))
    a, b = _padded(vis_a, n), _padded(vis_b, n)
    union = np.count_nonzero(a | b)
    return 0.0 if union == 0 else np.count_nonzero(a & b) / union


def visibility_overlap_coefficient(vis_a: np.ndarray, vis_b: np.ndarray) -> float:
    """Szymkiewicz–Simpson coefficient |A & B| / min(|A|, |B|) (0 when either is empty)."""
    n = max(len(vis_a), len(vis_b))
    a, b = _padded(vis_a, n), _padded(vis_b, n)
    denom = min(np.count_nonzero(a), np.count_nonzero(b))
    return 0.0 if denom == 0 else np.count_nonzero(a & b) / denom


def relative_translation(pose_a_cw: np.ndarray, pose_b_cw: np.ndarray) -> float:
    """Distance between two camera centres, ``|t(T_a,w T_w,b)|`` in metres."""
    rel = pose_a_cw @ np.linalg.inv(pose_b_cw)
    return float(np.linalg.norm(rel[:3, 3]))


@dataclass(frozen=True)
class KeyframeCandidate:
    """A tracked frame and what the keyframe test compares it with.

    Attributes:
        frame_idx, last_kf_idx: the frame's and the last keyframe's indices.
        pose_cw, last_kf_pose_cw: their world-to-camera poses [4, 4].
        vis, last_kf_vis: their visibility sets, bool [N] over the Gaussians.
        median_depth: median rendered depth of the frame (m).
        window_len: keyframes in the window now.
    """

    frame_idx: int
    last_kf_idx: int
    pose_cw: np.ndarray
    last_kf_pose_cw: np.ndarray
    vis: np.ndarray
    last_kf_vis: np.ndarray
    median_depth: float
    window_len: int


def is_keyframe(c: KeyframeCandidate, rules: KeyframeConfig, window_size: int) -> bool:
    """MonoGS's single-thread keyframe test for the tracked frame ``c.frame_idx``.

    A frame becomes a keyframe when enough frames have passed (``interval``) and either the
    window (of ``window_size``) is not yet full and the overlap (IoU) with the last keyframe is
    below ``overlap``, or the camera moved more than ``translation`` x median depth, or it
    moved more than ``min_translation`` x median depth while the overlap is below ``overlap``.
    """
    if c.frame_idx - c.last_kf_idx < rules.interval:
        return False
    iou = visibility_iou(c.vis, c.last_kf_vis)
    if c.window_len < window_size:
        return iou < rules.overlap
    dist = relative_translation(c.pose_cw, c.last_kf_pose_cw)
    return bool((iou < rules.overlap and dist > rules.min_translation * c.median_depth)
                or dist > rules.translation * c.median_depth)


def update_window(window: list[int], new_kf: int, visibility: dict[int, np.ndarray],
                  poses_cw: dict[int, np.ndarray], rules: KeyframeConfig, window_size: int
                  ) -> tuple[list[int], list[int]]:
    """Insert ``new_kf`` at the front of the window and remove keyframes (MonoGS rules).

    First, among the unprotected keyframes whose overlap coefficient with the new keyframe is
    at most ``cutoff``, the oldest one is removed. Then, if the window is still longer than
    ``window_size``, the keyframe with the largest DSO score
    ``sqrt(d(i, newest)) * sum_j 1 / (d(i, j) + 1e-6)`` (j over the other unprotected ones) is
    removed.

    Returns:
        (new window newest first, removed keyframe ids).
    """
    win = [new_kf] + [k for k in window if k != new_kf]
    removed: list[int] = []
    cur_vis = visibility[new_kf]
    candidates = [k for k in win[rules.protected:]
                  if visibility_overlap_coefficient(cur_vis, visibility[k]) <= rules.cutoff]
    if candidates:
        removed.append(candidates[-1])
        win.remove(candidates[-1])
    if len(win) > window_size:
        unprotected = win[rules.protected:]
        newest = poses_cw[win[0]]
        best, best_score = None, -np.inf
        for i in unprotected:
            d_new = relative_translation(poses_cw[i], newest)
            s = sum(1.0 / (relative_translation(poses_cw[i], poses_cw[j]) + 1e-6)
                    for j in unprotected if j != i)
            score = np.sqrt(d_new) * s
            if score > best_score:
                best, best_score = i, score
        assert best is not None
        removed.append(best)
        win.remove(best)
    return win, removed


class MonoGSKeyframes:
    """The default :class:`~egs_bench.slam.components.KeyframePolicy`: MonoGS's RGB-D rules
    (:func:`is_keyframe`, :func:`update_window`) with the run's window size."""

    def __init__(self, rules: KeyframeConfig, window_size: int) -> None:
        self.rules, self.window_size = rules, window_size

    def is_keyframe(self, candidate: KeyframeCandidate) -> bool:
        return is_keyframe(candidate, self.rules, self.window_size)

    def update_window(self, window: list[int], new_kf: int, visibility: dict[int, np.ndarray],
                      poses_cw: dict[int, np.ndarray]) -> tuple[list[int], list[int]]:
        return update_window(window, new_kf, visibility, poses_cw, self.rules, self.window_size)
