"""Mapping quality without tracking error: run a method with ground-truth exposure trajectories.

Every frame is tracked as usual (so exposure compensation is estimated), then its ``T_0`` and
``T_tau`` are replaced by the ground truth at the exposure's start and end (interpolated in
``groundtruth_dense.txt``). What remains of the rendering error is the mapping's: this
separates "the blur model does not deblur" from "tracking error blurs the renders".

    EGS_BENCH_DATA=data python benchmarks/oracle_tracking.py --seq demo-fast \
        --methods egs,monogs [--set resolution_scale=1.0] [--max-frames 40]

Two further uses, both written per run as ``tracking_errors.csv`` (one row per tracked
frame: the tracker's own ``T_tau`` / ``T_0`` estimate and its constant-velocity prediction,
each against the ground truth, camera-centre distance in cm and rotation in degrees, before
the ground truth replaces them):

* how well a method's tracker does against a map built from correct poses (``--methods
  egs,egs-no-event-mapping``: the same frames, predictions and map poses for both, so the
  per-frame errors compare paired);
* a clean start (``--oracle-until N``): ground truth for frames ``0..N`` only, the tracker's own
  estimates after that, e.g. to take a sequence's start-up transient out of a closed-loop
  comparison;
* frame 0's exposure span (``--oracle-exposure0``): the SLAM system places frame 0 with
  ``T_0 = T_tau`` (its motion within the exposure is unknown), so the map of frame 0 holds the
  blur and frame 1 has no velocity to extrapolate; this puts ``T_0`` of frame 0 at the ground
  truth before the map is initialised, for methods with the blur model (use it with
  ``--oracle-until`` to let the tracker run from frame 1).

The oracles are SLAM components (:mod:`egs_bench.slam.components`) that wrap the built-in
tracker and mapper; the system runs them like any other.
"""

from __future__ import annotations

import argparse
import csv
import io
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np

from egs_bench.datasets.registry import load_sequence
from egs_bench.datasets.sequence import Sequence
from egs_bench.eval.evaluate import evaluate_run
from egs_bench.fileio import write_text_atomic
from egs_bench.geometry import invert_pose, rotation_angle
from egs_bench.geometry.se3 import interpolate_trajectory
from egs_bench.runs.registry import get_method
from egs_bench.slam.components import MapOptimiser, SlamComponents, Tracker
from egs_bench.slam.config import parse_overrides
from egs_bench.slam.context import SlamContext
from egs_bench.slam.frames import FrameState
from egs_bench.slam.mapper import Mapper
from egs_bench.slam.runner import RunSettings, run_slam
from egs_bench.slam.scheduling import MapRound
from egs_bench.slam.tracker import GradientTracker, TrackRequest, TrackResult

ERROR_COLUMNS = ("frame", "tau_cm", "tau_deg", "start_cm", "start_deg", "predicted_cm",
                 "predicted_deg")


def pose_error(estimate_cw: np.ndarray, truth_cw: np.ndarray) -> tuple[float, float]:
    """Camera-centre distance (cm) and relative rotation (deg) of two world-to-camera poses
    [4, 4] (metres)."""
    centre_est = invert_pose(estimate_cw)[:3, 3]
    centre_true = invert_pose(truth_cw)[:3, 3]
    return (float(np.linalg.norm(centre_est - centre_true) * 100.0),
            math.degrees(rotation_angle(estimate_cw, truth_cw)))


def errors_csv(rows: list[tuple[float, ...]]) -> str:
    """``tracking_errors.csv`` text of rows ``(frame, tau_cm, tau_deg, start_cm, start_deg,
    predicted_cm, predicted_deg)``."""
    text = io.StringIO()
    writer = csv.writer(text, lineterminator="\n")
    writer.writerow(ERROR_COLUMNS)
    writer.writerows([int(r[0]), *(f"{v:.6f}" for v in r[1:])] for r in rows)
    return text.getvalue()


def ground_truth_w2c(seq: Sequence) -> Callable[[int], np.ndarray]:
    """``pose(t_us)``: the world-to-camera ground truth [4, 4] of ``seq`` at time ``t_us``
    (microseconds), interpolated in ``groundtruth_dense.txt``."""
    dense = seq.dense_trajectory
    if dense is None:
        raise SystemExit(f"{seq.path}: no groundtruth_dense.txt, cannot place exposure starts")

    def pose(t_us: int) -> np.ndarray:
        wc = interpolate_trajectory(dense.timestamps, dense.poses, np.array([t_us * 1e-6]))[0]
        return invert_pose(wc)

    return pose


