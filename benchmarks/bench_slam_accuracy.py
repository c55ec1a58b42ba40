"""Accuracy benchmark: EGS-SLAM vs the MonoGS-style baseline and the ablations, side by side.

Runs every method on every sequence with one preset and one or more seeds, evaluates each run
with the default protocol (``egs_bench.eval.evaluate.evaluate_run``), and prints / writes one table
(ATE RMSE in cm, PSNR / SSIM against the sharp ground truth, FPS) plus the ratios the issue
asks for (ATE egs / monogs, PSNR egs - monogs).

    python benchmarks/bench_slam_accuracy.py --seq SEQ [--seq SEQ2 ...] [--preset cpu]
        [--methods egs,monogs,egs-no-events,...] [--ablation-seq SEQ] [--max-frames N]
        [--jobs J] [--out bench_out/slam] [--set KEY=VALUE ...] [--unblurred SEQ ...]
        [--seed S [--seed S2 ...]]

With several ``--seed`` the table holds the mean over the seeds that finished and the standard
deviation (``*_std`` columns); ``seeds`` says how many finished of how many were asked for and
``error`` names each unfinished seed with its state. ``code`` is the commit each run was made
with (``egs_bench.provenance``; ``?`` for runs that predate its recording). The ratios use the
means. With at least two finished seeds per method and sequence, the summary adds how far the
seeds could move it: a 95 % bootstrap interval of the mean ATE ratio and PSNR gain, and of
each ablation row's difference to ``egs`` (:func:`seed_intervals`). The summary lines are
printed and written to ``<out>/accuracy_summary.txt``.

``--from-runs RUNS_CSV`` (repeatable) starts nothing and tabulates the ``runs.csv`` of earlier
invocations together, e.g. seeds run in separate checkouts or on several machines: one
table and one summary over all their finished runs (a run listed twice must agree; printed
only, nothing is written).

The tables of docs/notes/slam.md and BENCHMARKS.md were made with

    EGS_BENCH_DATA=data python benchmarks/bench_slam_accuracy.py --seq demo --seq demo-fast \
        --seq livingroom-fast --seq studio-fast --seq livingroom-s --seq studio-s \
        --seq demo-sharp --unblurred demo-sharp --jobs 2

(the ``cpu`` preset, half resolution, with the ablation on ``demo``) and, for the issue's
targets at full processing resolution, the same seven sequences with
``--set resolution_scale=1.0 --ablation-seq demo --unblurred demo-sharp`` (run as two
invocations, see BENCHMARKS.md).

``--set`` overrides configuration fields of every (built-in) method, as ``egs-bench run --set``.

The runs go through ``egs-bench sweep``'s machinery (:mod:`egs_bench.experiments`): one process
per run, ``--jobs`` runs in parallel sharing the CPU budget (each gets the budget divided by
``--jobs`` threads), run folders under ``<out>/runs/<seq>/<method>/seed<k>``, and a second
invocation skips runs that finished with the same configuration (``--force`` reruns them, e.g.
after a code change; ``--retry-failed`` reruns only the failed ones). Each row's numbers come
from a run the sweep reports ``done`` for this invocation's configuration: a folder made with
another preset or ``--set`` (``stale``) or by something else (``conflict``) is named in
``error``, never read. ``--status`` starts and evaluates nothing and tabulates the runs as they
are (unfinished ones carry their state in ``error``): for a long benchmark running in the
background, or several invocations sharing one ``--out``. ``<out>/sweep_summary.md`` lists
every run of the invocation (both grids).

Sequences are folders or names under $EGS_BENCH_DATA (built-in synthetic names are generated
on first use; ``--status`` lists the runs of one not generated yet as pending).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from egs_bench.errors import EgsBenchError
from egs_bench.eval.results import read_run_result
from egs_bench.experiments.spec import DEVICES, LocalOptions, RunSpec, SweepSpec
from egs_bench.experiments.sweep import run_sweep, write_summary
from egs_bench.fileio import write_text_atomic
from egs_bench.runs.registry import get_method
from egs_bench.slam.config import parse_overrides
from egs_bench.slam.methods import ConfiguredSlamMethod

DEFAULT_METHODS = ["monogs", "monogs-edi", "egs-no-events", "egs-no-event-mapping",
                   "egs-no-event-tracking", "egs-no-crf", "egs-no-ne-loss", "egs"]
# run on every --seq (the others only on the ablation sequences); monogs-edi is the paper's
# MonoGS+EDI baseline (Table VI)
MAIN_METHODS = ("egs", "monogs", "monogs-edi")


def run_grid(args: argparse.Namespace) -> pd.DataFrame:
    """Run (or resume) the benchmark's runs as sweeps and return one row per run."""
    methods = args.methods.split(",")
    ablation_seqs = args.ablation_seq or args.seq[:1]
    main = [m for m in methods if m in MAIN_METHODS]
    ablations = [m for m in methods if m not in MAIN_METHODS]
    grids = [(main, args.seq), (ablations, [s for s in args.seq if s in ablation_seqs])]
    rows: list[dict[str, object]] = []  # this invocation's runs only (not older runs)
    summaries = []
    for grid_methods, seqs in grids:
        if not grid_methods or not seqs:
            continue
        spec = SweepSpec(path=None, methods=tuple(grid_methods), sequences=tuple(seqs),
                         seeds=tuple(args.seeds), presets=(args.preset,),
                         devices=(args.device,), max_frames=args.max_frames,
                         options=dict(args.options), out=args.out,
                         local=LocalOptions(jobs=args.jobs, threads_per_job=None))
        report = run_sweep(spec, force=args.force, retry_failed=args.retry_failed,
                           status_only=args.status, say=print)
        summaries.append(report.summary)
        states = report.summary.set_index("run")
        rows += [table_row(r, str(states.loc[r.run_id, "state"]),
                         str(states.loc[r.run_id, "reason"] or ""), args.out)
                 for r in report.runs]
        rows += [{"sequence": seq, "method": m, "seed": seed,
                  "error": "pending: sequence not generated yet"}
                 for seq in report.ungenerated for m in grid_methods for seed in args.seeds]
    if summaries:  # one summary of both grids (each run_sweep wrote only its own)
        write_summary(args.out, pd.concat(summaries, ignore_index=True))
    return pd.DataFrame(rows)


