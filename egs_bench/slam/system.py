"""The SLAM loop: initialise on frame 0, then track every frame, select keyframes, map."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import torch

from egs_bench.errors import InputError
from egs_bench.geometry import invert_pose
from egs_bench.interrupts import raise_if_interrupted
from egs_bench.render import GaussianMap
from egs_bench.slam.config import SlamConfig
from egs_bench.slam.crf import make_crf
from egs_bench.slam.frames import FrameObs, FrameState, internal_intrinsics, load_frame
from egs_bench.slam.keyframes import is_keyframe, update_window
from egs_bench.slam.mapper import Mapper
from egs_bench.slam.render_model import render_views
from egs_bench.slam.tracker import last_motion, predict_initial, track_frame


@dataclass
class FrameReport:
    index: int
    loss: float
    iterations: int
    keyframe: bool
    diverged: bool
    wall_s: float


@dataclass
class SlamResult:
    states: list[FrameState]
    keyframes: list[int]
    gmap: GaussianMap
    crf: torch.nn.Module
    reports: list[FrameReport] = field(default_factory=list)
    divergences: list[str] = field(default_factory=list)


class SlamSystem:
    """EGS-SLAM (or a configured variant) on one sequence.

    Args:
        seq: an opened :class:`~egs_bench.datasets.sequence.Sequence`.
        cfg: validated configuration.
        device: torch device for maps and images.
        seed: seeds every random choice (insertion subsampling, random mapping views).
        log: callback for human-readable log lines.
    """

    def __init__(self, seq, cfg: SlamConfig, device: str = "cpu", seed: int = 0,
                 log: Callable[[str], None] | None = None) -> None:
        self.seq, self.cfg = seq, cfg
        self.device = torch.device(device)
        self.log = log or (lambda _m: None)
        self.cam = internal_intrinsics(seq.intrinsics, cfg.budget.resolution_scale)
        self.K = torch.tensor(self.cam.K, dtype=torch.float32, device=self.device)
        self.gen = torch.Generator().manual_seed(seed)  # insertion subsampling
        self.rng = np.random.default_rng(seed)  # random mapping views
        torch.manual_seed(seed)
        self.gmap = GaussianMap.empty(torch.float32, self.device)
        m = cfg.method
        self.crf = make_crf(m.crf, m.crf_nodes, m.crf_alpha, m.crf_init, self.device)
        if cfg.method.theta is not None:
            self.theta = (float(cfg.method.theta), float(cfg.method.theta))
        else:
            self.theta = (float(seq.pos_threshold), float(seq.neg_threshold))
        self.eps = float(seq.eps)
        self.states: list[FrameState] = []  # filled by run()
        self.want_events = cfg.method.event_tracking or cfg.method.event_mapping
        if self.want_events and not getattr(seq, "has_events", True):
            self.log("sequence has no events: event losses see empty event maps")
        self.mapper = Mapper(self.gmap, self.crf, cfg, self.K, self.cam.width, self.cam.height,
                             self.theta, self.eps, self.rng)

    # -------------------------------------------------------------------------------- helpers
    def _obs(self, i: int) -> FrameObs:
        return load_frame(self.seq, i, self.cam, self.cfg, self.want_events, self.device)

    def _insert(self, obs: FrameObs, state: FrameState, downsample: int, kf_id: int) -> int:
        with torch.no_grad():
            lin = self.crf.inverse(obs.rgb.to(torch.float32)).clamp_min(0.0)
        depth = (obs.depth * obs.rgb_mask).cpu().numpy()  # MonoGS zeroes near-black pixels
        pose_wc = invert_pose(state.pose1_cw)
        return self.gmap.add_from_depth(lin.cpu().numpy(), depth, self.cam, pose_wc,
                                        downsample=downsample,
                                        point_size=self.cfg.mapping.point_size,
                                        keyframe_id=kf_id, generator=self.gen)

    @torch.no_grad()
    def _end_render(self, state: FrameState):
        return render_views(self.gmap, state.pose1_cw[None], self.K, self.cam.width,
                            self.cam.height, self.cfg, visibility=True)

    @staticmethod
    def _median_depth(res) -> float:
        d, a = res.depth[0], res.alpha[0]
        sel = d[(d > 0) & (a > 0.95)]
        return float(sel.median()) if sel.numel() else 1.0

    def _diverged(self, prev: FrameState, new: FrameState, loss: float,
                  recent: list[float]) -> str | None:
        cfg = self.cfg
        if not math.isfinite(loss) or not np.isfinite(new.pose1_cw).all():
            return "non-finite loss or pose"
        rel = new.pose1_cw @ invert_pose(prev.pose1_cw)
        trans = float(np.linalg.norm(rel[:3, 3]))
        ang = float(np.arccos(np.clip((np.trace(rel[:3, :3]) - 1) / 2, -1, 1)))
        if trans > cfg.tracking.max_translation_jump or ang > cfg.tracking.max_rotation_jump:
            return f"pose jump {trans:.3f} m / {math.degrees(ang):.1f} deg"
        factor = cfg.tracking.divergence_loss_factor
        if len(recent) >= 5 and loss > factor * float(np.median(recent)):
            med = float(np.median(recent))
            return f"loss {loss:.4g} > {factor} x median {med:.4g}"
        return None

    # -------------------------------------------------------------------------------- main loop
    def run(self, n_frames: int, on_frame: Callable[[FrameReport], None] | None = None,
            on_phase: Callable[[str, int, int], None] | None = None) -> SlamResult:
        """Process frames ``0 .. n_frames-1``; returns the estimates and the map.

        Args:
            on_frame: called after every frame with its report.
            on_phase: called during long phases inside a frame as ``on_phase(name, done,
                total)`` (``"map init"``: the mapping on frame 0, ``"mapping"``: a keyframe's
                round), for progress displays.
        """
        def phase(name: str):
            return None if on_phase is None else (lambda done, total: on_phase(name, done, total))

        if n_frames < 1:
            raise InputError(self.seq.path, "no frames to process")
        cfg = self.cfg
        t_wall = time.perf_counter()
        gt0 = invert_pose(np.asarray(self.seq.poses[0], dtype=np.float64))
        states = [FrameState(0, gt0.copy(), gt0.copy())]
        self.states = states  # grows frame by frame: what an interrupted run got done
        obs0 = self._obs(0)
        observations: dict[int, FrameObs] = {0: obs0}
        kf_states: dict[int, FrameState] = {0: states[0]}
        n_added = self._insert(obs0, states[0], cfg.budget.pcd_downsample_init, 0)
        if n_added == 0:
            raise InputError(self.seq.path, "frame 0 has no valid depth: cannot initialise the map")
        self.mapper.optimise(kf_states, observations, [0], [0], cfg.budget.init_iters, initial=True,
                             report=phase("map init"))
        self.log(f"initialised map on frame 0: {len(self.gmap)} Gaussians")
        keyframes, window = [0], [0]
        visibility = {0: self._end_render(states[0]).visibility[0].cpu().numpy()}
        result = SlamResult(states, keyframes, self.gmap, self.crf)
        rep = FrameReport(0, float("nan"), cfg.budget.init_iters, True, False,
                          time.perf_counter() - t_wall)
        result.reports.append(rep)
        if on_frame:
            on_frame(rep)
        recent_losses: list[float] = []
        starts = [int(self.seq.exposure(i)[0]) for i in range(n_frames)]
        ends = [int(self.seq.exposure(i)[1]) for i in range(n_frames)]
        for i in range(1, n_frames):
            raise_if_interrupted()  # one whose exception was swallowed: stop within a frame
            t_frame = time.perf_counter()
            obs = self._obs(i)
            t0, t1 = (int(v) for v in self.seq.exposure(i))
            prev_prev_end = ends[i - 2] if i >= 2 else None
            init = predict_initial(i, states, cfg.tracking.motion_model, t0, t1, ends[i - 1],
                                   prev_prev_end, starts[i - 1])
            # Without a velocity the start is off by the whole motion since the previous frame.
            iters = None
            if (cfg.budget.tracking_iters_no_prior is not None
                    and cfg.tracking.motion_model == "constant-velocity"
                    and last_motion(states, cfg.tracking.motion_model, ends[i - 1],
                                    prev_prev_end, starts[i - 1]) is None):
                iters = cfg.budget.tracking_iters_no_prior
            anchor = None
            since_prev = max(t1 - ends[i - 1], 1)
            short = t1 - t0 < cfg.tracking.short_exposure_ratio * since_prev
            if cfg.tracking.continuous_exposure or short:
                anchor = (states[-1].pose1_cw, (t0 - ends[i - 1]) / since_prev)
            tr = track_frame(self.gmap, self.crf, obs, init, self.K, self.cam.width,
                             self.cam.height, cfg, self.theta, self.eps, start_anchor=anchor,
                             iterations=iters)
            why = self._diverged(states[-1], tr.state, tr.loss, recent_losses)
            diverged = why is not None
            if diverged:
                self.log(f"frame {i}: tracking diverged ({why}); re-tracking from the previous "
                         "pose with half the learning rate")
                result.divergences.append(f"frame {i}: {why}")
                init = predict_initial(i, states, "constant-position", t0, t1, None, None)
                tr = track_frame(self.gmap, self.crf, obs, init, self.K, self.cam.width,
                                 self.cam.height, cfg, self.theta, self.eps, lr_scale=0.5,
                                 start_anchor=anchor)
                if self._diverged(states[-1], tr.state, tr.loss, recent_losses) is not None:
                    self.log(f"frame {i}: re-tracking diverged too; keeping the previous pose")
                    tr.state = FrameState(i, states[-1].pose1_cw.copy(),
                                          states[-1].pose1_cw.copy(), states[-1].exp_a,
                                          states[-1].exp_b)
            if math.isfinite(tr.loss):
                recent_losses = (recent_losses + [tr.loss])[-20:]
            states.append(tr.state)
            res = self._end_render(tr.state)
            vis = res.visibility[0].cpu().numpy()
            last = keyframes[-1]
            is_kf = (not diverged) and is_keyframe(
                i, last, tr.state.pose1_cw, kf_states[last].pose1_cw,
                vis, visibility[last], self._median_depth(res), len(window), cfg.keyframes,
                cfg.budget.window_size)
            if is_kf:
                keyframes.append(i)
                kf_states[i] = tr.state
                observations[i] = obs
                visibility[i] = vis
                window, removed = update_window(window, i, visibility, {
                    k: kf_states[k].pose1_cw for k in kf_states}, cfg.keyframes,
                    cfg.budget.window_size)
                self._insert(obs, tr.state, cfg.budget.pcd_downsample, i)
                self.mapper.optimise(kf_states, observations, window, keyframes,
                                     cfg.budget.mapping_iters, report=phase("mapping"))
                for k in window:  # MonoGS recomputes window visibility after mapping
                    visibility[k] = self._end_render(kf_states[k]).visibility[0].cpu().numpy()
                if removed:
                    self.log(f"frame {i}: keyframe; window -{removed}")
            rep = FrameReport(i, tr.loss, tr.iterations, is_kf, diverged,
                              time.perf_counter() - t_frame)
            result.reports.append(rep)
            if on_frame:
                on_frame(rep)
        if cfg.mapping.refine_iters > 0:
            t_ref = time.perf_counter()
            loss = self.mapper.refine(kf_states, observations, keyframes, cfg.mapping.refine_iters)
            self.log(f"refined the map: {cfg.mapping.refine_iters} iterations over "
                     f"{len(keyframes)} keyframes in {time.perf_counter() - t_ref:.1f} s "
                     f"(loss {loss:.4g})")
        result.keyframes = keyframes
        return result
