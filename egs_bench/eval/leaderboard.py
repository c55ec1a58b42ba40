"""Leaderboards from a folder of run folders: Markdown, LaTeX (booktabs) or CSV.

Runs are grouped by (method, settings, sequence) (:mod:`egs_bench.eval.grouping`): repeats with
different seeds give ``mean ± std`` with the number of runs shown where it differs from the
rest. ``by="sequence"`` makes one row per method/settings and one column group per sequence plus
the average over sequences (given only when a row has every sequence), like the tables of
GS-SLAM papers; ``by="method"`` puts sequences in rows. The best mean of each comparison is bold
and the second underlined, in the metric's direction (lower is better for ATE and LPIPS), ranked
on the displayed rounded values, ties sharing a rank. Runs that cover fewer frames than their
sequence form their own ``[partial]`` rows that never compete with complete rows (only among
themselves, in a column without complete values). Missing, failed or unreadable
runs show ``--``, runs that lost tracking ``L``, and a footnote says why: a bad run folder
never stops the table.

CSV output is long-format (one row per run, units in the column names, numeric columns stay
numeric, a ``status`` column); ``csv-summary`` has one row per (method, settings, sequence)
with ``<metric>_mean``, ``<metric>_std`` and the run counts.
"""

from __future__ import annotations

import math
from collections.abc import Sequence as Seq
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal, get_args

import numpy as np
import pandas as pd

from egs_bench.errors import ConfigError
from egs_bench.eval.grouping import (
    LOST,
    MISSING,
    Cell,
    RowKey,
    Stat,
    cell_notes,
    group_runs,
    results_frame,
)
from egs_bench.eval.protocols import DEFAULT_PROTOCOL
from egs_bench.eval.results import (
    DEFAULT_METRICS,
    METRICS,
    ResultSet,
    collect_results,
)
from egs_bench.eval.tables import (
    TableWidth,
    common_n,
    dense_ranks,
    estimate_width_pt,
    format_stat,
    header,
    latex_escape,
    slug,
    wrap_latex_table,
)

BoardFormat = Literal["md", "latex", "csv", "csv-summary"]
#: What the rows are: one per sequence (methods as columns) or one per method.
BoardLayout = Literal["sequence", "method"]
FORMATS: tuple[BoardFormat, ...] = get_args(BoardFormat)
LAYOUTS: tuple[BoardLayout, ...] = get_args(BoardLayout)
AVERAGE = "Avg."

__all__ = ["AVERAGE", "DEFAULT_METRICS", "FORMATS", "LAYOUTS", "LOST", "METRICS", "MISSING",
           "Leaderboard", "build", "collect", "leaderboard", "render_csv", "render_csv_summary",
           "render_latex", "render_markdown", "to_frame"]


@dataclass
class Leaderboard:
    """Grouped results.

    Attributes:
        rows: table rows (method + settings, complete rows first).
        sequences: sorted sequence names.
        metrics: metric keys shown (metrics with no value at all are dropped).
        cells: the runs and statistics per (row, sequence).
        notes: footnotes (unreadable folders, missing/failed/lost runs, partial coverage).
        protocol: protocol name the numbers were computed under.
        results: the per-run results the board was built from.
    """

    rows: list[RowKey]
    sequences: list[str]
    metrics: list[str]
    cells: dict[tuple[RowKey, str], Cell]
    notes: list[str] = field(default_factory=list)
    protocol: str = DEFAULT_PROTOCOL
    results: ResultSet | None = None

    def stat(self, row: RowKey, sequence: str, key: str) -> Stat | None:
        cell = self.cells.get((row, sequence))
        return None if cell is None else cell.stats.get(key)

    def marker(self, row: RowKey, sequence: str) -> str:
        cell = self.cells.get((row, sequence))
        return MISSING if cell is None else cell.marker

    def average(self, row: RowKey, key: str) -> Stat | None:
        """Mean over the sequences of a row's means (``None`` unless it has every sequence);
        a derived value (``n == 0``: no spread, no count)."""
        stats = [self.stat(row, s, key) for s in self.sequences]
        present = [s for s in stats if s is not None]
        if not stats or len(present) < len(stats):
            return None
        return Stat(float(np.mean([s.mean for s in present])), math.nan, 0)