def table_row(spec: RunSpec, state: str, reason: str, out: Path) -> dict[str, object]:
    """One table row: the run's metrics when the sweep reports it ``done`` for this
    configuration, else its state and reason in ``error`` (a stale or conflicting folder holds
    another configuration's numbers and is not read). Nothing is evaluated here: the sweep's
    worker evaluates every finished run."""
    # names from the spec: a run not started yet has no folder to read them from
    row: dict[str, object] = {"sequence": spec.sequence_name, "method": spec.method,
                              "seed": spec.seed}
    if state != "done":
        return {**row, "error": (f"{state}: {reason}" if reason else
                                 "pending: not started" if state == "pending" else state)[:80]}
    r = read_run_result(Path(spec.run_dir), out / "runs", spec.protocol, evaluate_missing=False)
    v = r.values
    row["method"] = r.method or spec.method  # the recorded name (not an import path)
    row |= {"ate_cm": 100 * v["ate"] if "ate" in v else None, "psnr_db": v.get("psnr"),
            "ssim": v.get("ssim"), "fps": v.get("fps"), "code": _code_label(r.code_revision)}
    if r.status not in ("ok", "incomplete"):
        row["error"] = f"{r.status}: {r.reason}"[:80]
    return row


def _code_label(rev: dict[str, Any] | None) -> str:
    """The commit a run was made with, as its first 7 hex digits (``+``: tracked files were
    modified), or ``?`` where the run folder does not record it."""
    return "?" if rev is None else rev["commit"][:7] + ("+" if rev.get("modified") else "")


