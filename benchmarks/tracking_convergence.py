"""When does tracking converge? Per-iteration traces of a run, and where stopping rules would stop.

Runs a method with a tracker that records every iteration (loss, largest pose step, ``T_tau``;
:class:`~egs_bench.slam.tracker.TrackTrace`), then asks of each candidate stopping rule, frame
by frame: at which iteration would it stop, how far is the pose there from the pose after the
whole budget, and from the ground truth. Open loop: the run itself uses the full budget, so
later frames are tracked against the same map whatever the rule (closed-loop effects need real
runs with the rule switched on: ``--set convergence=...``).

    EGS_BENCH_DATA=data python benchmarks/tracking_convergence.py --seq demo --method egs \\
        --preset cpu --max-frames 12 [--set KEY=VALUE] [--out bench_out/convergence]

Writes ``traces.npz`` (per frame: losses, step norms, poses) next to the run and prints one
table row per rule. ``--from-traces RUN`` analyses the traces an earlier invocation left in the
run folder ``RUN`` instead of running again.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np

from egs_bench.datasets.registry import load_sequence
from egs_bench.datasets.sequence import Sequence
from egs_bench.geometry import invert_pose, rotation_angle
from egs_bench.runs.registry import get_method
from egs_bench.slam.components import SlamComponents
from egs_bench.slam.config import parse_overrides
from egs_bench.slam.convergence import stop_iteration
from egs_bench.slam.runner import RunSettings, run_slam
from egs_bench.slam.tracker import GradientTracker, TrackRequest, TrackResult, TrackTrace


def recording_components(traces: dict[int, TrackTrace]) -> SlamComponents:
    """Components whose tracker is the built-in one with every iteration recorded (the last
    attempt of a frame wins, as its pose is the one the system keeps)."""
    class Recording(GradientTracker):
        def track(self, gmap, crf, request: TrackRequest) -> TrackResult:
            result = super().track(gmap, crf, dataclasses.replace(request, trace=True))
            if result.trace is not None:
                traces[request.obs.index] = result.trace
            return result

    return SlamComponents(tracker=Recording)


def pose_gap(a_cw: np.ndarray, b_cw: np.ndarray) -> tuple[float, float]:
    """Camera-centre distance (cm) and rotation (deg) between two world-to-camera poses."""
    d = np.linalg.norm(invert_pose(a_cw)[:3, 3] - invert_pose(b_cw)[:3, 3]) * 100.0
    return float(d), math.degrees(rotation_angle(a_cw, b_cw))


Rule = Callable[[TrackTrace], int]


def candidate_rules(budget: int) -> dict[str, Rule]:
    """Stopping rules to compare, by name: each maps a trace to the number of iterations it
    would have run (``budget`` when it never triggers)."""
    rules: dict[str, Rule] = {"fixed": lambda t: len(t.losses)}
    for rel in (0.05, 0.1, 0.2):
        for patience in (3, 5):
            rules[f"relative-step {rel} x{patience}"] = (
                lambda t, r=rel, p=patience: stop_iteration(t.losses, t.step_norms, t.poses1_cw,
                                                            "relative-step", r, p, budget))
    for tol in (1e-3, 1e-4):
        for patience in (5, 10):
            rules[f"plateau {tol:g} x{patience}"] = (
                lambda t, r=tol, p=patience: stop_iteration(t.losses, t.step_norms, t.poses1_cw,
                                                            "plateau", r, p, budget))
    for tol in (0.2, 0.3):
        for patience in (10, 20):
            rules[f"net-motion {tol:g} x{patience}"] = (
                lambda t, r=tol, p=patience: stop_iteration(t.losses, t.step_norms, t.poses1_cw,
                                                            "net-motion", r, p, budget))
    return rules


def analyse(traces: dict[int, TrackTrace], truth_cw: dict[int, np.ndarray],
            budget: int) -> list[dict[str, float | str]]:
    """Per rule: mean iterations, and the mean / max pose gap at the stop to the full budget's
    pose and the ground truth minus the full budget's gap to it."""
    rows = []
    for name, rule in candidate_rules(budget).items():
        iters, gaps, extra = [], [], []
        for i, trace in sorted(traces.items()):
            n = max(1, min(rule(trace), len(trace.losses)))
            iters.append(n)
            stop, final = trace.poses1_cw[n - 1], trace.poses1_cw[-1]
            gaps.append(pose_gap(stop, final))
            extra.append(pose_gap(stop, truth_cw[i])[0] - pose_gap(final, truth_cw[i])[0])
        g = np.array(gaps)
        rows.append({"rule": name, "mean_iters": float(np.mean(iters)),
                     "gap_cm_mean": float(g[:, 0].mean()), "gap_cm_max": float(g[:, 0].max()),
                     "gap_deg_max": float(g[:, 1].max()),
                     "gt_extra_cm_mean": float(np.mean(extra))})
    return rows