def _check_metrics(metrics: Seq[str]) -> None:
    for key in metrics:
        if key not in METRICS:
            raise ConfigError(f"unknown metric {key!r}; choose from {', '.join(METRICS)}")


def build(results: ResultSet, metrics: Seq[str] = DEFAULT_METRICS) -> Leaderboard:
    """Group ``results`` into a :class:`Leaderboard` with its footnotes."""
    _check_metrics(metrics)
    rows, sequences, cells = group_runs(results.runs, metrics)
    notes = [f"{r.rel}: skipped ({r.reason})" for r in results.runs
             if r.method is None or r.sequence is None]
    for row in rows:
        for s in sequences:
            notes.extend(cell_notes(row, s, cells.get((row, s))))
    shown = [k for k in metrics if any(k in c.stats for c in cells.values())] or list(metrics)
    return Leaderboard(rows, sequences, shown, cells, list(dict.fromkeys(notes)),
                       results.protocol, results)


def collect(runs_root: str | Path, protocol: str = DEFAULT_PROTOCOL,
            metrics: Seq[str] = DEFAULT_METRICS, evaluate_missing: bool = True) -> Leaderboard:
    """Read every run folder under ``runs_root`` and group it (see :func:`build`).

    Raises:
        InputError: ``runs_root`` is missing or holds no run folder.
        ConfigError: unknown metric.
    """
    _check_metrics(metrics)
    return build(collect_results(runs_root, protocol, evaluate_missing), metrics)


@dataclass
class TableData:
    """A board laid out as frames with MultiIndex columns ``(group, metric)``.

    ``mean``/``std`` are in stored units (NaN where no value), ``n`` the run counts, ``marker``
    ``""``/``"--"``/``"L"``, ``ranked`` False for rows that must not be ranked (partial runs).
    """

    mean: pd.DataFrame
    std: pd.DataFrame
    n: pd.DataFrame
    marker: pd.DataFrame
    ranked: pd.Series


def to_frame(board: Leaderboard, by: BoardLayout = "sequence") -> TableData:
    """Lay out ``board``: ``by="sequence"`` rows are methods (labels), groups are sequences plus
    ``Avg.``; ``by="method"`` rows are sequences plus ``Avg.``, groups are methods."""
    if by not in LAYOUTS:
        raise ConfigError(f"unknown layout {by!r}; choose one of {', '.join(LAYOUTS)}")
    seq_groups = board.sequences + ([AVERAGE] if len(board.sequences) > 1 else [])
    labels = [r.label for r in board.rows]
    if by == "sequence":
        index, groups = labels, seq_groups
    else:
        index, groups = seq_groups, labels
    columns = pd.MultiIndex.from_tuples([(g, k) for g in groups for k in board.metrics])
    mean = pd.DataFrame(math.nan, index=pd.Index(index), columns=columns, dtype=float)
    std = mean.copy()
    n = pd.DataFrame(0, index=pd.Index(index), columns=columns, dtype=int)
    marker = pd.DataFrame("", index=pd.Index(index), columns=columns, dtype=object)
    ranked = pd.Series(True, index=pd.Index(labels))
    for row in board.rows:
        ranked[row.label] = row.complete
        for s in seq_groups:
            for k in board.metrics:
                if s == AVERAGE:
                    st, mk = board.average(row, k), MISSING
                else:
                    st, mk = board.stat(row, s, k), board.marker(row, s) or MISSING
                at = (row.label, (s, k)) if by == "sequence" else (s, (row.label, k))
                if st is None:
                    marker.loc[at[0], at[1]] = mk
                else:
                    mean.loc[at[0], at[1]] = st.mean
                    std.loc[at[0], at[1]] = st.std
                    n.loc[at[0], at[1]] = st.n
    return TableData(mean, std, n, marker, ranked)


def rank_cells(data: TableData, by: BoardLayout) -> pd.DataFrame:
    """1 best, 2 second, 0 otherwise; partial rows never compete with complete ones."""
    mean = data.mean.copy()
    ranks = pd.DataFrame(0, index=mean.index, columns=mean.columns, dtype=int)
    if by == "sequence":  # rows are methods: rank down each column
        full = data.ranked.reindex(mean.index).to_numpy()
        for col in mean.columns:
            ranks[col] = dense_ranks(_competing(mean[col], full), col[1])
    else:  # methods are column groups: rank across the groups, per row and metric
        for row in mean.index:
            for key in mean.columns.get_level_values(1).unique():
                cols = [c for c in mean.columns if c[1] == key]
                full = np.array([bool(data.ranked[c[0]]) for c in cols])
                values = _competing(mean.loc[row, cols], full)
                ranks.loc[row, cols] = dense_ranks(values, key).to_numpy()
    return ranks