class OracleTracker:
    """A :class:`~egs_bench.slam.components.Tracker` that runs ``inner`` (so exposure
    compensation is estimated and its errors can be recorded), then returns the ground-truth
    exposure trajectory of ``seq`` for frames ``<= until`` (all frames when None). Appends
    each tracked frame's errors (:data:`ERROR_COLUMNS`) to ``errors`` when given."""

    def __init__(self, inner: Tracker, seq: Sequence, until: int | None = None,
                 errors: list[tuple[float, ...]] | None = None) -> None:
        self.inner, self.seq, self.until, self.errors = inner, seq, until, errors
        self.gt_w2c = ground_truth_w2c(seq)

    def track(self, gmap, crf, request: TrackRequest) -> TrackResult:
        result = self.inner.track(gmap, crf, request)
        obs, init = request.obs, request.init
        t0, t1 = self.seq.exposure(obs.index)
        pose1 = self.gt_w2c(t1)
        pose0 = self.gt_w2c(t0) if len(obs.fractions) > 1 else pose1.copy()
        if self.errors is not None:
            self.errors.append((obs.index, *pose_error(result.state.pose1_cw, pose1),
                                *pose_error(result.state.pose0_cw, pose0),
                                *pose_error(init.pose1_cw, pose1)))
        if self.until is None or obs.index <= self.until:
            result.state = FrameState(obs.index, pose0, pose1, result.state.exp_a,
                                      result.state.exp_b)
        return result


class TrueExposure0Mapper:
    """A :class:`~egs_bench.slam.components.MapOptimiser` that puts frame 0's exposure start
    ``T_0`` at the ground truth before ``inner`` initialises the map, for methods with the blur
    model (``T_tau`` stays where the system put it, at the ground truth)."""

    def __init__(self, inner: MapOptimiser, seq: Sequence, blur_model: bool) -> None:
        self.inner, self.blur_model = inner, blur_model
        self.start_cw = ground_truth_w2c(seq)(seq.exposure(0)[0])

    def optimise(self, states, observations, window, all_keyframes, iterations, *,
                 initial=False, fixed_end_pose=0, report=None) -> float:
        round_ = self.begin_round(states, observations, window, all_keyframes, iterations,
                                  initial=initial, fixed_end_pose=fixed_end_pose, report=report)
        round_.advance(iterations)
        return round_.close()

    def begin_round(self, states, observations, window, all_keyframes, iterations, *,
                    initial=False, fixed_end_pose=0, report=None) -> MapRound:
        if initial and self.blur_model and 0 in states:
            states[0].pose0_cw = self.start_cw.copy()
        return self.inner.begin_round(states, observations, window, all_keyframes, iterations,
                                      initial=initial, fixed_end_pose=fixed_end_pose,
                                      report=report)

    def refine(self, states, observations, keyframes, iterations) -> float:
        return self.inner.refine(states, observations, keyframes, iterations)


def oracle_components(seq: Sequence, until: int | None, errors: list[tuple[float, ...]] | None,
                      exposure0: bool) -> SlamComponents:
    """The SLAM components of an oracle run: :class:`OracleTracker` around the built-in
    tracker and, with ``exposure0``, :class:`TrueExposure0Mapper` around the built-in mapper."""
    def tracker(ctx: SlamContext) -> Tracker:
        return OracleTracker(GradientTracker(ctx), seq, until, errors)

    def mapper(ctx: SlamContext, gmap, crf, rng) -> MapOptimiser:
        inner = Mapper(ctx, gmap, crf, rng)
        return TrueExposure0Mapper(inner, seq, ctx.cfg.method.blur_model) if exposure0 else inner

    return SlamComponents(tracker=tracker, mapper=mapper)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seq", required=True, help="sequence folder or name")
    ap.add_argument("--methods", default="egs,monogs")
    ap.add_argument("--preset", default="cpu", choices=["cpu", "paper"])
    ap.add_argument("--max-frames", type=int, default=None)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--oracle-until", type=int, default=None, metavar="N",
                    help="ground truth for frames 0..N only, the tracker's estimates after")
    ap.add_argument("--oracle-exposure0", action="store_true",
                    help="frame 0's exposure start at the ground truth (blur-model methods)")
    ap.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--out", type=Path, default=Path("bench_out/oracle"))
    args = ap.parse_args()
    if args.oracle_until is not None and args.oracle_until < 0:
        ap.error("--oracle-until must be >= 0")
    seq = load_sequence(args.seq)
    errors: list[tuple[float, ...]] = []
    components = oracle_components(seq, args.oracle_until, errors, args.oracle_exposure0)
    options = parse_overrides(args.overrides)
    print("| method | PSNR dB | SSIM | ATE cm | T_tau tracking error cm (mean) |")
    print("|:--|--:|--:|--:|--:|")
    for name in args.methods.split(","):
        method = get_method(name)
        if not hasattr(method, "config"):
            raise SystemExit(f"method {name!r} is not configured by a SlamConfig; the oracle "
                             "needs a built-in-style method")
        cfg = method.config(args.preset).replace(**options)
        out = args.out / seq.name / name
        errors.clear()
        run_slam(seq, out, method_name=name, config=cfg,
                 settings=RunSettings(preset=args.preset, seed=args.seed,
                                      max_frames=args.max_frames, progress=False),
                 components=components)
        write_text_atomic(out / "tracking_errors.csv", errors_csv(errors))
        report = evaluate_run(out)
        r = report.get("rendering")
        if not r:
            raise SystemExit(f"{seq.path}: no sharp ground truth, nothing to score renders against")
        ate = report.get("ate", {}).get("rmse_m", float("nan")) * 100.0
        tau = float(np.mean([e[1] for e in errors])) if errors else float("nan")
        print(f"| {name} | {r['psnr_db']:.2f} | {r['ssim']:.3f} | {ate:.2f} | {tau:.3f} |",
              flush=True)


if __name__ == "__main__":
    main()
