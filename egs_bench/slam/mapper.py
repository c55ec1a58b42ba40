"""Mapping: optimise the Gaussians (and the latest keyframes' exposure trajectories, their
exposures and the CRF) on the keyframe window plus random older keyframes (paper §III.D,
MonoGS single-process backend).

Each iteration renders the sub-poses of all its keyframes in one rasteriser call and evaluates
their losses as one batched expression. Keyframe poses and exposures are optimised on the host
like tracking does (:mod:`egs_bench.slam.tracker`): one copy of their values to the device and
one copy of their gradients and the loss back per iteration.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import torch

from egs_bench.geometry.lie import se3_exp, twist_gradient
from egs_bench.interrupts import raise_if_interrupted
from egs_bench.render import GaussianMap
from egs_bench.slam.config import MappingConfig
from egs_bench.slam.context import SlamContext
from egs_bench.slam.contribution import low_contribution
from egs_bench.slam.crf import CameraResponse
from egs_bench.slam.exposure import exposure_path
from egs_bench.slam.frames import FrameObs, FrameState, coarse_observation
from egs_bench.slam.host_adam import HostAdam
from egs_bench.slam.levels import coarse_iterations
from egs_bench.slam.losses import exposure_prior_gradient
from egs_bench.slam.render_model import (
    LossTargets,
    blur_loss,
    mapping_regulariser,
    prepare_targets,
    stack_targets,
)
from egs_bench.slam.tracker import flat_grad, to_device


@dataclass
class _HostPlan:
    """A mapping round's host-side unknowns: the keyframes whose end poses are refined, those
    whose exposure is free, the mask of the end-pose twists that move [12 x len(refine)], and
    the Adam over them."""

    refine: list[int]
    free_exposure: list[int]
    slot_mask: np.ndarray
    adam: HostAdam


class Mapper:
    """Holds the map optimisation state across keyframes.

    Deviation from MonoGS (documented in docs/notes/slam.md): the Gaussian Adam state is rebuilt
    for every mapping round (insertion and pruning replace the tensors), and there is no
    clone/split densification; insertion is denser instead.
    """

    Config: ClassVar[type] = MappingConfig

    def __init__(self, ctx: SlamContext, gmap: GaussianMap, crf: CameraResponse,
                 rng: np.random.Generator) -> None:
        """``rng`` draws the random older keyframes of each iteration."""
        self.ctx, self.gmap, self.crf, self.cfg = ctx, gmap, crf, ctx.cfg
        self.rng = rng
        cfg = ctx.cfg
        self.iteration = 0
        # by (keyframe, coarse level): its targets and sub-pose fractions
        self.levels: dict[tuple[int, bool], tuple[LossTargets, np.ndarray]] = {}
        self.crf_opt = None
        crf_params = list(crf.parameters())
        if crf_params:
            self.crf_opt = torch.optim.Adam(crf_params, lr=cfg.mapping.lr_crf, fused=True)

    def _gaussian_optimizer(self) -> torch.optim.Adam:
        g, c = self.gmap, self.cfg
        g.requires_grad_(True)
        # Fused: one kernel per step for all tensors, and the step counters stay on the device
        # (the for-each and per-tensor forms read them on the host: a sync per tensor).
        return torch.optim.Adam([
            {"params": [g.means], "lr": c.budget.lr_means},
            {"params": [g.colors], "lr": c.budget.lr_colors},
            {"params": [g.opacity_logits], "lr": c.budget.lr_opacity},
            {"params": [g.log_scales], "lr": c.budget.lr_scales},
            {"params": [g.quats], "lr": c.mapping.lr_quats},
        ], eps=1e-15, fused=True)

    def _targets(self, k: int, obs: FrameObs, coarse: bool = False
                 ) -> tuple[LossTargets, np.ndarray]:
        """Keyframe ``k``'s mapping targets and sub-pose fractions [M] at the internal level, or
        at the coarse level of ``budget.mapping_coarse_scale`` (and its
        ``mapping_coarse_segments``); prepared once per keyframe."""
        if (k, coarse) not in self.levels:
            if coarse:
                budget = self.cfg.budget
                lvl = self.ctx.level(budget.mapping_coarse_scale)
                obs = coarse_observation(obs, lvl.cam, self.cfg, lvl.edge_blocks,
                                         budget.mapping_coarse_segments)
            targets = prepare_targets(obs, self.cfg, self.ctx.theta, tracking=False,
                                      use_events=self.cfg.method.event_mapping,
                                      terms=self.ctx.loss_terms)
            self.levels[k, coarse] = (targets, obs.fractions)
        return self.levels[k, coarse]

    def _pick_views(self, window: list[int], all_keyframes: list[int]) -> list[int]:
        """The window plus ``n_random_kfs`` random older keyframes, optionally subsampled to
        ``views_per_iter`` (always keeping the newest keyframe)."""
        cfg = self.cfg
        views = list(window)
        others = [k for k in all_keyframes if k not in window]
        if others and cfg.mapping.n_random_kfs > 0:
            pick = self.rng.permutation(len(others))[: cfg.mapping.n_random_kfs]
            views += [others[int(j)] for j in pick]
        if cfg.budget.views_per_iter is not None and len(views) > cfg.budget.views_per_iter:
            rest = views[1:]
            pick = self.rng.permutation(len(rest))[: cfg.budget.views_per_iter - 1]
            views = [views[0]] + [rest[int(j)] for j in pick]
        return views

    def optimise(self, states: dict[int, FrameState], observations: dict[int, FrameObs],
                 window: list[int], all_keyframes: list[int], iterations: int,
                 *, initial: bool = False, fixed_end_pose: int | None = 0,
                 report: Callable[[int, int], None] | None = None) -> float:
        """Run ``iterations`` mapping iterations; returns the last total loss.

        Args:
            states: estimated trajectories of keyframes (updated in place for refined ones).
            window: keyframe window, newest first.
            all_keyframes: every keyframe so far (random extra views come from outside the
                window).
            initial: MonoGS map initialisation (frame 0 only; no isotropic term, no exposure).
            fixed_end_pose: keyframe whose ``T_tau`` is never refined (frame 0, placed at GT);
                its ``T_0`` is refined when the blur model is on.
            report: called as ``report(done, iterations)`` about 50 times over the round
                (progress display).
        """
        round_ = self.begin_round(states, observations, window, all_keyframes, iterations,
                                  initial=initial, fixed_end_pose=fixed_end_pose, report=report)
        round_.advance(iterations)
        return round_.close()

    def begin_round(self, states: dict[int, FrameState], observations: dict[int, FrameObs],
                    window: list[int], all_keyframes: list[int], iterations: int,
                    *, initial: bool = False, fixed_end_pose: int | None = 0,
                    report: Callable[[int, int], None] | None = None) -> MappingRound:
        """A mapping round of :meth:`optimise` (same arguments) to be run in slices:
        ``advance(n)`` runs up to ``n`` of its iterations, ``close()`` ends it (pruning)."""
        return MappingRound(self, RoundInputs(states, observations, list(window),
                                              list(all_keyframes)),
                            iterations, initial, fixed_end_pose, report)

    def _host_plan(self, window: list[int], initial: bool, fixed_end_pose: int | None
                   ) -> _HostPlan:
        """What a mapping round optimises on the host besides the Gaussians."""
        cfg = self.cfg
        blur = cfg.method.blur_model
        # No pose is refined while the map is built from frame 0 alone: with one view the map
        # absorbs any T_0 (measured: frame 0's T_0 drifted 9 cm from a 2 cm true motion on
        # `demo`, and the constant-velocity prediction of frame 1 inherited it). Frame 0's T_0
        # is refined later, when other keyframes constrain the map.
        refine = [] if initial or not cfg.mapping.refine_poses else list(
            window[: cfg.budget.pose_window])
        # Which end poses of each refined keyframe move: (T_0, T_tau).
        slots = {k: (blur, k != fixed_end_pose) for k in refine}
        refine = [k for k in refine if any(slots[k])]
        use_exposure = cfg.method.exposure_compensation and not initial
        free_exposure = [k for k in window if k != fixed_end_pose] if use_exposure else []
        # Host Adam over the refined keyframes' end twists (12 each; frozen slots get zero
        # gradients) and the window's exposures (2 each).
        pose_lr = (np.r_[[cfg.budget.lr_trans] * 3, [cfg.budget.lr_rot] * 3]
                   * cfg.mapping.kf_pose_lr_scale)
        adam = HostAdam(np.r_[np.tile(pose_lr, 2 * len(refine)),
                              [cfg.tracking.lr_exposure] * (2 * len(free_exposure))])
        slot_mask = np.repeat(np.array([s for k in refine for s in slots[k]], float), 6)
        return _HostPlan(refine, free_exposure, slot_mask, adam)

    def _host_step(self, plan: _HostPlan, states: dict[int, FrameState], views: list[int],
                   paths: dict[int, tuple[np.ndarray, np.ndarray]], host_grads: np.ndarray,
                   m: int) -> None:
        """One host Adam step on the refined keyframes' end poses and the window's exposures,
        from the packed gradients (sub-pose gradients of every view, then ``(a, b)`` per view)."""
        refine, free_exposure, adam = plan.refine, plan.free_exposure, plan.adam
        n_vm = 16 * m * len(views) if refine else 0
        g_pose = []
        if refine:
            g_views = host_grads[:n_vm].reshape(len(views), m, 4, 4)
            for k in refine:
                if k in views:
                    v = views.index(k)
                    g_sub = twist_gradient(paths[k][0], g_views[v])
                    g_pose.append(np.einsum("mi,mij->j", g_sub, paths[k][1]))
                else:  # subsampled out of this iteration: no gradient
                    g_pose.append(np.zeros(12))
        g_exp = []
        if free_exposure:
            e = host_grads[n_vm:].reshape(len(views), 2)
            prior = self.cfg.budget.lambda_exposure_prior
            for k in free_exposure:
                if k not in views:  # not drawn this iteration: no gradient, not even the prior's
                    g_exp.append(np.zeros(2))
                    continue
                ab = np.array([states[k].exp_a, states[k].exp_b])
                g_exp.append(e[views.index(k)] + exposure_prior_gradient(ab, prior))
        delta = adam.step(np.concatenate([*g_pose, *g_exp]) if (g_pose or g_exp) else
                          np.zeros(0))
        twists = (delta[:12 * len(refine)] * plan.slot_mask).reshape(len(refine), 2, 6)
        for j, k in enumerate(refine):
            st = states[k]
            st.pose0_cw = se3_exp(twists[j, 0]) @ st.pose0_cw
            st.pose1_cw = se3_exp(twists[j, 1]) @ st.pose1_cw
            if not self.cfg.method.blur_model:
                st.pose0_cw = st.pose1_cw.copy()
        for j, k in enumerate(free_exposure):
            da, db = delta[12 * len(refine) + 2 * j: 12 * len(refine) + 2 * j + 2]
            states[k].exp_a += float(da)
            states[k].exp_b += float(db)

    def refine(self, states: dict[int, FrameState], observations: dict[int, FrameObs],
               keyframes: list[int], iterations: int) -> float:
        """Final map refinement after the sequence (MonoGS's colour refinement): each iteration
        optimises the Gaussians on one random keyframe; poses, exposures and the CRF stay fixed.
        Unlike MonoGS (0.8 L1 + 0.2 (1 - SSIM) on RGB), the loss is the method's own mapping
        loss, so `egs` keeps its blur model and events. Returns the last loss."""
        cfg = self.cfg
        opt = self._gaussian_optimizer()
        like = self.gmap.means
        loss_val = float("nan")
        for _ in range(iterations):
            raise_if_interrupted()
            k = keyframes[int(self.rng.integers(len(keyframes)))]
            st = states[k]
            views = exposure_path(st.pose0_cw, st.pose1_cw, observations[k].fractions)[0]
            exp_ab = to_device(np.array([st.exp_a, st.exp_b]), like).view(1, 2) \
                if cfg.method.exposure_compensation else None
            res = self.ctx.render(self.gmap, views, phase="refinement")
            total = (blur_loss(res, self._targets(k, observations[k])[0], self.crf, exp_ab, cfg,
                               tracking=False, eps=self.ctx.eps)
                     + mapping_regulariser(self.gmap, cfg))
            opt.zero_grad(set_to_none=True)
            total.backward()
            loss_val = float(total.detach())
            if not np.isfinite(loss_val):
                break
            self._gaussian_step(opt)
        self.gmap.requires_grad_(False)
        return loss_val

    def _gaussian_step(self, opt: torch.optim.Adam) -> None:
        """One Adam step on the Gaussians, then colours projected onto >= 0 (radiance is
        non-negative; MonoGS clamps colour at 0)."""
        opt.step()
        with torch.no_grad():
            self.gmap.colors.clamp_(min=0.0)

    def _prune(self, min_opacity: float) -> int:
        return self._remove(self.gmap.opacities.detach() < min_opacity)

    def _prune_by_contribution(self, states: dict[int, FrameState], window: list[int],
                               min_pixels: float) -> int:
        """Remove the Gaussians in view of the window's keyframes whose blending weight summed
        over them (each rendered sharp at the middle of its exposure, at mapping's coarse level)
        is below ``min_pixels`` internal-resolution pixels; those out of every view stay."""
        mid = np.array([0.5])
        poses = np.stack([exposure_path(states[k].pose0_cw, states[k].pose1_cw, mid)[0][0]
                          for k in window])
        viewmats = torch.from_numpy(poses).to(device=self.gmap.device, dtype=self.gmap.dtype)
        return self._remove(low_contribution(self.ctx, self.gmap, viewmats,
                                             self.cfg.budget.mapping_coarse_scale, min_pixels))

    def _remove(self, remove: torch.Tensor) -> int:
        """Prune the Gaussians where ``remove`` [N] holds, unless that would empty the map."""
        if bool(remove.all()):
            return 0
        return self.gmap.prune(remove)


@dataclass
class RoundInputs:
    """What a mapping round optimises over: the keyframes' states (refined in place) and
    observations, the window (newest first) and every keyframe so far."""

    states: dict[int, FrameState]
    observations: dict[int, FrameObs]
    window: list[int]
    all_keyframes: list[int]


class MappingRound:
    """One mapping round (map initialisation or a keyframe's) run in slices of iterations
    (:meth:`Mapper.begin_round`); the map must not be edited from outside while it is open."""

    def __init__(self, mapper: Mapper, inputs: RoundInputs, iterations: int, initial: bool,
                 fixed_end_pose: int | None,
                 report: Callable[[int, int], None] | None) -> None:
        self.mapper, self.states, self.observations = mapper, inputs.states, inputs.observations
        self.window, self.all_keyframes = inputs.window, inputs.all_keyframes
        self.iterations, self.initial, self.report = iterations, initial, report
        self.report_every = max(1, iterations // 50)
        budget = mapper.cfg.budget
        self.n_coarse = coarse_iterations(iterations, budget.mapping_coarse_scale,
                                          budget.mapping_coarse_fraction)
        self.opt = mapper._gaussian_optimizer()
        self.plan = mapper._host_plan(self.window, initial, fixed_end_pose)
        self.use_exposure = mapper.cfg.method.exposure_compensation and not initial
        self.done = 0
        self.loss = float("nan")
        self.prune_due = False
        self.stopped = False  # a non-finite loss ends the round early

    @property
    def remaining(self) -> int:
        return 0 if self.stopped else self.iterations - self.done

    def advance(self, n: int) -> None:
        """Run up to ``n`` more iterations of the round."""
        for _ in range(min(n, self.remaining)):
            if not self._iteration():
                self.stopped = True
                return

    def _iteration(self) -> bool:
        """One mapping iteration; False when its loss is not finite."""
        mapper, cfg = self.mapper, self.mapper.cfg
        states, observations = self.states, self.observations
        plan, initial = self.plan, self.initial
        refine, free_exposure = plan.refine, plan.free_exposure
        raise_if_interrupted()  # a swallowed signal: map initialisation alone takes minutes
        if self.report is not None and self.done % self.report_every == 0:
            self.report(self.done, self.iterations)
        views = mapper._pick_views(self.window, self.all_keyframes)
        coarse = self.done < self.n_coarse
        level = [mapper._targets(k, observations[k], coarse) for k in views]
        paths = {k: exposure_path(states[k].pose0_cw, states[k].pose1_cw, fractions)
                 for k, (_, fractions) in zip(views, level, strict=True)}
        m = len(level[0][1])
        exposure = np.array([[states[k].exp_a, states[k].exp_b] for k in views])
        flat = [paths[k][0].ravel() for k in views]
        packed = to_device(np.concatenate(flat + [exposure.ravel()]), mapper.gmap.means)
        n_vm = 16 * m * len(views)
        viewmats = packed[:n_vm].view(-1, 4, 4)
        exp_ab = packed[n_vm:].view(-1, 2) if self.use_exposure else None
        if refine:
            viewmats.requires_grad_()
        if free_exposure and exp_ab is not None:
            exp_ab.requires_grad_()
        targets = stack_targets([t for t, _ in level])
        res = mapper.ctx.render(mapper.gmap, viewmats, phase="init" if initial else "mapping",
                                scale=cfg.budget.mapping_coarse_scale if coarse else 1.0)
        total = blur_loss(res, targets, mapper.crf, exp_ab, cfg, tracking=False, eps=mapper.ctx.eps)
        if not initial:
            total = total + mapping_regulariser(mapper.gmap, cfg)
        self.opt.zero_grad(set_to_none=True)
        if mapper.crf_opt is not None:
            mapper.crf_opt.zero_grad(set_to_none=True)
        total.backward()
        grads = []
        if refine:
            grads.append(flat_grad(viewmats))
        if free_exposure and exp_ab is not None:
            grads.append(flat_grad(exp_ab))
        host = torch.cat([*grads, total.detach().reshape(1)]).cpu().numpy().astype(np.float64)
        self.done += 1
        self.loss = float(host[-1])
        if not np.isfinite(self.loss):
            return False
        mapper._gaussian_step(self.opt)
        if mapper.crf_opt is not None and not initial:
            mapper.crf_opt.step()
        if refine or free_exposure:
            mapper._host_step(plan, states, views, paths, host[:-1], m)
        mapper.iteration += 1
        every = cfg.budget.prune_every
        if not initial and mapper.iteration % every == cfg.budget.prune_offset % every:
            self.prune_due = True
        return True

    def close(self) -> float:
        """End the round: freeze the map and prune it; returns the last loss."""
        mapper, cfg = self.mapper, self.mapper.cfg
        mapper.gmap.requires_grad_(False)
        with torch.no_grad():
            if self.initial:
                mapper._prune(cfg.mapping.init_prune_opacity)
            elif self.prune_due:
                mapper._prune(cfg.mapping.prune_opacity)
        if self.prune_due and cfg.budget.prune_contribution > 0:
            mapper._prune_by_contribution(self.states, self.window, cfg.budget.prune_contribution)
        return self.loss