def _competing(values: pd.Series, complete: np.ndarray) -> pd.Series:
    """Values that compete for a rank: complete rows' only, unless none has a value (then the
    partial rows compete among themselves)."""
    full = values.where(complete)
    return full if full.notna().any() else values


def _cells(data: TableData, by: BoardLayout, style: str) -> tuple[pd.DataFrame, int]:
    ranks = rank_cells(data, by)
    usual = common_n(data.n.to_numpy().ravel())
    out = pd.DataFrame("", index=data.mean.index, columns=data.mean.columns, dtype=object)
    for col in data.mean.columns:
        for row in data.mean.index:
            v = data.mean.loc[row, col]
            if math.isnan(v):
                out.loc[row, col] = data.marker.loc[row, col]
                continue
            stat = Stat(float(v), float(data.std.loc[row, col]), int(data.n.loc[row, col]))
            out.loc[row, col] = format_stat(stat, col[1], int(ranks.loc[row, col]), style, usual)
    return out, usual


def _legend(board: Leaderboard, usual_n: int, quote: str = "`", pm: str = "±") -> list[str]:
    spread = (f" Cells: mean {pm} std over {usual_n} runs (seeds) unless (n=k) says otherwise."
              if usual_n > 1 else "")
    lines = [f"Protocol {quote}{board.protocol}{quote}. Best in bold, second underlined."
             f"{spread} {MISSING}: no result; {LOST}: tracking lost."]
    return lines + board.notes


def render_markdown(board: Leaderboard, by: BoardLayout = "sequence") -> str:
    """GitHub Markdown table (underline as ``<u>``) followed by numbered footnotes."""
    data = to_frame(board, by)
    cells, usual = _cells(data, by, "md")
    cells.columns = [f"{g} {header(k, 'md')}" for g, k in data.mean.columns]
    cells.index.name = "Method" if by == "sequence" else "Sequence"
    table = cells.reset_index().to_markdown(index=False, disable_numparse=True,
                                             colalign=["left"] + ["center"] * len(cells.columns))
    notes = "\n".join(f"{i}. {n}" if i else n for i, n in enumerate(_legend(board, usual)))
    return f"{table}\n\n{notes}\n"


def render_latex(board: Leaderboard, by: BoardLayout = "sequence", caption: str | None = None,
                 label: str | None = None, width: TableWidth = "auto", notes: bool = True) -> str:
    """A booktabs table in a float (needs ``\\usepackage{booktabs,graphicx}``).

    Args:
        caption: caption text (plain text, escaped here); default names the protocol.
        label: ``\\label`` key; ``None`` writes no label.
        width: ``auto``, ``natural``, ``column`` or ``page`` (see
            :func:`egs_bench.eval.tables.wrap_latex_table`).
        notes: print the legend and footnotes under the table.
    """
    data = to_frame(board, by)
    cells, usual = _cells(data, by, "latex")
    groups = list(dict.fromkeys(data.mean.columns.get_level_values(0)))
    keys = board.metrics
    n = len(keys)
    first = "Method" if by == "sequence" else "Sequence"
    tab = [r"\begin{tabular}{l" + "c" * (len(groups) * n) + "}", r"\toprule",
           " & ".join([""] + [rf"\multicolumn{{{n}}}{{c}}{{{latex_escape(g)}}}"
                              for g in groups]) + r" \\",
           " ".join(rf"\cmidrule(lr){{{2 + i * n}-{1 + (i + 1) * n}}}" for i in range(len(groups))),
           " & ".join([first] + [header(k, "latex") for k in keys] * len(groups)) + r" \\",
           r"\midrule"]
    body = []
    for row in cells.index:
        body.append([latex_escape(str(row))] + [str(cells.loc[row, (g, k)]) for g in groups
                                                for k in keys])
        tab.append(" & ".join(body[-1]) + r" \\")
    tab += [r"\bottomrule", r"\end{tabular}"]
    heads = [[first] + [header(k, "latex") for k in keys] * len(groups)]
    legend = [latex_escape(t).replace("PLUSMINUS", r"$\pm$")
              for t in _legend(board, usual, quote="", pm="PLUSMINUS")] if notes else []
    return wrap_latex_table(tab, caption=latex_escape(caption or
                                                      f"Results (protocol {board.protocol})."),
                            label=label, width=width,
                            est_width_pt=estimate_width_pt(heads + body), notes=legend)


