"""Tracking: optimise a frame's exposure trajectory (T_0, T_tau) with the map fixed.

MonoGS style: a twist per pose left-multiplies the world-to-camera matrix; after every Adam
step the increment is folded into the pose and reset to zero (the Adam moments persist), and
tracking stops once the step is below ``converged_threshold``.

Split between host and device: the poses, their twists, the exposure scalars and their Adam
state are float64 numpy on the host (:mod:`egs_bench.geometry.lie`,
:func:`~egs_bench.slam.exposure.exposure_path`, :class:`~egs_bench.slam.host_adam.HostAdam`);
the device renders the sub-poses and evaluates the loss. Per iteration one host-to-device copy
carries the sub-poses and exposure, and one device-to-host copy brings back their gradients and
the loss: the only synchronisation. Because the twists are zero whenever the loss is
evaluated, the twist gradients follow exactly from the sub-pose gradients through the
closed-form Jacobians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import torch

from egs_bench.geometry import invert_pose
from egs_bench.geometry.lie import se3_exp, so3_log, twist_gradient
from egs_bench.render import GaussianMap
from egs_bench.slam.config import MotionModel, TrackingConfig
from egs_bench.slam.context import SlamContext
from egs_bench.slam.convergence import ConvergenceTest
from egs_bench.slam.crf import CameraResponse
from egs_bench.slam.exposure import exposure_path
from egs_bench.slam.frames import FrameObs, FrameState, coarse_observation
from egs_bench.slam.host_adam import HostAdam
from egs_bench.slam.levels import coarse_iterations
from egs_bench.slam.losses import exposure_prior_gradient
from egs_bench.slam.render_model import blur_loss, prepare_targets


@dataclass
class TrackTrace:
    """What each tracking iteration did (diagnostics, :attr:`TrackRequest.trace`).

    Attributes:
        losses: the loss evaluated by each iteration [n] (before its step).
        step_norms: the largest twist norm of the iteration's pose steps [n].
        poses1_cw: ``T_tau`` after each iteration's step [n, 4, 4].
    """

    losses: np.ndarray
    step_norms: np.ndarray
    poses1_cw: np.ndarray


@dataclass
class TrackResult:
    state: FrameState
    loss: float
    iterations: int
    converged: bool
    trace: TrackTrace | None = None


def to_device(values: np.ndarray, like: torch.Tensor) -> torch.Tensor:
    """One host-to-device copy of a flat float64 array, in ``like``'s dtype and device."""
    host = torch.from_numpy(np.ascontiguousarray(values, dtype=np.float64))
    return host.to(device=like.device, dtype=like.dtype, non_blocking=True)


def flat_grad(leaf: torch.Tensor) -> torch.Tensor:
    """The gradient of ``leaf`` after ``backward()``, flattened [N]; an error if it got none."""
    if leaf.grad is None:
        raise RuntimeError("the loss does not depend on a tensor the step needs a gradient of")
    return leaf.grad.reshape(-1)


