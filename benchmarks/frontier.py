"""The accuracy-per-work frontier: ATE, PSNR, SSIM and LPIPS against the rendering work per
frame, from finished run folders (BENCHMARKS.md "Accuracy per work").

Work is machine-independent (slam_stats.json's ``work`` section, egs_bench.render.work):
Gaussian-pixel blends per frame after frame 0, forward plus backward. A run's budget label is
the sweep setting in its folder name (``<method>__<setting>/seed<N>``; a ``_p<N>`` suffix names
a perturbation run of the same budget, ``runtime.perturbation``), else its preset. Each budget's
row is the mean and spread over its seeds and perturbations (the noise floor), per
``measured`` label (where and when the runs were made: another machine rounds differently, so
its runs are never averaged with these).

    python benchmarks/frontier.py collect SWEEP_DIR... --measured LABEL --out CSV \
        [--append | --overwrite]
    python benchmarks/frontier.py table CSV [--budgets b05,e1,...] [--measured LABEL]
    python benchmarks/frontier.py figure CSV --out PNG [--budgets ...] [--measured LABEL]
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import re
import statistics
import sys
from collections import defaultdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from egs_bench.fileio import write_text_atomic

COLUMNS = ("sequence", "method", "budget", "seed", "perturbation", "frames", "ate_cm",
           "psnr_db", "ssim", "lpips", "blends_m_per_frame", "pixels_m_per_frame",
           "cameras_per_frame", "gaussians", "keyframes", "s_per_frame_after_init", "measured")


def _budget(run_dir: Path, config: dict) -> str:
    name = run_dir.parent.name
    if "__" not in name:
        return str(config.get("preset", "?"))
    return re.sub(r"_p\d+$", "", name.split("__", 1)[1])


def run_row(run_dir: Path, measured: str) -> dict | None:
    """One CSV row of a finished, evaluated run folder (None when it lacks its metrics or work);
    ``measured``: where and when it ran."""
    import yaml

    metrics_path, stats_path = run_dir / "metrics.json", run_dir / "slam_stats.json"
    if not metrics_path.is_file() or not stats_path.is_file():
        return None
    metrics = json.loads(metrics_path.read_text())
    stats = json.loads(stats_path.read_text())
    work = stats.get("work")
    if not work:
        return None
    config = yaml.safe_load((run_dir / "config.yaml").read_text()) or {}
    mean = work["per_frame_after_init"]
    rendering, speed = metrics.get("rendering") or {}, metrics.get("speed") or {}
    blends = (mean["blends_fwd"] or 0) + (mean["blends_bwd"] or 0)
    after = speed.get("fps_after_init")
    return {
        "sequence": metrics["run"]["sequence"], "method": metrics["run"]["method"],
        "budget": _budget(run_dir, config), "seed": config.get("seed"),
        "perturbation": ((config.get("slam") or {}).get("runtime") or {}).get("perturbation", 0),
        "frames": stats["frames"], "ate_cm": round(100 * metrics["ate"]["rmse_m"], 3),
        "psnr_db": _round(rendering.get("psnr_db"), 2), "ssim": _round(rendering.get("ssim"), 3),
        "lpips": _round(rendering.get("lpips"), 3),
        "blends_m_per_frame": round(blends / 1e6, 2),
        "pixels_m_per_frame": round(mean["pixels"] / 1e6, 3),
        "cameras_per_frame": round(mean["cameras"], 1),
        "gaussians": stats["gaussians"], "keyframes": stats["keyframes"],
        "s_per_frame_after_init": _round(1 / after if after else None, 2),
        "measured": measured,
    }


def _round(value, digits: int):
    return None if value is None else round(float(value), digits)


def collect(roots: list[Path], out: Path, measured: str, append: bool = False) -> list[dict]:
    """Rows of every finished run under ``roots`` into ``out`` (after the rows ``out`` holds
    when ``append``); returns the new rows."""
    kept = read_rows(out) if append and out.is_file() else []
    rows = []
    for root in roots:
        for stats in sorted(root.rglob("slam_stats.json")):
            row = run_row(stats.parent, measured)
            if row is not None:
                rows.append(row)
    new = list(rows)
    rows = kept + rows
    rows.sort(key=lambda r: (r["sequence"], r["method"], float(r["blends_m_per_frame"]),
                             int(r["seed"]), int(r["perturbation"])))
    text = io.StringIO(newline="")
    writer = csv.DictWriter(text, fieldnames=COLUMNS, restval="")
    writer.writeheader()
    writer.writerows(rows)
    out.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(out, text.getvalue())
    return new


def read_rows(path: Path) -> list[dict]:
    with path.open() as f:
        return list(csv.DictReader(f))


def groups(rows: list[dict]) -> dict[tuple[str, str, str, str], list[dict]]:
    """Runs by (sequence, method, budget, measured)."""
    out: dict[tuple[str, str, str, str], list[dict]] = defaultdict(list)
    for r in rows:
        out[(r["sequence"], r["method"], r["budget"], r.get("measured") or "")].append(r)
    return out


def _spread(values: list[float], digits: int) -> str:
    if not values:
        return "n/a"
    mean = statistics.fmean(values)
    if len(values) == 1:
        return f"{mean:.{digits}f}"
    return f"{mean:.{digits}f} ± {(max(values) - min(values)) / 2:.{digits}f}"


def table(rows: list[dict]) -> str:
    """Markdown: per sequence, method, budget and measured label, mean ± half-range over its
    runs (seeds x perturbations)."""
    lines = ["| sequence | method | budget | runs | blends / frame (M) | ATE cm | PSNR dB | "
             "SSIM | LPIPS | Gaussians | s / frame | measured |",
             "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
    for (seq, method, budget, measured), rs in sorted(groups(rows).items(), key=lambda kv: (
            kv[0][0], kv[0][1], kv[0][3],
            statistics.fmean(float(r["blends_m_per_frame"]) for r in kv[1]))):
        def col(key: str, digits: int, rs: list[dict] = rs) -> str:
            return _spread([float(r[key]) for r in rs if r[key] not in ("", None)], digits)
        lines.append(f"| {seq} | {method} | {budget} | {len(rs)} | {col('blends_m_per_frame', 1)} "
                     f"| {col('ate_cm', 2)} | {col('psnr_db', 2)} | {col('ssim', 3)} | "
                     f"{col('lpips', 3)} | {col('gaussians', 0)} | "
                     f"{col('s_per_frame_after_init', 2)} | {measured} |")
    return "\n".join(lines)


def figure(rows: list[dict], out: Path) -> None:
    """ATE and PSNR against blends per frame (log scale), one colour per method and sequence,
    each point a budget's mean over its runs with their range (budgets are points, not a
    curve: they differ in more than one field)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    by_line: dict[tuple[str, str], list] = defaultdict(list)
    several = len({r.get("measured") or "" for r in rows}) > 1
    for (seq, method, budget, measured), rs in groups(rows).items():
        work = statistics.fmean(float(r["blends_m_per_frame"]) for r in rs)
        # the date tells apart the same budget measured on two machines
        label = f"{budget} ({measured.split(',')[0][5:]})" if several and measured else budget
        by_line[(seq, method)].append((work, label, rs))
    for (seq, method), points in sorted(by_line.items()):
        points.sort(key=lambda p: p[0])
        for ax, key in zip(axes, ("ate_cm", "psnr_db"), strict=True):
            xs = [p[0] for p in points]
            vals = [[float(r[key]) for r in p[2] if r[key]] for p in points]
            ys = [statistics.fmean(v) for v in vals]
            err = [[y - min(v) for y, v in zip(ys, vals, strict=True)],
                   [max(v) - y for y, v in zip(ys, vals, strict=True)]]
            ax.errorbar(xs, ys, yerr=err, marker="o" if method == "egs" else "s", capsize=3,
                        linestyle="none", label=f"{method} · {seq}")
            for x, y, p in zip(xs, ys, points, strict=True):
                ax.annotate(p[1], (x, y), textcoords="offset points", xytext=(4, 4), fontsize=7)
    for ax, label in zip(axes, ("ATE RMSE (cm)", "PSNR (dB)"), strict=True):
        ax.set_xscale("log")
        ax.set_xlabel("Gaussian-pixel blends per frame after frame 0 (millions, fwd + bwd)")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[1].legend(fontsize=7)
    fig.suptitle("Accuracy per work (mean and range over seeds and perturbations)")
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="cmd", required=True)
    c = sub.add_parser("collect")
    c.add_argument("roots", nargs="+", type=Path)
    c.add_argument("--measured", required=True,
                   help="where and when the runs were made, e.g. '2026-12-06, 2-core EPYC'")
    c.add_argument("--out", type=Path, required=True)
    mode = c.add_mutually_exclusive_group()
    mode.add_argument("--overwrite", action="store_true", help="replace an existing --out file")
    mode.add_argument("--append", action="store_true", help="add to an existing --out file")
    t = sub.add_parser("table")
    t.add_argument("csv", type=Path)
    t.add_argument("--budgets", help="comma-separated budgets to list (default: all)")
    t.add_argument("--measured", help="only the runs of this measured label")
    f = sub.add_parser("figure")
    f.add_argument("csv", type=Path)
    f.add_argument("--out", type=Path, required=True)
    f.add_argument("--overwrite", action="store_true", help="replace an existing --out file")
    f.add_argument("--measured", help="only the runs of this measured label")
    f.add_argument("--budgets", help="comma-separated budgets to plot (default: all)")
    args = parser.parse_args()
    if args.cmd in ("collect", "figure") and args.out.exists() and not (
            args.overwrite or getattr(args, "append", False)):
        parser.error(f"{args.out} exists; give --overwrite to replace it"
                     + (" or --append to add to it" if args.cmd == "collect" else ""))
    if args.cmd == "collect":
        new = collect(args.roots, args.out, args.measured, append=args.append)
        print(f"{len(new)} runs -> {args.out}")
        return
    rows = read_rows(args.csv)
    if args.measured:
        rows = [row for row in rows if row.get("measured") == args.measured]
    if args.budgets:
        keep = set(args.budgets.split(","))
        rows = [row for row in rows if row["budget"] in keep]
    if args.cmd == "table":
        print(table(rows))
    else:
        figure(rows, args.out)
        print(f"figure -> {args.out}")


if __name__ == "__main__":
    main()
