"""Mapping quality without tracking error: run a method with ground-truth exposure trajectories.

Every frame is tracked as usual (so exposure compensation is estimated), then its ``T_0`` and
``T_tau`` are replaced by the ground truth at the exposure's start and end (interpolated in
``groundtruth_dense.txt``). What remains of the rendering error is the mapping's: this
separates "the blur model does not deblur" from "tracking error blurs the renders".

    EGS_BENCH_DATA=data python benchmarks/oracle_tracking.py --seq demo-fast \
        --methods egs,monogs [--set resolution_scale=1.0] [--max-frames 40]

Diagnostic only: the SLAM system is not meant to accept poses from outside, so this script
wraps the tracker function the system calls.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import egs_bench.slam.system as slam_system
from egs_bench.eval.evaluate import evaluate_run
from egs_bench.geometry import invert_pose
from egs_bench.geometry.se3 import interpolate_trajectory
from egs_bench.runs.registry import get_method
from egs_bench.slam.config import parse_overrides
from egs_bench.slam.frames import FrameState
from egs_bench.slam.runner import resolve_sequence, run_slam


def install_oracle(seq) -> None:
    """Make the SLAM system's tracker return ground-truth exposure trajectories of ``seq``."""
    dense = seq.dense_trajectory
    if dense is None:
        raise SystemExit(f"{seq.path}: no groundtruth_dense.txt, cannot place exposure starts")
    track = slam_system.track_frame

    def gt_w2c(t_us: int) -> np.ndarray:
        wc = interpolate_trajectory(dense.timestamps, dense.poses, np.array([t_us * 1e-6]))[0]
        return invert_pose(wc)

    def oracle(gmap, crf, obs, init, *args, **kwargs):
        result = track(gmap, crf, obs, init, *args, **kwargs)
        t0, t1 = seq.exposure(obs.index)
        pose1 = gt_w2c(t1)
        pose0 = gt_w2c(t0) if len(obs.fractions) > 1 else pose1.copy()
        result.state = FrameState(obs.index, pose0, pose1, result.state.exp_a,
                                  result.state.exp_b)
        return result

    slam_system.track_frame = oracle


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seq", required=True, help="sequence folder or name")
    ap.add_argument("--methods", default="egs,monogs")
    ap.add_argument("--preset", default="cpu", choices=["cpu", "paper"])
    ap.add_argument("--max-frames", type=int, default=None)
    ap.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--out", type=Path, default=Path("bench_out/oracle"))
    args = ap.parse_args()
    seq = resolve_sequence(args.seq)
    install_oracle(seq)
    options = parse_overrides(args.overrides)
    print("| method | PSNR dB | SSIM |")
    print("|:--|--:|--:|")
    for name in args.methods.split(","):
        method = get_method(name)
        if not hasattr(method, "config"):
            raise SystemExit(f"method {name!r} is not configured by a SlamConfig; the oracle "
                             "needs a built-in-style method")
        cfg = method.config(args.preset).replace(**options)
        out = args.out / seq.name / name
        run_slam(seq, out, method_name=name, config=cfg, preset=args.preset,
                 max_frames=args.max_frames, progress=False)
        r = evaluate_run(out).get("rendering")
        if not r:
            raise SystemExit(f"{seq.path}: no sharp ground truth, nothing to score renders against")
        print(f"| {name} | {r['psnr_db']:.2f} | {r['ssim']:.3f} |", flush=True)


if __name__ == "__main__":
    main()