def anchored_start(anchor: tuple[np.ndarray, float], pose1_cw: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """``T_0`` [4, 4] at fraction ``anchor[1]`` of the path from ``anchor[0]`` to ``pose1_cw``,
    and the Jacobian [6, 6] of its twist w.r.t. the twist of ``pose1_cw``."""
    prev_cw, f0 = anchor
    views, jac = exposure_path(prev_cw, pose1_cw, np.array([f0]))
    return views[0], jac[0, :, 6:]


@dataclass
class TrackRequest:
    """One frame to track.

    Attributes:
        obs: the frame's observations.
        init: initial estimate (its poses are not modified).
        start_anchor: ``(T_tau of the previous frame [4, 4], f0)``: ``T_0`` is then not free
            but tied to the motion since the previous frame, ``T_0 = T(f0)`` on the path from
            the previous ``T_tau`` to this ``T_tau`` (constant velocity across the gap between
            exposures), so only ``T_tau`` is estimated (``continuous_exposure``, short exposures).
        iterations: the iteration budget (the learning rate decays over it); None =
            ``budget.tracking_iters``.
        lr_scale: multiplies the pose learning rates (used when re-tracking after divergence).
        trace: record every iteration's loss, step and pose in the result (diagnostics).
    """

    obs: FrameObs
    init: FrameState
    start_anchor: tuple[np.ndarray, float] | None = None
    iterations: int | None = None
    lr_scale: float = 1.0
    trace: bool = False


def track_frame(ctx: SlamContext, gmap: GaussianMap, crf: CameraResponse,
                request: TrackRequest) -> TrackResult:
    """Estimate ``T_0, T_tau`` (and exposure a, b) of one frame against the fixed map (see
    :class:`TrackRequest`)."""
    cfg, obs, init, iterations = ctx.cfg, request.obs, request.init, request.iterations
    start_anchor, lr_scale = request.start_anchor, request.lr_scale
    n_iters = cfg.budget.tracking_iters if iterations is None else iterations
    fractions = obs.fractions
    blur = len(fractions) > 1
    anchor = start_anchor if blur else None
    n_free = 2 if blur and anchor is None else 1
    pose0, pose1 = init.pose0_cw.copy(), init.pose1_cw.copy()
    use_exposure = cfg.method.exposure_compensation
    exposure = np.array([init.exp_a, init.exp_b])
    lr = np.tile(np.r_[[cfg.budget.lr_trans] * 3, [cfg.budget.lr_rot] * 3] * lr_scale, n_free)
    if use_exposure:
        lr = np.r_[lr, [cfg.tracking.lr_exposure] * 2]
    # Exponential decay from lr to lr x tracking_lr_final over the iteration budget: large first
    # steps follow fast motion, small last steps stop Adam's oscillation around the optimum.
    decay = cfg.budget.tracking_lr_final ** (1.0 / max(n_iters - 1, 1))
    adam = HostAdam(lr, decay)
    targets = prepare_targets(obs, cfg, ctx.theta, tracking=True,
                              use_events=cfg.method.event_tracking, terms=ctx.loss_terms)
    # Coarse-to-fine: the first n_coarse iterations at the coarse level (budget.tracking_coarse_*),
    # which only moves the pose towards the basin; the stopping rules watch the fine ones.
    coarse_scale = cfg.budget.tracking_coarse_scale
    n_coarse = coarse_iterations(n_iters, coarse_scale, cfg.budget.tracking_coarse_fraction)
    coarse_targets = None
    coarse_fractions = fractions  # the coarse level's sub-poses (budget.tracking_coarse_segments)
    if n_coarse:
        lvl = ctx.level(coarse_scale)
        coarse_obs = coarse_observation(obs, lvl.cam, cfg, lvl.edge_blocks,
                                        cfg.budget.tracking_coarse_segments)
        coarse_fractions = coarse_obs.fractions
        coarse_targets = prepare_targets(
            coarse_obs, cfg, ctx.theta, tracking=True, use_events=cfg.method.event_tracking,
            terms=ctx.loss_terms)
    curve = crf.frozen()
    scene = gmap.frozen()  # the map is fixed while tracking: activate it once
    like = obs.rgb  # dtype and device of the copies
    loss_val, it, converged = math.inf, 0, False
    trace: list[tuple[float, float, np.ndarray]] = []
    settled = ConvergenceTest.from_config(cfg.tracking)
    coarse_patience = cfg.budget.tracking_coarse_patience
    coarse_settled = ConvergenceTest("net-motion", cfg.budget.tracking_coarse_tolerance,
                                     coarse_patience) if coarse_patience and n_coarse else None
    step_i = 0
    while step_i < n_iters:
        step_i += 1
        it += 1
        # Map from the free twists (xi_0, xi_1 | xi_1) to the end twists (xi_0, xi_1) [12, 6n].
        select = np.zeros((12, 6 * n_free))
        if anchor is not None:
            pose0, d0 = anchored_start(anchor, pose1)
            select[:6], select[6:] = d0, np.eye(6)
        elif n_free == 2:
            select[:] = np.eye(12)
        else:
            select[6:] = np.eye(6)
        coarse = step_i <= n_coarse
        level_fractions = coarse_fractions if coarse else fractions
        m = len(level_fractions)
        views, jac = exposure_path(pose0, pose1, level_fractions)
        packed = to_device(np.r_[views.ravel(), exposure] if use_exposure else views.ravel(), like)
        viewmats = packed[:16 * m].view(m, 4, 4).requires_grad_()
        exp_ab = packed[16 * m:].view(1, 2).requires_grad_() if use_exposure else None
        res = ctx.render(scene, viewmats, phase="tracking", scale=coarse_scale if coarse else 1.0)
        total = blur_loss(res, coarse_targets if coarse and coarse_targets else targets, curve,
                          exp_ab, cfg, tracking=True, eps=ctx.eps)
        total.backward()
        grads = [flat_grad(viewmats)] + ([flat_grad(exp_ab)] if exp_ab is not None else [])
        host = torch.cat([*grads, total.detach().reshape(1)]).cpu().numpy().astype(np.float64)
        loss_val = float(host[-1])
        if not math.isfinite(loss_val):
            break
        g_sub = twist_gradient(views, host[:16 * m].reshape(m, 4, 4))  # [M, 6]
        g_free = select.T @ np.einsum("mi,mij->j", g_sub, jac)
        if use_exposure:
            g_exposure = host[16 * m:-1] + exposure_prior_gradient(
                exposure, cfg.budget.lambda_exposure_prior)
            delta = adam.step(np.r_[g_free, g_exposure])
        else:
            delta = adam.step(g_free)
        steps = delta[:6 * n_free].reshape(n_free, 6)
        if n_free == 2:
            pose0 = se3_exp(steps[0]) @ pose0
        pose1 = se3_exp(steps[-1]) @ pose1
        if use_exposure:
            exposure = exposure + delta[6 * n_free:]
        step_norm = float(np.linalg.norm(steps, axis=-1).max())
        if request.trace:
            trace.append((loss_val, step_norm, pose1.copy()))
        if coarse:
            if coarse_settled is not None and step_i < n_coarse and \
                    coarse_settled.update(loss_val, step_norm, pose1):
                adam.skip(n_coarse - step_i)  # the fine iterations keep their learning rate
                step_i = n_coarse
            continue
        if settled.update(loss_val, step_norm, pose1) or \
                step_norm < cfg.budget.converged_threshold:
            converged = True
            break
    if anchor is not None:
        pose0 = anchored_start(anchor, pose1)[0]
    elif not blur:
        pose0 = pose1.copy()
    state = FrameState(init.index, pose0, pose1, float(exposure[0]), float(exposure[1]))
    recorded = None
    if request.trace:
        recorded = TrackTrace(np.array([t[0] for t in trace]), np.array([t[1] for t in trace]),
                              np.array([t[2] for t in trace]).reshape(-1, 4, 4))
    return TrackResult(state, loss_val, it, converged, recorded)


class GradientTracker:
    """The default :class:`~egs_bench.slam.components.Tracker`: :func:`track_frame`."""

    Config: ClassVar[type] = TrackingConfig

    def __init__(self, ctx: SlamContext) -> None:
        self.ctx = ctx

    def track(self, gmap: GaussianMap, crf: CameraResponse, request: TrackRequest
              ) -> TrackResult:
        return track_frame(self.ctx, gmap, crf, request)


def last_motion(history: list[FrameState], motion_model: MotionModel, prev_end_us: int | None,
                prev_prev_end_us: int | None, prev_start_us: int | None = None
                ) -> tuple[np.ndarray, int] | None:
    """The most recent estimated motion ``(relative pose [4, 4], its span in us)`` that the
    constant-velocity model extrapolates, or None when there is none yet (or the model is
    ``constant-position``); see :func:`predict_initial`."""
    if motion_model != "constant-velocity" or prev_end_us is None:
        return None
    last = history[-1]
    if len(history) >= 2 and prev_prev_end_us is not None and prev_end_us > prev_prev_end_us:
        # motion over the last interval
        return last.pose1_cw @ invert_pose(history[-2].pose1_cw), prev_end_us - prev_prev_end_us
    if prev_start_us is not None and prev_end_us > prev_start_us and not np.array_equal(
            last.pose0_cw, last.pose1_cw):
        # motion during the last exposure
        return last.pose1_cw @ invert_pose(last.pose0_cw), prev_end_us - prev_start_us
    return None


def predict_initial(index: int, history: list[FrameState], motion_model: MotionModel,
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
    last = history[-1]
    p_last = last.pose1_cw
    motion = last_motion(history, motion_model, prev_end_us, prev_prev_end_us, prev_start_us)
    if motion is None or prev_end_us is None:
        return FrameState(index, p_last.copy(), p_last.copy(), last.exp_a, last.exp_b)
    rel, span = motion
    scale = (t_end_us - prev_end_us) / span
    xi = np.r_[rel[:3, 3], so3_log(rel[:3, :3])]  # small motion: twist ~ (t, log R)
    pred1 = se3_exp(xi * scale) @ p_last
    f0 = (t_start_us - prev_end_us) / max(t_end_us - prev_end_us, 1)
    pred0 = exposure_path(p_last, pred1, np.array([np.clip(f0, 0.0, 1.0)]))[0][0]
    return FrameState(index, pred0, pred1, last.exp_a, last.exp_b)
