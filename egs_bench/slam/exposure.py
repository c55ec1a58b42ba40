"""The exposure trajectory of one frame: two poses, linear motion in between, K sub-poses.

``T(eta)`` (paper eq. 4) slerps the rotation and lerps the translation between the pose at the
start of the exposure, ``T_0``, and at its end, ``T_tau``. We interpolate the camera-to-world
poses (so the camera *centre* moves on a straight line, the physical constant-velocity model
that the data generator also uses) and hand world-to-camera matrices to the rasteriser.

The sub-pose times ``eta_0 = 0 < eta_1 < ... < eta_K = tau`` split the exposure so that every
segment holds about the same number of events (uniform when there are too few events).
"""

from __future__ import annotations

import numpy as np
import torch

from egs_bench.slam.lie import invert_rigid, make_pose, so3_exp, so3_log


def interpolate_c2w(pose0_wc: torch.Tensor, pose1_wc: torch.Tensor, fractions: torch.Tensor
                    ) -> torch.Tensor:
    """Poses [M, 4, 4] at ``fractions`` [M] (0 -> pose0, 1 -> pose1), slerp + lerp.

    Differentiable w.r.t. both poses. Args are camera-to-world [4, 4].
    """
    rot0, rot1 = pose0_wc[:3, :3], pose1_wc[:3, :3]
    rel = so3_log(rot0.transpose(0, 1) @ rot1)  # [3]
    f = fractions.to(pose0_wc.dtype)
    rots = rot0 @ so3_exp(f[:, None] * rel[None])  # [M, 3, 3]
    trans = (1 - f)[:, None] * pose0_wc[:3, 3] + f[:, None] * pose1_wc[:3, 3]
    return make_pose(rots, trans)


def interpolate_w2c(pose0_cw: torch.Tensor, pose1_cw: torch.Tensor, fractions: torch.Tensor
                    ) -> torch.Tensor:
    """World-to-camera sub-poses [M, 4, 4] from world-to-camera end poses [4, 4] each.

    Interpolation happens on the camera-to-world poses (straight-line camera centre).
    """
    return invert_rigid(interpolate_c2w(invert_rigid(pose0_cw), invert_rigid(pose1_cw),
                                        fractions))


def subpose_fractions(event_t_us: np.ndarray, t_start_us: int, t_end_us: int, n_segments: int,
                      min_events: int | None = None) -> np.ndarray:
    """Fractions ``eta_k / tau`` [K+1] of the exposure at the sub-pose times.

    Interior boundaries are the event-count quantiles, so each of the ``K`` segments holds about
    the same number of events; with fewer than ``min_events`` (default ``4 K``) events in the
    window the split is uniform. Boundaries are forced strictly increasing.

    Args:
        event_t_us: event timestamps (int64 us) inside ``[t_start_us, t_end_us)``.
        t_start_us, t_end_us: exposure window.
        n_segments: K >= 1.
    """
    if n_segments < 1:
        raise ValueError("n_segments must be >= 1")
    tau = float(t_end_us - t_start_us)
    uniform = np.linspace(0.0, 1.0, n_segments + 1)
    if tau <= 0:
        return uniform
    need = 4 * n_segments if min_events is None else min_events
    t = np.asarray(event_t_us, dtype=np.float64)
    t = t[(t >= t_start_us) & (t <= t_end_us)]
    if n_segments == 1 or len(t) < max(need, 1):
        return uniform
    inner = (np.quantile(t, uniform[1:-1]) - t_start_us) / tau
    frac = np.concatenate([[0.0], np.clip(inner, 0.0, 1.0), [1.0]])
    # Keep segments non-degenerate (a burst of events at one instant would collapse them).
    min_gap = 0.02 / n_segments
    for k in range(1, n_segments + 1):
        frac[k] = max(frac[k], frac[k - 1] + min_gap)
    if frac[-1] > 1.0 + 1e-12:  # pushed past the end: rescale the tail back into [0, 1]
        frac = frac / frac[-1]
    frac[-1] = 1.0
    return frac


def segment_edges_us(fractions: np.ndarray, t_start_us: int, t_end_us: int) -> np.ndarray:
    """Sub-pose times in microseconds [K+1] (int64), first = t_start, last = t_end."""
    edges = np.round(t_start_us + fractions * (t_end_us - t_start_us)).astype(np.int64)
    edges[0], edges[-1] = t_start_us, t_end_us
    return edges
