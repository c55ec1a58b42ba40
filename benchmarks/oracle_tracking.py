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

Diagnostic only: the SLAM system is not meant to accept poses from outside, so this script
wraps the tracker function the system calls.
"""

from __future__ import annotations

import argparse
import csv
import io
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np

import egs_bench.slam.system as slam_system
from egs_bench.datasets.registry import load_sequence
from egs_bench.eval.evaluate import evaluate_run
from egs_bench.fileio import write_text_atomic
from egs_bench.geometry import invert_pose, rotation_angle
from egs_bench.geometry.se3 import interpolate_trajectory
from egs_bench.runs.registry import get_method
from egs_bench.slam.config import parse_overrides
from egs_bench.slam.frames import FrameState
from egs_bench.slam.mapper import Mapper
from egs_bench.slam.runner import run_slam

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


def ground_truth_w2c(seq) -> Callable[[int], np.ndarray]:
    """``pose(t_us)``: the world-to-camera ground truth [4, 4] of ``seq`` at time ``t_us``
    (microseconds), interpolated in ``groundtruth_dense.txt``."""
    dense = seq.dense_trajectory
    if dense is None:
        raise SystemExit(f"{seq.path}: no groundtruth_dense.txt, cannot place exposure starts")

    def pose(t_us: int) -> np.ndarray:
        wc = interpolate_trajectory(dense.timestamps, dense.poses, np.array([t_us * 1e-6]))[0]
        return invert_pose(wc)

    return pose


def install_oracle(seq, until: int | None = None,
                   errors: list[tuple[float, ...]] | None = None) -> None:
    """Make the SLAM system's tracker return ground-truth exposure trajectories of ``seq``
    for frames ``<= until`` (all frames when None); append each tracked frame's errors
    (:data:`ERROR_COLUMNS`) to ``errors`` when given."""
    gt_w2c = ground_truth_w2c(seq)
    track = slam_system.track_frame

    def oracle(gmap, crf, obs, init, *args, **kwargs):
        result = track(gmap, crf, obs, init, *args, **kwargs)
        t0, t1 = seq.exposure(obs.index)
        pose1 = gt_w2c(t1)
        pose0 = gt_w2c(t0) if len(obs.fractions) > 1 else pose1.copy()
        if errors is not None:
            errors.append((obs.index, *pose_error(result.state.pose1_cw, pose1),
                           *pose_error(result.state.pose0_cw, pose0),
                           *pose_error(init.pose1_cw, pose1)))
        if until is None or obs.index <= until:
            result.state = FrameState(obs.index, pose0, pose1, result.state.exp_a,
                                      result.state.exp_b)
        return result

    slam_system.track_frame = oracle


def install_exposure0_oracle(seq) -> None:
    """Make the map initialisation of methods with the blur model start from frame 0's
    ground-truth exposure start ``T_0`` (``T_tau`` stays where the system put it, at the
    ground truth)."""
    gt_w2c = ground_truth_w2c(seq)
    optimise = Mapper.optimise

    def with_true_exposure0(self, states, *args, **kwargs):
        if kwargs.get("initial") and self.cfg.method.blur_model and 0 in states:
            states[0].pose0_cw = gt_w2c(seq.exposure(0)[0])
        return optimise(self, states, *args, **kwargs)

    Mapper.optimise = with_true_exposure0  # type: ignore[method-assign]


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
    install_oracle(seq, args.oracle_until, errors)
    if args.oracle_exposure0:
        install_exposure0_oracle(seq)
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
        run_slam(seq, out, method_name=name, config=cfg, preset=args.preset, seed=args.seed,
                 max_frames=args.max_frames, progress=False)
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
