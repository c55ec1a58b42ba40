"""Tracking: optimise a frame's exposure trajectory (T_0, T_tau) with the map fixed.

MonoGS style: a twist per pose left-multiplies the world-to-camera matrix; after every Adam
step the increment is folded into the pose and reset to zero (the Adam moments persist), and
tracking stops once the step is below ``converged_threshold``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from egs_bench.render import GaussianMap
from egs_bench.slam.config import SlamConfig
from egs_bench.slam.crf import CameraResponse
from egs_bench.slam.exposure import interpolate_w2c
from egs_bench.slam.frames import FrameObs, FrameState
from egs_bench.slam.lie import se3_exp
from egs_bench.slam.render_model import frame_loss, render_views, subposes


@dataclass
class TrackResult:
    state: FrameState
    loss: float
    iterations: int
    converged: bool


class PoseIncrements:
    """Zero-initialised twists for a set of poses, split into translation and rotation parts so
    each gets its own learning rate (MonoGS: rho 0.001, theta 0.003)."""

    def __init__(self, n: int, dtype: torch.dtype, device: torch.device) -> None:
        self.rho = torch.zeros(n, 3, dtype=dtype, device=device, requires_grad=True)
        self.theta = torch.zeros(n, 3, dtype=dtype, device=device, requires_grad=True)

    def twists(self, mask: torch.Tensor | None = None) -> torch.Tensor:
        """Increments [n, 6] (rho, theta), times ``mask`` [n, 1] when given (0 = frozen)."""
        xi = torch.cat([self.rho, self.theta], -1)
        return xi if mask is None else xi * mask

    def apply(self, poses_cw: torch.Tensor, mask: torch.Tensor | None = None) -> torch.Tensor:
        """``exp(xi_j) @ T_j`` for poses [n, 4, 4]."""
        return se3_exp(self.twists(mask)) @ poses_cw

    @torch.no_grad()
    def fold(self, poses_cw: torch.Tensor, mask: torch.Tensor | None = None
             ) -> tuple[torch.Tensor, float]:
        """Poses with the increments folded in, and the largest increment norm; zeros them."""
        xi = self.twists(mask)
        new = se3_exp(xi) @ poses_cw
        norm = float(xi.norm(dim=-1).max()) if xi.numel() else 0.0
        self.rho.zero_()
        self.theta.zero_()
        return new, norm


def track_frame(gmap: GaussianMap, crf: CameraResponse, obs: FrameObs, init: FrameState,
                K: torch.Tensor, width: int, height: int, cfg: SlamConfig,
                theta: tuple[float, float], eps: float, lr_scale: float = 1.0,
                start_anchor: tuple[torch.Tensor, float] | None = None) -> TrackResult:
    """Estimate ``T_0, T_tau`` (and exposure a, b) of one frame against the fixed map.

    Args:
        init: initial estimate (its poses are not modified).
        K: intrinsics [3, 3] at the internal resolution.
        lr_scale: multiplies the pose learning rates (used when re-tracking after divergence).
        start_anchor: ``(T_tau of the previous frame [4, 4], f0)``: ``T_0`` is then not free
            but tied to the motion since the previous frame, ``T_0 = T(f0)`` on the path from
            the previous ``T_tau`` to this ``T_tau`` (constant velocity across the gap between
            exposures), so only ``T_tau`` is estimated (``continuous_exposure``, short exposures).
    """
    blur = obs.fractions.numel() > 1
    poses = torch.stack([init.pose0_cw, init.pose1_cw]).detach().clone()
    anchored = blur and start_anchor is not None
    n_opt = 2 if blur and not anchored else 1
    inc = PoseIncrements(n_opt, poses.dtype, poses.device)
    exp_a = torch.tensor(init.exp_a, dtype=gmap.dtype, device=gmap.device, requires_grad=True)
    exp_b = torch.tensor(init.exp_b, dtype=gmap.dtype, device=gmap.device, requires_grad=True)
    groups = [{"params": [inc.rho], "lr": cfg.lr_trans * lr_scale},
              {"params": [inc.theta], "lr": cfg.lr_rot * lr_scale}]
    if cfg.exposure_compensation:
        groups.append({"params": [exp_a, exp_b], "lr": cfg.lr_exposure})
    opt = torch.optim.Adam(groups)
    # Exponential decay from lr to lr x tracking_lr_final over the iteration budget: large first
    # steps follow fast motion, small last steps stop Adam's oscillation around the optimum.
    decay = cfg.tracking_lr_final ** (1.0 / max(cfg.tracking_iters - 1, 1))
    sched = torch.optim.lr_scheduler.ExponentialLR(opt, decay)
    was_grad = gmap.means.requires_grad
    gmap.requires_grad_(False)
    loss_val, it, converged = math.inf, 0, False
    try:
        for step_i in range(1, cfg.tracking_iters + 1):
            it = step_i
            opt.zero_grad(set_to_none=True)
            cur = inc.apply(poses[2 - n_opt:])
            if anchored:
                p1 = cur[0]
                p0 = _anchored_start(start_anchor, p1)
            else:
                p0, p1 = (cur[0], cur[1]) if blur else (poses[0], cur[0])
            res = render_views(gmap, subposes(p0, p1, obs.fractions), K, width, height, cfg)
            parts = frame_loss(res, obs, crf, exp_a, exp_b, cfg, tracking=True,
                               use_events=cfg.event_tracking, theta=theta, eps=eps)
            loss_val = float(parts.total.detach())
            if not math.isfinite(loss_val):
                break
            parts.total.backward()
            opt.step()
            sched.step()
            folded, step = inc.fold(poses[2 - n_opt:])
            poses[2 - n_opt:] = folded
            if step < cfg.converged_threshold:
                converged = True
                break
    finally:
        gmap.requires_grad_(was_grad)
    if anchored:
        with torch.no_grad():
            poses[0] = _anchored_start(start_anchor, poses[1])
    elif not blur:
        poses[0] = poses[1]
    state = FrameState(init.index, poses[0].clone(), poses[1].clone(), float(exp_a.detach()),
                       float(exp_b.detach()))
    return TrackResult(state, loss_val, it, converged)


def _anchored_start(anchor: tuple[torch.Tensor, float], pose1_cw: torch.Tensor) -> torch.Tensor:
    """``T_0`` [4, 4] at fraction ``anchor[1]`` of the path from ``anchor[0]`` to ``pose1_cw``."""
    prev_cw, f0 = anchor
    frac = torch.tensor([f0], dtype=pose1_cw.dtype, device=pose1_cw.device)
    return interpolate_w2c(prev_cw, pose1_cw, frac)[0]


def predict_initial(index: int, history: list[FrameState], motion_model: str,
                    t_start_us: int, t_end_us: int, prev_end_us: int | None,
                    prev_prev_end_us: int | None, prev_start_us: int | None = None
                    ) -> FrameState:
    """Initial exposure trajectory of frame ``index`` from the previous estimates.

    ``constant-position`` (MonoGS): both poses start at the previous frame's ``T_tau``.
    ``constant-velocity``: ``T_tau`` extrapolates the last inter-frame motion (scaled by the
    time gap); ``T_0`` is placed on that motion at the exposure start. With a single previous
    frame whose exposure trajectory is non-degenerate (blur model: ``T_0 != T_tau``), the
    velocity is that frame's intra-exposure motion ``T_0 -> T_tau`` over
    ``prev_end_us - prev_start_us``: the blur model measures the velocity before any
    inter-frame motion exists.
    """
    from egs_bench.slam.exposure import interpolate_w2c
    from egs_bench.slam.lie import invert_rigid, se3_exp, so3_log

    last = history[-1]
    p_last = last.pose1_cw
    if motion_model != "constant-velocity" or prev_end_us is None:
        return FrameState(index, p_last.clone(), p_last.clone(), last.exp_a, last.exp_b)
    rel, span = None, 0
    if len(history) >= 2 and prev_prev_end_us is not None and prev_end_us > prev_prev_end_us:
        rel = p_last @ invert_rigid(history[-2].pose1_cw)  # motion over the last interval
        span = prev_end_us - prev_prev_end_us
    elif prev_start_us is not None and prev_end_us > prev_start_us and not torch.equal(
            last.pose0_cw, last.pose1_cw):
        rel = p_last @ invert_rigid(last.pose0_cw)  # motion during the last exposure
        span = prev_end_us - prev_start_us
    if rel is None:
        return FrameState(index, p_last.clone(), p_last.clone(), last.exp_a, last.exp_b)
    scale = (t_end_us - prev_end_us) / span
    xi = torch.cat([rel[:3, 3], so3_log(rel[:3, :3])])  # small motion: twist ~ (t, log R)
    pred1 = se3_exp(xi * scale) @ p_last
    f0 = (t_start_us - prev_end_us) / max(t_end_us - prev_end_us, 1)
    pred0 = interpolate_w2c(p_last, pred1, torch.tensor([np.clip(f0, 0.0, 1.0)]))[0]
    return FrameState(index, pred0, pred1, last.exp_a, last.exp_b)
