"""The SLAM loop: initialise on frame 0, then track every frame, select keyframes, map."""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import torch

from egs_bench.datasets.sequence_view import SequenceView
from egs_bench.errors import InputError
from egs_bench.geometry import invert_pose
from egs_bench.geometry.lie import se3_exp
from egs_bench.interrupts import raise_if_interrupted
from egs_bench.render import GaussianMap, RasterResult
from egs_bench.slam.components import (
    KeyframePolicy,
    MapOptimiser,
    SlamComponents,
    Tracker,
    check_part,
)
from egs_bench.slam.config import SlamConfig
from egs_bench.slam.context import SlamContext
from egs_bench.slam.crf import CameraResponse, make_crf
from egs_bench.slam.frames import FrameObs, FrameState, load_frame
from egs_bench.slam.keyframes import KeyframeCandidate
from egs_bench.slam.scheduling import ConcurrentMapping, MapRound, iterations_per_frame
from egs_bench.slam.tracker import TrackRequest, TrackResult, last_motion, predict_initial


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


@dataclass
class _Keyframes:
    """The loop's keyframe bookkeeping: keyframe ids in order, the window (newest first), and
    per keyframe its state, observations and visibility set (bool [N] over the Gaussians)."""

    ids: list[int]
    window: list[int]
    states: dict[int, FrameState]
    observations: dict[int, FrameObs]
    visibility: dict[int, np.ndarray]

    def poses_cw(self) -> dict[int, np.ndarray]:
        return {k: s.pose1_cw for k, s in self.states.items()}


def perturbed_pose(pose_cw: np.ndarray, perturbation: int, size: float = 1e-6) -> np.ndarray:
    """``pose_cw`` [4, 4] moved by ``size`` rad about and ``size`` m along directions drawn
    from seed ``perturbation`` (0: unchanged), left-multiplied as tracking's steps are."""
    if perturbation == 0:
        return pose_cw
    rng = np.random.default_rng(perturbation)
    twist = np.concatenate([rng.normal(size=3), rng.normal(size=3)])
    twist[:3] *= size / np.linalg.norm(twist[:3])
    twist[3:] *= size / np.linalg.norm(twist[3:])
    return se3_exp(twist) @ pose_cw


