"""Mapping: optimise the Gaussians (and the latest keyframes' exposure trajectories, their
exposures and the CRF) on the keyframe window plus random older keyframes (paper §III.D,
MonoGS single-process backend)."""

from __future__ import annotations

import torch

from egs_bench.render import GaussianMap
from egs_bench.slam.config import SlamConfig
from egs_bench.slam.crf import CameraResponse
from egs_bench.slam.frames import FrameObs, FrameState
from egs_bench.slam.losses import isotropic_loss
from egs_bench.slam.render_model import frame_loss, render_views, subposes
from egs_bench.slam.tracker import PoseIncrements


class Mapper:
    """Holds the map optimisation state across keyframes.

    Deviation from MonoGS (documented in docs/notes/slam.md): the Gaussian Adam state is rebuilt
    for every mapping round (insertion and pruning replace the tensors), and there is no
    clone/split densification; insertion is denser instead.
    """

    def __init__(self, gmap: GaussianMap, crf: CameraResponse, cfg: SlamConfig, K: torch.Tensor,
                 width: int, height: int, theta: tuple[float, float], eps: float,
                 generator: torch.Generator) -> None:
        self.gmap, self.crf, self.cfg = gmap, crf, cfg
        self.K, self.width, self.height = K, width, height
        self.theta, self.eps, self.gen = theta, eps, generator
        self.iteration = 0
        self.crf_opt = None
        crf_params = list(crf.parameters())
        if crf_params:
            self.crf_opt = torch.optim.Adam(crf_params, lr=cfg.lr_crf)

    def _gaussian_optimizer(self) -> torch.optim.Adam:
        g, c = self.gmap, self.cfg
        g.requires_grad_(True)
        return torch.optim.Adam([
            {"params": [g.means], "lr": c.lr_means},
            {"params": [g.colors], "lr": c.lr_colors},
            {"params": [g.opacity_logits], "lr": c.lr_opacity},
            {"params": [g.log_scales], "lr": c.lr_scales},
            {"params": [g.quats], "lr": c.lr_quats},
        ], eps=1e-15)

    def optimise(self, states: dict[int, FrameState], observations: dict[int, FrameObs],
                 window: list[int], all_keyframes: list[int], iterations: int,
                 *, initial: bool = False, fixed_end_pose: int | None = 0) -> float:
        """Run ``iterations`` mapping iterations; returns the last total loss.

        Args:
            states: estimated trajectories of keyframes (updated in place for refined ones).
            window: keyframe window, newest first.
            all_keyframes: every keyframe so far (random extra views come from outside the
                window).
            initial: MonoGS map initialisation (frame 0 only; no isotropic term, no exposure).
            fixed_end_pose: keyframe whose ``T_tau`` is never refined (frame 0, placed at GT);
                its ``T_0`` is refined when the blur model is on.
        """
        cfg = self.cfg
        opt = self._gaussian_optimizer()
        dev, pdt = self.gmap.device, states[window[0]].pose1_cw.dtype
        # No pose is refined while the map is built from frame 0 alone: with one view the map
        # absorbs any T_0 (measured: frame 0's T_0 drifted 9 cm from a 2 cm true motion on
        # `demo`, and the constant-velocity prediction of frame 1 inherited it). Frame 0's T_0
        # is refined later, when other keyframes constrain the map.
        refine = [] if initial else list(window[: cfg.pose_window])
        blur = cfg.n_segments > 1
        # Which pose slots of each refined keyframe move: [T_0, T_tau].
        slots = {k: [blur, k != fixed_end_pose] for k in refine}
        refine = [k for k in refine if any(slots[k])]
        inc = PoseIncrements(2 * len(refine), pdt, dev)
        exposure = {k: (torch.tensor(states[k].exp_a, dtype=self.gmap.dtype, device=dev,
                                     requires_grad=True),
                        torch.tensor(states[k].exp_b, dtype=self.gmap.dtype, device=dev,
                                     requires_grad=True)) for k in window}
        groups = [{"params": [inc.rho], "lr": cfg.lr_trans * cfg.kf_pose_lr_scale},
                  {"params": [inc.theta], "lr": cfg.lr_rot * cfg.kf_pose_lr_scale}]
        use_exposure = cfg.exposure_compensation and not initial
        if use_exposure:
            groups.append({"params": [t for k in window if k != fixed_end_pose
                                      for t in exposure[k]], "lr": cfg.lr_exposure})
        kf_opt = torch.optim.Adam(groups)
        slot_mask = torch.tensor([[float(s) for s in slots[k]] for k in refine], dtype=pdt,
                                 device=dev).reshape(-1, 1)
        loss_val = float("nan")
        prune_due = False
        for _ in range(iterations):
            views = list(window)
            others = [k for k in all_keyframes if k not in window]
            if others and cfg.n_random_kfs > 0:
                pick = torch.randperm(len(others), generator=self.gen)[: cfg.n_random_kfs]
                views += [others[int(j)] for j in pick]
            if cfg.views_per_iter is not None and len(views) > cfg.views_per_iter:
                rest = views[1:]
                pick = torch.randperm(len(rest), generator=self.gen)[: cfg.views_per_iter - 1]
                views = [views[0]] + [rest[int(j)] for j in pick]
            opt.zero_grad(set_to_none=True)
            kf_opt.zero_grad(set_to_none=True)
            if self.crf_opt is not None:
                self.crf_opt.zero_grad(set_to_none=True)
            total = torch.zeros((), dtype=self.gmap.dtype, device=dev)
            moved = None
            if refine:
                base = torch.stack([p for k in refine
                                    for p in (states[k].pose0_cw, states[k].pose1_cw)])
                moved = inc.apply(base, slot_mask)
            for k in views:
                if moved is not None and k in refine:
                    j = refine.index(k)
                    p0, p1 = moved[2 * j], moved[2 * j + 1]
                else:
                    p0, p1 = states[k].pose0_cw, states[k].pose1_cw
                zero = torch.zeros((), dtype=self.gmap.dtype, device=dev)
                a, b = exposure.get(k, (zero, zero)) if use_exposure else (zero, zero)
                total = total + self._view_loss(p0, p1, observations[k], a, b)
            if not initial:
                total = total + cfg.lambda_iso * isotropic_loss(self.gmap.scales)
            loss_val = float(total.detach())
            if not torch.isfinite(total):
                break
            total.backward()
            self._gaussian_step(opt)
            kf_opt.step()
            if self.crf_opt is not None and not initial:
                self.crf_opt.step()
            if refine:
                new, _ = inc.fold(torch.stack(
                    [p for k in refine for p in (states[k].pose0_cw, states[k].pose1_cw)]),
                    slot_mask)
                for j, k in enumerate(refine):
                    states[k].pose0_cw, states[k].pose1_cw = new[2 * j], new[2 * j + 1]
            if blur is False:
                for k in refine:
                    states[k].pose0_cw = states[k].pose1_cw
            self.iteration += 1
            if not initial and self.iteration % cfg.prune_every == cfg.prune_offset % max(
                    cfg.prune_every, 1):
                prune_due = True
        for k in window:
            if use_exposure and k != fixed_end_pose:
                states[k].exp_a = float(exposure[k][0].detach())
                states[k].exp_b = float(exposure[k][1].detach())
        self.gmap.requires_grad_(False)
        with torch.no_grad():
            if initial:
                self._prune(cfg.init_prune_opacity)
            elif prune_due:
                self._prune(cfg.prune_opacity)
        return loss_val

    def refine(self, states: dict[int, FrameState], observations: dict[int, FrameObs],
               keyframes: list[int], iterations: int) -> float:
        """Final map refinement after the sequence (MonoGS's colour refinement): each iteration
        optimises the Gaussians on one random keyframe; poses, exposures and the CRF stay fixed.
        Unlike MonoGS (0.8 L1 + 0.2 (1 - SSIM) on RGB), the loss is the method's own mapping
        loss, so `egs` keeps its blur model and events. Returns the last loss."""
        cfg = self.cfg
        opt = self._gaussian_optimizer()
        dev = self.gmap.device
        loss_val = float("nan")
        for _ in range(iterations):
            k = keyframes[int(torch.randint(len(keyframes), (1,), generator=self.gen))]
            st = states[k]
            a = torch.tensor(st.exp_a, dtype=self.gmap.dtype, device=dev)
            b = torch.tensor(st.exp_b, dtype=self.gmap.dtype, device=dev)
            total = (self._view_loss(st.pose0_cw, st.pose1_cw, observations[k], a, b)
                     + cfg.lambda_iso * isotropic_loss(self.gmap.scales))
            loss_val = float(total.detach())
            if not torch.isfinite(total):
                break
            opt.zero_grad(set_to_none=True)
            total.backward()
            self._gaussian_step(opt)
        self.gmap.requires_grad_(False)
        return loss_val

    def _view_loss(self, pose0_cw: torch.Tensor, pose1_cw: torch.Tensor, obs: FrameObs,
                   exp_a: torch.Tensor, exp_b: torch.Tensor) -> torch.Tensor:
        """Mapping loss (scalar tensor) of one keyframe rendered along its exposure trajectory
        ``pose0_cw -> pose1_cw`` [4, 4] with exposure compensation ``exp_a, exp_b``."""
        res = render_views(self.gmap, subposes(pose0_cw, pose1_cw, obs.fractions), self.K,
                           self.width, self.height, self.cfg)
        return frame_loss(res, obs, self.crf, exp_a, exp_b, self.cfg, tracking=False,
                          use_events=self.cfg.event_mapping, theta=self.theta,
                          eps=self.eps).total

    def _gaussian_step(self, opt: torch.optim.Adam) -> None:
        """One Adam step on the Gaussians, then colours projected onto >= 0 (radiance is
        non-negative; MonoGS clamps colour at 0)."""
        opt.step()
        with torch.no_grad():
            self.gmap.colors.clamp_(min=0.0)

    def _prune(self, min_opacity: float) -> int:
        remove = self.gmap.opacities.detach() < min_opacity
        if bool(remove.all()):  # never empty the map entirely
            return 0
        return self.gmap.prune(remove)