def load_traces(path: Path) -> dict[int, TrackTrace]:
    """The traces that :func:`main` saved in ``path`` (``traces.npz``), by frame."""
    data = np.load(path)
    frames = sorted(int(k.rsplit("_", 1)[1]) for k in data if k.startswith("losses_"))
    return {i: TrackTrace(data[f"losses_{i}"], data[f"step_norms_{i}"],
                          data[f"poses1_cw_{i}"]) for i in frames}


def report(seq: Sequence, method: str, preset: str, traces: dict[int, TrackTrace],
           budget: int) -> None:
    truth = {i: invert_pose(np.asarray(seq.poses[i])) for i in traces}
    print(f"{seq.name}, {method}, preset {preset}, {len(traces)} tracked frames, "
          f"budget {budget} iterations")
    print("| rule | mean iterations | gap to full budget cm (mean / max) | max deg "
          "| GT error change cm (mean) |")
    print("|:--|--:|--:|--:|--:|")
    for r in analyse(traces, truth, budget):
        print(f"| {r['rule']} | {r['mean_iters']:.1f} | {r['gap_cm_mean']:.4f} / "
              f"{r['gap_cm_max']:.4f} | {r['gap_deg_max']:.4f} | {r['gt_extra_cm_mean']:+.4f} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seq", required=True)
    ap.add_argument("--method", default="egs")
    ap.add_argument("--preset", default="cpu", choices=["cpu", "paper"])
    ap.add_argument("--max-frames", type=int, default=None)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--out", type=Path, default=Path("bench_out/convergence"))
    ap.add_argument("--from-traces", type=Path, default=None, metavar="RUN",
                    help="analyse RUN/traces.npz of an earlier invocation instead of running")
    args = ap.parse_args()
    seq = load_sequence(args.seq)
    if args.from_traces is not None:
        import yaml

        resolved = yaml.safe_load((args.from_traces / "config.yaml").read_text())
        report(seq, resolved["method"], resolved["preset"],
               load_traces(args.from_traces / "traces.npz"),
               int(resolved["slam"]["budget"]["tracking_iters"]))
        return
    method = get_method(args.method)
    if not hasattr(method, "config"):
        ap.error(f"--method {args.method}: needs a built-in-style method")
    cfg = method.config(args.preset, seq.meta).replace(**parse_overrides(args.overrides))
    out = args.out / seq.name / args.method
    traces: dict[int, TrackTrace] = {}
    run_slam(seq, out, method_name=args.method, config=cfg.validate(),
             settings=RunSettings(preset=args.preset, seed=args.seed,
                                  max_frames=args.max_frames, progress=False, overwrite=True),
             components=recording_components(traces))
    np.savez_compressed(out / "traces.npz", **{
        f"{k}_{i}": getattr(t, k) for i, t in traces.items()
        for k in ("losses", "step_norms", "poses1_cw")})
    report(seq, args.method, args.preset, traces, cfg.budget.tracking_iters)


if __name__ == "__main__":
    main()