def summarise_seeds(runs: pd.DataFrame) -> pd.DataFrame:
    """One row per (sequence, method) in first-seen order: the mean of every metric over the
    seeds that finished, ``<metric>_std`` columns, ``seeds`` = how many finished of how many
    asked, and ``error`` naming each seed that has not finished (with its state)."""
    metrics = [c for c in ("ate_cm", "psnr_db", "ssim", "fps") if c in runs]
    if runs["seed"].nunique() <= 1 or not metrics:
        return runs.drop(columns="seed")
    keys = ["sequence", "method"]
    grouped = runs.groupby(keys, sort=False)
    out = grouped[metrics].mean()
    for c in ("ate_cm", "psnr_db"):
        if c in metrics:
            out[f"{c}_std"] = grouped[c].std()
    finished = runs["ate_cm"].notna() if "ate_cm" in runs else pd.Series(False, runs.index)
    out["seeds"] = [f"{int(finished[g.index].sum())}/{len(g)}" for _, g in grouped]
    if "code" in runs:  # which commits the finished seeds ran with (rows may mix code)
        out["code"] = [", ".join(dict.fromkeys(g.loc[finished[g.index], "code"].dropna()))
                       or None for _, g in grouped]
    if "error" in runs:
        out["error"] = ["; ".join(f"seed {s}: {e}" for s, e in zip(g["seed"], g["error"],
                                                                    strict=True)
                                  if isinstance(e, str)) or None for _, g in grouped]
    return out.reset_index()


def ratio_lines(df: pd.DataFrame, unblurred: list[str], setting: str) -> list[str]:
    """Per-sequence ATE ratio and PSNR gain of egs over monogs, their mean over the blurred
    sequences, and the 10 % ATE rule on the unblurred ones. Each method's numbers are its mean
    over the seeds it finished; with several seeds each line says how many that was, since
    the two methods of a sequence may have finished different seeds so far."""
    if not {"egs", "monogs"} <= set(df["method"]) or "ate_cm" not in df:
        return []
    piv = df.pivot(index="sequence", columns="method", values=["ate_cm", "psnr_db"])
    ratio = (piv["ate_cm"]["egs"] / piv["ate_cm"]["monogs"]).dropna()
    gain = (piv["psnr_db"]["egs"] - piv["psnr_db"]["monogs"]).reindex(ratio.index)
    if ratio.empty:
        return ["no sequence has finished runs of both egs and monogs yet"]
    lines = []
    seeds = (df.set_index(["sequence", "method"])["seeds"] if "seeds" in df else None)
    for name in ratio.index:
        counts = ("" if seeds is None else
                  f" (seeds finished: egs {seeds[name, 'egs']}, monogs {seeds[name, 'monogs']})")
        lines.append(f"{name}: ATE(egs)/ATE(monogs) = {ratio[name]:.3f}, "
                     f"PSNR(egs) - PSNR(monogs) = {gain[name]:+.2f} dB{counts}")
    blurred = [n for n in ratio.index if n not in set(unblurred)]
    if blurred:
        lines.append(f"mean over the blurred sequences ({', '.join(blurred)}): ATE ratio "
                     f"{ratio[blurred].mean():.3f}, PSNR gain {gain[blurred].mean():+.2f} dB "
                     f"({setting})")
    for name in [n for n in ratio.index if n in set(unblurred)]:
        verdict = "met" if ratio[name] <= 1.1 else "NOT met"
        lines.append(f"unblurred {name}: ATE ratio {ratio[name]:.3f} (at most 1.10: {verdict})")
    return lines


def resample_seed_means(runs: pd.DataFrame, n_resamples: int,
                        rng: np.random.Generator) -> dict[tuple[str, str], np.ndarray]:
    """Bootstrap replicates of each (sequence, method)'s seed means: the finished seeds are
    drawn with replacement, as many as there are, ``n_resamples`` times. Returns, per cell, an
    array ``(n_resamples, 2)`` of (mean ATE cm, mean PSNR dB). Cells with fewer than two
    finished seeds are left out (one seed says nothing about the spread).

    A run's ATE and PSNR are drawn together (one index draw per replicate), which is why this
    is not ``scipy.stats.bootstrap``: it resamples each sample's values on their own."""
    done = runs.dropna(subset=["ate_cm", "psnr_db"])
    out = {}
    for (seq, method), cell in done.groupby(["sequence", "method"], sort=False):
        values = cell[["ate_cm", "psnr_db"]].to_numpy(dtype=np.float64)  # (seeds, 2)
        if len(values) < 2:
            continue
        draws = rng.integers(0, len(values), size=(n_resamples, len(values)))
        out[str(seq), str(method)] = values[draws].mean(axis=1)
    return out