class SlamSystem:
    """EGS-SLAM (or a configured variant) on one sequence.

    Args:
        seq: an opened :class:`~egs_bench.datasets.sequence.Sequence`, or a view of one
            (:class:`~egs_bench.datasets.sequence_view.SequenceView`).
        cfg: validated configuration.
        device: torch device for maps and images.
        seed: seeds every random choice (insertion subsampling, random mapping views).
        log: callback for human-readable log lines.
        components: the tracker, mapper and keyframe policy (default: the built-in ones,
            configured by ``cfg``); see :mod:`egs_bench.slam.components`.
    """

    def __init__(self, seq: SequenceView, cfg: SlamConfig, device: str = "cpu", seed: int = 0,
                 log: Callable[[str], None] | None = None,
                 components: SlamComponents | None = None) -> None:
        self.seq, self.cfg = seq, cfg
        parts = components or SlamComponents()
        self.ctx = SlamContext.build(seq, cfg, device, parts.loss_terms)
        self.device = self.ctx.device
        self.log = log or (lambda _m: None)
        self.gen = torch.Generator().manual_seed(seed)  # insertion subsampling
        self.rng = np.random.default_rng(seed)  # random mapping views
        torch.manual_seed(seed)
        self.gmap = GaussianMap.empty(torch.float32, self.device)
        m = cfg.method
        self.crf = make_crf(m.crf, m.crf_nodes, m.crf_alpha, m.crf_init, self.device)
        self.states: list[FrameState] = []  # filled by run()
        self.want_events = cfg.method.event_tracking or cfg.method.event_mapping
        if self.want_events and not seq.has_events:
            self.log("sequence has no events: event losses see empty event maps")
        self.tracker = parts.tracker(self.ctx)
        self.mapper = parts.mapper(self.ctx, self.gmap, self.crf, self.rng)
        self.keyframe_policy = parts.keyframes(self.ctx)
        check_part(self.tracker, Tracker, "tracker")
        check_part(self.mapper, MapOptimiser, "mapper")
        check_part(self.keyframe_policy, KeyframePolicy, "keyframe policy")
        per_frame = iterations_per_frame(cfg.budget.mapping_iters, cfg.keyframes.interval,
                                         cfg.budget.mapping_iters_per_frame)
        self.concurrent = ConcurrentMapping.scheduled(cfg.mapping, per_frame, self.device,
                                                      self._round_closed)
        self._kfs: _Keyframes | None = None

    # -------------------------------------------------------------------------------- helpers
    def obs(self, i: int) -> FrameObs:
        """Frame ``i``'s observations at the internal resolution."""
        return load_frame(self.seq, i, self.ctx.cam, self.cfg, self.want_events, self.device)

    def insert(self, obs: FrameObs, state: FrameState, downsample: int, kf_id: int,
               candidates: torch.Tensor | None = None) -> int:
        """Add Gaussians back-projected from ``obs``'s depth at ``state``'s ``T_tau``, from
        the pixels of ``candidates`` (bool [H, W]; None: every valid pixel); returns how
        many."""
        with torch.no_grad():
            lin = self.crf.inverse(obs.rgb.to(torch.float32)).clamp_min(0.0)
        masked = obs.depth * obs.rgb_mask  # MonoGS zeroes near-black pixels
        if candidates is not None:
            masked = masked * candidates
        depth = masked.cpu().numpy()
        pose_wc = invert_pose(state.pose1_cw)
        return self.gmap.add_from_depth(lin.cpu().numpy(), depth, self.ctx.cam, pose_wc,
                                        downsample=downsample,
                                        point_size=self.cfg.mapping.point_size,
                                        keyframe_id=kf_id, generator=self.gen)

    @torch.no_grad()
    def _end_render(self, state: FrameState) -> tuple[RasterResult, np.ndarray]:
        """The render at ``state``'s ``T_tau`` and its visibility set (bool [N] over the
        Gaussians)."""
        res = self.ctx.render(self.gmap, state.pose1_cw[None], phase="selection",
                              visibility=True)
        assert res.visibility is not None  # asked for
        return res, res.visibility[0].cpu().numpy()

    def _uncovered(self, obs: FrameObs, res: RasterResult) -> torch.Tensor | None:
        """The pixels of a new keyframe that its render at ``T_tau`` (``res``) does not
        explain yet (``budget.insertion = "uncovered"``), bool [H, W]; None: every pixel."""
        b = self.cfg.budget
        if b.insertion == "all":
            return None
        alpha, depth = res.alpha[0], res.expected_depth[0]
        off = (depth - obs.depth).abs() > b.insertion_depth_error * obs.depth
        return (alpha < b.insertion_alpha) | off

    def _visibility(self, state: FrameState) -> np.ndarray:
        return self._end_render(state)[1]

    @staticmethod
    def _median_depth(res: RasterResult) -> float:
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

    # -------------------------------------------------------------------------------- phases
    def _initialise(self, report: Callable[[int, int], None] | None) -> _Keyframes:
        """Frame 0 at its ground-truth pose (``T_0 = T_tau``): insert it and build the map."""
        gt0 = perturbed_pose(invert_pose(np.asarray(self.seq.poses[0], dtype=np.float64)),
                             self.cfg.runtime.perturbation)
        state0 = FrameState(0, gt0.copy(), gt0.copy())
        self.states.append(state0)
        obs0 = self.obs(0)
        kfs = _Keyframes([0], [0], {0: state0}, {0: obs0}, {})
        if self.insert(obs0, state0, self.cfg.budget.pcd_downsample_init, 0) == 0:
            raise InputError(self.seq.path, "frame 0 has no valid depth: cannot initialise the map")
        self.mapper.optimise(kfs.states, kfs.observations, [0], [0], self.cfg.budget.init_iters,
                             initial=True, report=report)
        self.log(f"initialised map on frame 0: {len(self.gmap)} Gaussians")
        kfs.visibility[0] = self._visibility(state0)
        return kfs

    def _request(self, i: int, obs: FrameObs) -> TrackRequest:
        """Frame ``i``'s tracking request: the motion model's prediction, the budget, and the
        exposure-start anchor (``continuous_exposure`` or a short exposure)."""
        cfg, ctx, states = self.cfg, self.ctx, self.states
        t0, t1 = ctx.exposure(i)
        prev_end, prev_start = ctx.exposure(i - 1)[1], ctx.exposure(i - 1)[0]
        prev_prev_end = ctx.exposure(i - 2)[1] if i >= 2 else None
        init = predict_initial(i, states, cfg.tracking.motion_model, t0, t1, prev_end,
                               prev_prev_end, prev_start)
        # Without a velocity the start is off by the whole motion since the previous frame.
        iters = None
        if (cfg.budget.tracking_iters_no_prior is not None
                and cfg.tracking.motion_model == "constant-velocity"
                and last_motion(states, cfg.tracking.motion_model, prev_end, prev_prev_end,
                                prev_start) is None):
            iters = cfg.budget.tracking_iters_no_prior
        anchor = None
        since_prev = max(t1 - prev_end, 1)
        short = t1 - t0 < cfg.tracking.short_exposure_ratio * since_prev
        if cfg.tracking.continuous_exposure or short:
            anchor = (states[-1].pose1_cw, (t0 - prev_end) / since_prev)
        return TrackRequest(obs, init, anchor, iters)

    def _track(self, i: int, obs: FrameObs, recent_losses: list[float],
               divergences: list[str]) -> tuple[TrackResult, bool]:
        """Track frame ``i``; on divergence re-track once from the previous pose with half the
        learning rate, and keep the previous pose if that diverges too. With concurrent
        mapping, this frame's slice of mapping runs meanwhile and tracking reads a snapshot
        of the map; what it reads of the estimates is copied before the slice starts."""
        request = self._request(i, obs)
        prev = dataclasses.replace(self.states[-1])  # mapping may refine the keyframe's state
        snapshot = self.concurrent.start_slice((self.gmap, self.crf)) if self.concurrent \
            else None
        gmap, crf = (snapshot.gmap, snapshot.crf) if snapshot else (self.gmap, self.crf)
        try:
            result = self._track_attempts(i, request, prev, (gmap, crf), recent_losses,
                                          divergences)
        except BaseException:
            if self.concurrent is not None:
                self.concurrent.cancel()  # stop mapping at its next iteration, then re-raise
            raise
        if self.concurrent is not None:
            self.concurrent.end_slice()
        return result

    def _track_attempts(self, i: int, request: TrackRequest, prev: FrameState,
                        maps: tuple[GaussianMap, CameraResponse], recent_losses: list[float],
                        divergences: list[str]) -> tuple[TrackResult, bool]:
        gmap, crf = maps
        tr = self.tracker.track(gmap, crf, request)
        why = self._diverged(prev, tr.state, tr.loss, recent_losses)
        if why is None:
            return tr, False
        self.log(f"frame {i}: tracking diverged ({why}); re-tracking from the previous "
                 "pose with half the learning rate")
        divergences.append(f"frame {i}: {why}")
        t0, t1 = self.ctx.exposure(i)
        init = predict_initial(i, [prev], "constant-position", t0, t1, None, None)
        tr = self.tracker.track(gmap, crf, TrackRequest(
            request.obs, init, request.start_anchor, lr_scale=0.5))
        if self._diverged(prev, tr.state, tr.loss, recent_losses) is not None:
            self.log(f"frame {i}: re-tracking diverged too; keeping the previous pose")
            tr.state = FrameState(i, prev.pose1_cw.copy(), prev.pose1_cw.copy(), prev.exp_a,
                                  prev.exp_b)
        return tr, True

    def _keyframe_step(self, i: int, obs: FrameObs, state: FrameState, kfs: _Keyframes,
                       report: Callable[[int, int], None] | None) -> bool:
        """Make frame ``i`` a keyframe if the policy wants it: insert Gaussians and run a
        mapping round on the updated window. Returns whether it became one."""
        res, vis = self._end_render(state)
        last = kfs.ids[-1]
        if not self.keyframe_policy.is_keyframe(KeyframeCandidate(
                i, last, state.pose1_cw, kfs.states[last].pose1_cw, vis, kfs.visibility[last],
                self._median_depth(res), len(kfs.window))):
            return False
        kfs.ids.append(i)
        kfs.states[i], kfs.observations[i], kfs.visibility[i] = state, obs, vis
        kfs.window, removed = self.keyframe_policy.update_window(kfs.window, i, kfs.visibility,
                                                                 kfs.poses_cw())
        if self.concurrent is not None:
            self.concurrent.finish_queued()  # an open round must not see the map change
        self.insert(obs, state, self.cfg.budget.pcd_downsample, i, self._uncovered(obs, res))
        if self.concurrent is not None:
            self.concurrent.submit(self.mapper.begin_round(
                kfs.states, kfs.observations, kfs.window, kfs.ids,
                self.cfg.budget.mapping_iters))
        else:
            self.mapper.optimise(kfs.states, kfs.observations, kfs.window, kfs.ids,
                                 self.cfg.budget.mapping_iters, report=report)
            self._refresh_visibility(kfs.window)
        if removed:
            self.log(f"frame {i}: keyframe; window -{removed}")
        return True

    def _refresh_visibility(self, window: list[int]) -> None:
        """MonoGS recomputes the window's visibility sets after each mapping round."""
        assert self._kfs is not None
        for k in window:
            self._kfs.visibility[k] = self._visibility(self._kfs.states[k])

    def _round_closed(self, round_: MapRound) -> None:
        self._refresh_visibility(round_.window)

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
        def phase(name: str) -> Callable[[int, int], None] | None:
            return None if on_phase is None else (lambda done, total: on_phase(name, done, total))

        if n_frames < 1:
            raise InputError(self.seq.path, "no frames to process")
        t_wall = time.perf_counter()
        self.states = []  # grows frame by frame: what an interrupted run got done
        self.ctx.work.begin_frame(0)
        kfs = self._kfs = self._initialise(phase("map init"))
        result = SlamResult(self.states, kfs.ids, self.gmap, self.crf)
        result.reports.append(FrameReport(0, float("nan"), self.cfg.budget.init_iters, True,
                                          False, time.perf_counter() - t_wall))
        if on_frame:
            on_frame(result.reports[-1])
        try:
            self._frames(n_frames, kfs, result, on_frame, phase("mapping"))
        finally:
            if self.concurrent is not None:
                self.concurrent.cancel()
        self.ctx.work.end_frames()
        self._final_refinement(kfs)
        result.keyframes = kfs.ids
        return result

    def _frames(self, n_frames: int, kfs: _Keyframes, result: SlamResult,
                on_frame: Callable[[FrameReport], None] | None,
                report: Callable[[int, int], None] | None) -> None:
        """Frames ``1 .. n_frames-1``: track, maybe make a keyframe (and map), report."""
        recent_losses: list[float] = []
        for i in range(1, n_frames):
            raise_if_interrupted()  # one whose exception was swallowed: stop within a frame
            t_frame = time.perf_counter()
            self.ctx.work.begin_frame(i)
            obs = self.obs(i)
            tr, diverged = self._track(i, obs, recent_losses, result.divergences)
            if math.isfinite(tr.loss):
                recent_losses[:] = (recent_losses + [tr.loss])[-20:]
            self.states.append(tr.state)
            is_kf = not diverged and self._keyframe_step(i, obs, tr.state, kfs, report)
            if i == n_frames - 1 and self.concurrent is not None:
                self.concurrent.finish_queued()  # the map is complete when the run ends
            result.reports.append(FrameReport(i, tr.loss, tr.iterations, is_kf, diverged,
                                              time.perf_counter() - t_frame))
            if on_frame:
                on_frame(result.reports[-1])

    def _final_refinement(self, kfs: _Keyframes) -> None:
        iters = self.cfg.mapping.refine_iters
        if iters <= 0:
            return
        t_ref = time.perf_counter()
        loss = self.mapper.refine(kfs.states, kfs.observations, kfs.ids, iters)
        self.log(f"refined the map: {iters} iterations over {len(kfs.ids)} keyframes in "
                 f"{time.perf_counter() - t_ref:.1f} s (loss {loss:.4g})")