def render_csv(board: Leaderboard, by: BoardLayout = "sequence") -> str:
    """Long-format CSV: one row per run (see :func:`egs_bench.eval.grouping.results_frame`)."""
    assert board.results is not None
    df = results_frame(board.results, board.metrics)
    return df.to_csv(index=False, lineterminator="\n")


def summary_frame(board: Leaderboard) -> pd.DataFrame:
    """One row per (method, settings, sequence) with the frames its runs cover, run counts, a
    status and mean/std columns in stored units (``ate_rmse_m_mean``, ``ate_rmse_m_std``, ...)."""
    rows = []
    for row in board.rows:
        settings = row.label[len(row.method):].removesuffix(" [partial]").strip()
        settings = settings[1:-1] if settings.startswith("(") else settings
        for s in board.sequences:
            cell = board.cells.get((row, s))
            if cell is None:
                continue
            counts = {st: sum(r.status == st for r in cell.runs)
                      for st in ("tracking_lost", "failed")}
            status = "ok" if len(cell.evaluated) == len(cell.runs) else (
                "tracking_lost" if cell.marker == LOST else (
                    "failed" if not cell.evaluated else "mixed"))
            if status == "ok" and not row.complete:
                status = "incomplete"
            # the frames the runs cover ("6/12" when they differ, "" when unknown), so that a
            # regression check never compares results over different frames
            frames = sorted({r.frames_processed for r in cell.runs
                             if r.frames_processed is not None})
            rec = {"method": row.method, "settings": settings, "sequence": s,
                   "complete": row.complete, "frames": "/".join(map(str, frames)),
                   "status": status, "n_runs": len(cell.runs),
                   "n_evaluated": len(cell.evaluated), "n_tracking_lost": counts["tracking_lost"],
                   "n_failed": len(cell.runs) - len(cell.evaluated) - counts["tracking_lost"]}
            for k in board.metrics:
                st = cell.stats.get(k)
                col = METRICS[k].column
                rec[f"{col}_mean"] = st.mean if st else math.nan
                rec[f"{col}_std"] = st.std if st else math.nan
            rows.append(rec)
    return pd.DataFrame(rows)


def render_csv_summary(board: Leaderboard, by: BoardLayout = "sequence") -> str:
    """CSV of :func:`summary_frame`."""
    return summary_frame(board).to_csv(index=False, lineterminator="\n")


def leaderboard(runs_root: str | Path, fmt: BoardFormat = "md", by: BoardLayout = "sequence",
                protocol: str = DEFAULT_PROTOCOL, metrics: Seq[str] = DEFAULT_METRICS,
                evaluate_missing: bool = True, caption: str | None = None,
                label: str | None = None, width: TableWidth = "auto") -> str:
    """Collect the runs under ``runs_root`` and render the table in ``fmt``.

    Args:
        fmt: ``md``, ``latex``, ``csv`` (one row per run) or ``csv-summary`` (one row per
            method/settings/sequence).
        caption, label, width: LaTeX options (see :func:`render_latex`); the default label is
            ``tab:<runs_root folder name>``.
    """
    if fmt not in FORMATS:
        raise ConfigError(f"unknown format {fmt!r}; choose one of {', '.join(FORMATS)}")
    if by not in LAYOUTS:
        raise ConfigError(f"unknown layout {by!r}; choose one of {', '.join(LAYOUTS)}")
    board = collect(runs_root, protocol, metrics, evaluate_missing)
    if fmt == "md":
        return render_markdown(board, by)
    if fmt == "latex":
        name = Path(runs_root).resolve().name
        return render_latex(board, by, caption=caption,
                            label=label if label is not None else f"tab:{slug(name)}",
                            width=width)
    if fmt == "csv":
        return render_csv(board, by)
    return render_csv_summary(board, by)