def seed_intervals(runs: pd.DataFrame, unblurred: list[str], ablation_seqs: list[str],
                   confidence: float = 0.95, n_resamples: int = 20_000,
                   seed: int = 0) -> list[str]:
    """How far the seeds could move the summary: percentile-bootstrap intervals (seeds
    resampled within each sequence and method, independently) of the mean ATE ratio and PSNR
    gain of egs over monogs across the blurred sequences, and, on each ablation sequence, of
    every other method's mean ATE and PSNR minus egs's. Needs two or more finished seeds per
    cell; with three seeds a cell has only 10 distinct resamples and the bootstrap variance of
    a mean is (n - 1) / n times the usual estimate (too narrow), so the interval is a guide,
    not a test."""
    if "ate_cm" not in runs or "psnr_db" not in runs:
        return []
    means = resample_seed_means(runs, n_resamples, np.random.default_rng(seed))
    tails = [100 * (1 - confidence) / 2, 100 * (1 + confidence) / 2]
    label = f"{100 * confidence:.0f} % seed-bootstrap interval"

    def bounds(x: np.ndarray, fmt: str) -> str:
        lo, hi = np.percentile(x, tails)
        return f"[{lo:{fmt}}, {hi:{fmt}}]"

    lines = []
    sequences = list(dict.fromkeys(runs["sequence"]))
    blurred = [s for s in sequences if s not in set(unblurred)
               and (s, "egs") in means and (s, "monogs") in means]
    if blurred and len(blurred) == len([s for s in sequences if s not in set(unblurred)]):
        ratio = np.mean([means[s, "egs"][:, 0] / means[s, "monogs"][:, 0] for s in blurred],
                        axis=0)
        gain = np.mean([means[s, "egs"][:, 1] - means[s, "monogs"][:, 1] for s in blurred],
                       axis=0)
        lines.append(f"{label} of the mean over the blurred sequences: ATE ratio "
                     f"{bounds(ratio, '.3f')}, PSNR gain {bounds(gain, '+.2f')} dB")
    elif runs["seed"].nunique() > 1:
        lines.append(f"no {label} of the mean yet: it needs two finished seeds of egs and "
                     "monogs on every blurred sequence")
    for seq in ablation_seqs:
        if (seq, "egs") not in means:
            continue
        for (s, method), m in means.items():
            if s != seq or method in ("egs", "monogs"):
                continue
            diff = m - means[seq, "egs"]
            lines.append(f"{seq}: {method} - egs ({label}): ATE {bounds(diff[:, 0], '+.2f')} "
                         f"cm, PSNR {bounds(diff[:, 1], '+.2f')} dB")
    return lines


def report(runs: pd.DataFrame, unblurred: list[str], ablation_seqs: list[str],
           setting: str) -> tuple[pd.DataFrame, list[str]]:
    """Print the per-(sequence, method) table of ``runs`` and the summary lines; return both
    (the table from :func:`summarise_seeds`, the lines of :func:`ratio_lines` then
    :func:`seed_intervals`)."""
    df = summarise_seeds(runs)
    print(df.to_markdown(index=False, floatfmt=".3f"))
    summary = ratio_lines(df, unblurred, setting) + seed_intervals(runs, unblurred, ablation_seqs)
    for line in summary:
        print(line)
    return df, summary


