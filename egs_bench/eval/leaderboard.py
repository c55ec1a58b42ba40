"""Leaderboards from a folder of run folders: Markdown, LaTeX (booktabs) or CSV.

One row per method and one column per (sequence, metric), plus the average over sequences,
like the tables of GS-SLAM papers (``by="sequence"``); ``by="method"`` puts sequences in rows.
The best value of each comparison is bold and the second underlined, in the metric's direction
(lower is better for ATE and LPIPS). Ranks use the displayed (rounded) values, ties share a rank.
Missing, failed or unevaluable runs show ``--``; runs that lost tracking show ``L``; footnotes
say why. A bad run never stops the table: it becomes a footnote.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence as Seq
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from egs_bench.errors import ConfigError, EgsBenchError, InputError
from egs_bench.eval.protocols import DEFAULT_PROTOCOL
from egs_bench.runs.folder import RunFolder, find_runs

FORMATS = ("md", "latex", "csv")
LAYOUTS = ("sequence", "method")
MISSING = "--"
LOST = "L"
AVERAGE = "Avg."


@dataclass(frozen=True)
class MetricSpec:
    """A leaderboard metric: label, unit-conversion from metrics.json, direction, decimals."""

    key: str
    label: str
    higher_is_better: bool
    decimals: int


METRICS: dict[str, MetricSpec] = {
    "ate": MetricSpec("ate", "ATE [cm]", False, 2),
    "psnr": MetricSpec("psnr", "PSNR [dB]", True, 2),
    "ssim": MetricSpec("ssim", "SSIM", True, 3),
    "lpips": MetricSpec("lpips", "LPIPS", False, 3),
    "fps": MetricSpec("fps", "FPS", True, 2),
}
DEFAULT_METRICS = ("ate", "psnr", "ssim", "lpips")


def _metric_value(metrics: dict, key: str) -> float | None:
    ate, rendering, speed = metrics.get("ate"), metrics.get("rendering"), metrics.get("speed")
    value = None
    if key == "ate" and ate:
        value = ate.get("rmse_m")
        value = None if value is None else 100.0 * value
    elif key in ("psnr", "ssim", "lpips") and rendering:
        value = rendering.get({"psnr": "psnr_db"}.get(key, key))
    elif key == "fps" and speed:
        value = speed.get("fps")
    return None if value is None or not math.isfinite(value) else float(value)


@dataclass
class Leaderboard:
    """Collected results: ``values[(method, sequence)][metric]`` plus per-cell states.

    Attributes:
        methods, sequences: sorted names.
        metrics: metric keys shown (columns with no value at all are dropped).
        values: numbers per (method, sequence) and metric.
        lost: (method, sequence) pairs whose run lost tracking.
        notes: footnotes (one per problem: missing run, failed run, unreadable files).
        protocol: protocol name the numbers were computed under.
    """

    methods: list[str]
    sequences: list[str]
    metrics: list[str]
    values: dict[tuple[str, str], dict[str, float]]
    lost: set[tuple[str, str]] = field(default_factory=set)
    notes: list[str] = field(default_factory=list)
    protocol: str = DEFAULT_PROTOCOL


def collect(runs_root: str | Path, protocol: str = DEFAULT_PROTOCOL,
            metrics: Seq[str] = DEFAULT_METRICS, evaluate_missing: bool = True) -> Leaderboard:
    """Read every run folder under ``runs_root`` into a :class:`Leaderboard`.

    Runs whose ``metrics.json`` is missing (or was computed under another protocol) are
    evaluated when ``evaluate_missing`` (a missing ``metrics.json`` is written; another
    protocol's file is left alone). Problems with single runs become footnotes.

    Raises:
        InputError: ``runs_root`` is missing or holds no run folder.
        ConfigError: unknown metric.
    """
    from egs_bench.eval.evaluate import evaluate_run, read_metrics

    for key in metrics:
        if key not in METRICS:
            raise ConfigError(f"unknown metric {key!r}; choose from {', '.join(METRICS)}")
    paths = find_runs(runs_root)
    root = Path(runs_root)
    if not paths:
        raise InputError(root, "holds no run folders (no run.yaml found)")
    values: dict[tuple[str, str], dict[str, float]] = {}
    lost: set[tuple[str, str]] = set()
    noted: set[tuple[str, str]] = set()  # cells that already have a footnote
    notes: list[str] = []
    methods: set[str] = set()
    sequences: set[str] = set()
    for path in paths:
        rel = path.relative_to(root) if path != root else Path(".")
        try:
            run = RunFolder.open(path)
        except EgsBenchError as exc:
            notes.append(f"{rel}: skipped ({exc})")
            continue
        cell = (run.method, run.sequence_name)
        what = f"{run.method} on {run.sequence_name}"
        methods.add(run.method)
        sequences.add(run.sequence_name)
        if cell in values or cell in lost or cell in noted:
            notes.append(f"{rel}: another run of {what} came first (sorted by path); ignored")
            continue
        try:
            status = run.read_status()
            if status.state == "failed":
                if status.tracking_lost:
                    lost.add(cell)
                    notes.append(f"{LOST}: {what} lost tracking ({status.reason})")
                else:
                    noted.add(cell)
                    notes.append(f"{MISSING}: {what} failed ({status.reason})")
                continue
            if status.state != "done":
                noted.add(cell)
                notes.append(f"{MISSING}: {what} is still {status.state}")
                continue
            data = None
            if run.metrics_path.is_file():
                data = read_metrics(path)
                if data.get("protocol", {}).get("name") != protocol:
                    data = None
            if data is None:
                if not evaluate_missing:
                    noted.add(cell)
                    notes.append(f"{MISSING}: {what} not evaluated under protocol {protocol!r}")
                    continue
                data = evaluate_run(path, protocol, write=not run.metrics_path.is_file())
        except EgsBenchError as exc:
            noted.add(cell)
            notes.append(f"{MISSING}: {what}: {exc}")
            continue
        values[cell] = {k: v for k in metrics if (v := _metric_value(data, k)) is not None}
        cov = data.get("coverage") or {}
        if cov and cov.get("frames_processed", 0) < cov.get("frames_in_sequence", 0):
            notes.append(f"{what}: covers only {cov['frames_processed']} of "
                         f"{cov['frames_in_sequence']} frames")
    shown = [k for k in metrics if any(k in v for v in values.values())] or list(metrics)
    methods_sorted, sequences_sorted = sorted(methods), sorted(sequences)
    for m in methods_sorted:
        for s in sequences_sorted:
            if (m, s) not in values and (m, s) not in lost and (m, s) not in noted:
                notes.append(f"{MISSING}: no run of {m} on {s}")
    return Leaderboard(methods_sorted, sequences_sorted, shown, values, lost, notes, protocol)


def to_frame(board: Leaderboard, by: str = "sequence") -> tuple[pd.DataFrame, pd.DataFrame]:
    """Numeric table and its cell markers.

    Returns:
        ``(numbers, markers)``: ``numbers`` float DataFrame (NaN where no value) with
        MultiIndex columns ``(group, metric_key)``; ``markers`` the same shape with ``""``,
        ``"--"`` or ``"L"``. ``by="sequence"``: rows are methods, groups are sequences plus
        ``Avg.`` (mean over all sequences, only when a method has all of them). ``by="method"``:
        rows are sequences plus ``Avg.``, groups are methods.
    """
    if by not in LAYOUTS:
        raise ConfigError(f"unknown layout {by!r}; choose one of {', '.join(LAYOUTS)}")
    avg: dict[tuple[str, str], float] = {}
    for m in board.methods:
        for k in board.metrics:
            vals = [board.values.get((m, s), {}).get(k) for s in board.sequences]
            if vals and all(v is not None for v in vals):
                avg[(m, k)] = float(np.mean(vals))

    def cell(m: str, s: str, k: str) -> tuple[float, str]:
        if s == AVERAGE:
            v = avg.get((m, k))
            return (v, "") if v is not None else (math.nan, MISSING)
        v = board.values.get((m, s), {}).get(k)
        if v is not None:
            return v, ""
        return math.nan, LOST if (m, s) in board.lost else MISSING

    seq_groups = board.sequences + ([AVERAGE] if len(board.sequences) > 1 else [])
    if by == "sequence":
        rows, groups = board.methods, seq_groups
        get = lambda r, g, k: cell(r, g, k)  # noqa: E731
    else:
        rows, groups = seq_groups, board.methods
        get = lambda r, g, k: cell(g, r, k)  # noqa: E731
    columns = pd.MultiIndex.from_tuples([(g, k) for g in groups for k in board.metrics])
    numbers = pd.DataFrame(math.nan, index=pd.Index(rows), columns=columns, dtype=float)
    markers = pd.DataFrame("", index=pd.Index(rows), columns=columns, dtype=object)
    for r in rows:
        for g in groups:
            for k in board.metrics:
                v, mk = get(r, g, k)
                numbers.loc[r, (g, k)] = v
                markers.loc[r, (g, k)] = mk
    return numbers, markers


def _ranks(numbers: pd.DataFrame, by: str) -> pd.DataFrame:
    """1 for best, 2 for second, 0 otherwise, comparing methods (rounded values, dense ranks)."""
    ranks = pd.DataFrame(0, index=numbers.index, columns=numbers.columns, dtype=int)

    def rank_values(values: pd.Series, key: str) -> pd.Series:
        spec = METRICS[key]
        r = values.round(spec.decimals).rank(method="dense", ascending=not spec.higher_is_better)
        return r.where(r <= 2, 0).fillna(0).astype(int)

    if by == "sequence":  # methods are rows: rank down each column
        for col in numbers.columns:
            ranks[col] = rank_values(numbers[col], col[1])
    else:  # methods are column groups: rank across the groups, per row and metric
        for row in numbers.index:
            for key in numbers.columns.get_level_values(1).unique():
                cols = [c for c in numbers.columns if c[1] == key]
                ranks.loc[row, cols] = rank_values(numbers.loc[row, cols], key).to_numpy()
    return ranks


def _format_cells(numbers: pd.DataFrame, markers: pd.DataFrame, ranks: pd.DataFrame,
                  best: str, second: str) -> pd.DataFrame:
    out = pd.DataFrame("", index=numbers.index, columns=numbers.columns, dtype=object)
    for col in numbers.columns:
        spec = METRICS[col[1]]
        for row in numbers.index:
            v = numbers.loc[row, col]
            if math.isnan(v):
                out.loc[row, col] = markers.loc[row, col]
                continue
            text = f"{v:.{spec.decimals}f}"
            rank = ranks.loc[row, col]
            out.loc[row, col] = best.format(text) if rank == 1 else (
                second.format(text) if rank == 2 else text)
    return out


def _header(key: str, arrows: tuple[str, str]) -> str:
    spec = METRICS[key]
    return f"{spec.label} {arrows[0] if spec.higher_is_better else arrows[1]}"


def _legend(board: Leaderboard, quote: str = "`") -> list[str]:
    lines = [f"Protocol {quote}{board.protocol}{quote}. Best in bold, second underlined. "
             f"{MISSING}: no result; {LOST}: tracking lost."]
    return lines + sorted(set(board.notes), key=board.notes.index)


def render_markdown(board: Leaderboard, by: str = "sequence") -> str:
    """GitHub Markdown table (underline as ``<u>``) followed by numbered footnotes."""
    numbers, markers = to_frame(board, by)
    cells = _format_cells(numbers, markers, _ranks(numbers, by), "**{}**", "<u>{}</u>")
    cells.columns = [f"{g} {_header(k, ('↑', '↓'))}" for g, k in numbers.columns]
    first = "Method" if by == "sequence" else "Sequence"
    cells.index.name = first
    table = cells.reset_index().to_markdown(index=False, disable_numparse=True,
                                             colalign=["left"] + ["center"] * len(cells.columns))
    notes = "\n".join(f"{i}. {n}" if i else n for i, n in enumerate(_legend(board)))
    return f"{table}\n\n{notes}\n"


_LATEX_SPECIAL = {"\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#",
                  "_": r"\_", "{": r"\{", "}": r"\}", "~": r"\textasciitilde{}",
                  "^": r"\textasciicircum{}"}


def _latex_escape(text: str) -> str:
    return re.sub(r"[\\&%$#_{}~^]", lambda m: _LATEX_SPECIAL[m.group(0)], text)


def render_latex(board: Leaderboard, by: str = "sequence",
                 caption: str = "Results.", label: str = "tab:results") -> str:
    """A ``table`` environment with booktabs rules (needs ``\\usepackage{booktabs}``)."""
    numbers, markers = to_frame(board, by)
    cells = _format_cells(numbers, markers, _ranks(numbers, by), r"\textbf{{{}}}",
                          r"\underline{{{}}}")
    groups = list(dict.fromkeys(numbers.columns.get_level_values(0)))
    keys = board.metrics
    n = len(keys)
    lines = [r"\begin{table}", r"\centering", rf"\caption{{{_latex_escape(caption)}}}",
             rf"\label{{{label}}}", r"\begin{tabular}{l" + "c" * (len(groups) * n) + "}",
             r"\toprule"]
    first = "Method" if by == "sequence" else "Sequence"
    lines.append(" & ".join([""] + [rf"\multicolumn{{{n}}}{{c}}{{{_latex_escape(g)}}}"
                                    for g in groups]) + r" \\")
    rules = [rf"\cmidrule(lr){{{2 + i * n}-{1 + (i + 1) * n}}}" for i in range(len(groups))]
    lines.append(" ".join(rules))
    heads = [_latex_escape(METRICS[k].label) + (r" $\uparrow$" if METRICS[k].higher_is_better
                                                 else r" $\downarrow$") for k in keys]
    lines.append(" & ".join([first] + heads * len(groups)) + r" \\")
    lines.append(r"\midrule")
    for row in cells.index:
        vals = [cells.loc[row, (g, k)] for g in groups for k in keys]
        lines.append(" & ".join([_latex_escape(str(row))] + [str(v) for v in vals]) + r" \\")
    lines.append(r"\bottomrule")
    lines.append(r"\end{tabular}")
    notes = _legend(board, quote="")
    lines.append(r"\par\smallskip\footnotesize " + r" \\ ".join(_latex_escape(n) for n in notes))
    lines.append(r"\end{table}")
    return "\n".join(lines) + "\n"


def render_csv(board: Leaderboard, by: str = "sequence") -> str:
    """CSV with one header row ``group/metric``; empty where missing, ``L`` where lost."""
    numbers, markers = to_frame(board, by)
    out = pd.DataFrame("", index=numbers.index, columns=numbers.columns, dtype=object)
    for col in numbers.columns:
        for row in numbers.index:
            v = numbers.loc[row, col]
            out.loc[row, col] = repr(float(v)) if not math.isnan(v) else (
                LOST if markers.loc[row, col] == LOST else "")
    out.columns = [f"{g}/{k}" for g, k in numbers.columns]
    out.index.name = "method" if by == "sequence" else "sequence"
    return out.to_csv(lineterminator="\n")


def leaderboard(runs_root: str | Path, fmt: str = "md", by: str = "sequence",
                protocol: str = DEFAULT_PROTOCOL, metrics: Seq[str] = DEFAULT_METRICS,
                evaluate_missing: bool = True) -> str:
    """Collect the runs under ``runs_root`` and render the table in ``fmt`` (md/latex/csv)."""
    if fmt not in FORMATS:
        raise ConfigError(f"unknown format {fmt!r}; choose one of {', '.join(FORMATS)}")
    if by not in LAYOUTS:
        raise ConfigError(f"unknown layout {by!r}; choose one of {', '.join(LAYOUTS)}")
    board = collect(runs_root, protocol, metrics, evaluate_missing)
    if fmt == "md":
        return render_markdown(board, by)
    if fmt == "latex":
        return render_latex(board, by, caption=f"Results (protocol {protocol}).")
    return render_csv(board, by)