def combine_runs(paths: list[Path]) -> pd.DataFrame:
    """The finished runs of several ``runs.csv`` files (this script's per-run output), one row
    per (sequence, method, seed). Raises :class:`EgsBenchError` naming the file when one cannot
    be read or lacks the columns, and when two files give one run different numbers."""
    key = ["sequence", "method", "seed"]
    frames = []
    for path in paths:
        try:
            frame = pd.read_csv(path, dtype={"code": str})
        except (OSError, ValueError) as exc:
            raise EgsBenchError(f"{path}: cannot read it as a runs.csv ({exc})") from exc
        missing = [c for c in (*key, "ate_cm", "psnr_db") if c not in frame]
        if missing:
            raise EgsBenchError(f"{path}: not a runs.csv of this benchmark "
                                f"(no column {', '.join(missing)})")
        frames.append(frame.dropna(subset=["ate_cm"]).assign(source=str(path)))
    runs = pd.concat(frames, ignore_index=True)
    values = [c for c in ("ate_cm", "psnr_db", "ssim") if c in runs]
    for (seq, method, seed), rows in runs.groupby(key, sort=False):
        if len(rows[values].round(6).drop_duplicates()) > 1:
            raise EgsBenchError(f"{seq}/{method}/seed{seed}: {' and '.join(rows['source'])} "
                                "give it different numbers")
    runs = runs.drop_duplicates(subset=key).drop(columns="source")
    return runs.drop(columns=[c for c in ("error",) if c in runs]).reset_index(drop=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seq", action="append", help="sequence folder or name")
    ap.add_argument("--from-runs", action="append", type=Path, default=[], metavar="RUNS_CSV",
                    help="start nothing: tabulate the runs.csv of earlier invocations together")
    ap.add_argument("--methods", default=",".join(DEFAULT_METHODS))
    ap.add_argument("--preset", default="cpu", choices=["cpu", "paper"])
    ap.add_argument("--device", default="cpu", choices=list(DEVICES))
    ap.add_argument("--seed", dest="seeds", type=int, action="append", default=None,
                    help="seed of every run (repeat for several: mean and std in the table)")
    ap.add_argument("--max-frames", type=int, default=None)
    ap.add_argument("--out", type=Path, default=Path("bench_out/slam"))
    ap.add_argument("--ablation-seq", action="append", default=None,
                    help="sequences that also get the ablation methods (default: the first "
                         "--seq); the others run egs and monogs only")
    ap.add_argument("--jobs", type=int, default=1,
                    help="runs in parallel (one torch thread each; FPS then reflects sharing)")
    ap.add_argument("--force", action="store_true",
                    help="rerun runs that finished earlier with the same configuration")
    ap.add_argument("--retry-failed", action="store_true",
                    help="rerun failed runs (finished ones are kept)")
    ap.add_argument("--status", action="store_true",
                    help="start nothing: tabulate the runs as they are")
    ap.add_argument("--set", dest="overrides", action="append", default=[],
                    metavar="KEY=VALUE", help="configuration override for every method")
    ap.add_argument("--unblurred", action="append", default=[],
                    help="sequences without blur: left out of the mean ratios, checked against "
                         "the 'not worse than monogs by more than 10 %% ATE' rule instead")
    args = ap.parse_args()
    if bool(args.seq) == bool(args.from_runs):
        ap.error("give --seq (run the benchmark) or --from-runs (tabulate earlier runs)")
    if args.from_runs:
        try:
            runs = combine_runs(args.from_runs)
        except EgsBenchError as exc:
            sys.exit(f"{Path(sys.argv[0]).name}: error: {exc}")
        sequences = list(dict.fromkeys(runs["sequence"]))
        report(runs, args.unblurred, args.ablation_seq or sequences[:1], "combined runs.csv files")
        return
    args.seeds = args.seeds or [0]
    for flag, values in (("--seed", args.seeds), ("--seq", args.seq),
                         ("--methods", args.methods.split(","))):
        twice = sorted({str(v) for v in values if values.count(v) > 1})
        if twice:
            ap.error(f"{flag} names {', '.join(twice)} more than once")
    outside = [s for s in args.ablation_seq or [] if s not in args.seq]
    if outside:
        ap.error(f"--ablation-seq {', '.join(outside)} is not among the --seq sequences")
    args.out = args.out.resolve()  # the sweep reports absolute run folders
    try:
        args.options = parse_overrides(args.overrides)
        if args.options and any(not isinstance(get_method(m), ConfiguredSlamMethod)
                                for m in args.methods.split(",")):
            ap.error("--set applies to built-in methods only")
        runs = run_grid(args)
    except EgsBenchError as exc:  # a bad --seq, method, --set or output: one line, no traceback
        sys.exit(f"{Path(sys.argv[0]).name}: error: {exc}")
    args.out.mkdir(parents=True, exist_ok=True)
    write_text_atomic(args.out / "runs.csv", runs.to_csv(index=False))
    df, summary = report(runs, args.unblurred, args.ablation_seq or args.seq[:1],
                         f"preset {args.preset}")
    write_text_atomic(args.out / "accuracy.csv", df.to_csv(index=False))
    write_text_atomic(args.out / "accuracy.md", df.to_markdown(index=False, floatfmt=".3f") + "\n")
    write_text_atomic(args.out / "accuracy_summary.txt", "".join(f"{x}\n" for x in summary))


if __name__ == "__main__":
    main()
