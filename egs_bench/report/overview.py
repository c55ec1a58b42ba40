"""The overview page's content: leaderboards as HTML-ready cells, the runs table with the
sweep's axes, the flagged runs and the provenance.

Cells carry the text shown and a ``sort`` value (the displayed number; empty where there is
none) that the page's script sorts by. Ranks (best bold) come from the leaderboard's own rule
(:mod:`egs_bench.eval.leaderboard`: partial rows never compete with complete ones).
"""

from __future__ import annotations

import datetime as _dt
import math
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

from egs_bench import __version__
from egs_bench.eval.grouping import RowKey, differing_keys
from egs_bench.eval.leaderboard import AVERAGE, Leaderboard, rank_cells, to_frame
from egs_bench.eval.results import EVALUATED, METRICS
from egs_bench.eval.tables import common_n, header
from egs_bench.provenance import code_revision
from egs_bench.report.collect import ReportData, RunRecord

#: Metrics of the runs table (stored units; shown in the leaderboards' units).
RUN_METRICS = ("ate", "psnr", "ssim", "lpips", "fps")
#: The sweep axes a page can filter by (``data-<axis>`` attributes of the rows).
AXES = ("method", "sequence", "seed", "settings")


@dataclass(frozen=True)
class HtmlCell:
    """One table cell: ``text`` shown, ``sort`` key (number as text, or ``""``), ``best`` bold,
    ``group`` the sequence of a leaderboard column (for the sequence filter)."""

    text: str
    sort: str = ""
    best: bool = False
    group: str | None = None


@dataclass
class HtmlTable:
    """A sortable table: header cells, rows of cells, and per row its axis values, the page
    its first cell links to (relative to the report folder) and whether it is flagged."""

    heads: list[HtmlCell]
    rows: list[list[HtmlCell]] = field(default_factory=list)
    axes: list[dict[str, str]] = field(default_factory=list)
    links: list[str | None] = field(default_factory=list)
    flags: list[bool] = field(default_factory=list)


def metric_text(key: str, value: float | None) -> tuple[str, str]:
    """A stored value in the displayed unit and decimals, and its sort key; ``("", "")`` for
    none."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "", ""
    spec = METRICS[key]
    shown = f"{value * spec.scale:.{spec.decimals}f}"
    return shown, shown


def settings_columns(runs: list[RunRecord]) -> list[str]:
    """Settings keys that vary between the runs of one method (the sweep's settings axes:
    each becomes a column); keys that only tell methods apart are left out."""
    by_method: dict[str, dict[str, dict[str, Any]]] = {}
    for r in runs:
        if r.result.method is not None and r.result.settings_known:
            by_method.setdefault(r.result.method, {})[r.result.settings_key] = r.result.settings
    keys: list[str] = []
    for variants in by_method.values():
        if len(variants) > 1:
            keys += [k for k in differing_keys(list(variants.values())) if k not in keys]
    return sorted(keys)


def setting_label(key: str) -> str:
    return key.removeprefix("slam.")


Labels = dict[tuple[str, str], str]


def _axis_values(r: RunRecord, labels: Labels) -> dict[str, str]:
    """The run's value on each axis; ``settings`` is the label a sweep or the leaderboard
    gives its settings (:func:`egs_bench.eval.grouping.settings_labels`)."""
    res = r.result
    return {"method": res.method or "", "sequence": res.sequence or "",
            "seed": "" if res.seed is None else str(res.seed),
            "settings": labels.get((res.method or "", res.settings_key), "")}


def _row_settings(board: Leaderboard, row: RowKey) -> dict[str, Any]:
    for (key, _), cell in board.cells.items():
        if key == row and cell.runs:
            return cell.runs[0].settings
    return {}


def leaderboard_table(board: Leaderboard, columns: list[str], labels: Labels) -> HtmlTable:
    """Rows = method (+ settings) rows of ``board``; one column per setting in ``columns``,
    then per sequence (and ``Avg.`` over several) one column per metric: mean ± std over the
    seeds, best bold, ``(n=k)`` where a cell has another number of runs than most."""
    data = to_frame(board, "sequence")
    ranks = rank_cells(data, "sequence")
    usual = common_n(data.n.to_numpy().ravel())
    heads = [HtmlCell("Method")] + [HtmlCell(setting_label(k)) for k in columns]
    for group, key in data.mean.columns:
        heads.append(HtmlCell(f"{group} {header(key, 'md')}",
                              group=None if group == AVERAGE else group))
    table = HtmlTable(heads)
    for row in board.rows:
        settings = _row_settings(board, row)
        cells = [HtmlCell(row.label, row.label)]
        cells += [HtmlCell(str(settings.get(k, "")), str(settings.get(k, ""))) for k in columns]
        for col in data.mean.columns:
            group, key = col
            mean = float(data.mean.loc[row.label, col])
            if math.isnan(mean):
                cells.append(HtmlCell(str(data.marker.loc[row.label, col]), "",
                                      group=None if group == AVERAGE else group))
                continue
            shown, sort = metric_text(key, mean)
            n = int(data.n.loc[row.label, col])
            spec = METRICS[key]
            if n >= 2:
                shown += f" ± {float(data.std.loc[row.label, col]) * spec.scale:.{spec.decimals}f}"
            if n and n != usual:
                shown += f" (n={n})"
            cells.append(HtmlCell(shown, sort, best=int(ranks.loc[row.label, col]) == 1,
                                  group=None if group == AVERAGE else group))
        table.rows.append(cells)
        table.axes.append({"method": row.method,
                           "settings": labels.get((row.method, row.settings_key), "")})
        table.links.append(None)
        table.flags.append(False)
    return table


def runs_table(data: ReportData, columns: list[str], labels: Labels,
               flagged_only: bool = False) -> HtmlTable:
    """One row per run: identity, the settings columns, status (with the reason for a flagged
    run), metrics under the first protocol, frames covered; linked to the run's page."""
    heads = [HtmlCell(h) for h in ("Run", "Method", "Sequence", "Seed")]
    heads += [HtmlCell(setting_label(k)) for k in columns]
    heads += [HtmlCell("Status"), HtmlCell("Reason")]
    if not flagged_only:
        heads += [HtmlCell(header(k, "md")) for k in RUN_METRICS] + [HtmlCell("Frames")]
    table = HtmlTable(heads)
    for r in data.runs:
        if flagged_only and not r.flagged:
            continue
        res = r.result
        seed = "" if res.seed is None else str(res.seed)
        cells = [HtmlCell(res.rel, res.rel), HtmlCell(res.method or "?", res.method or ""),
                 HtmlCell(res.sequence or "?", res.sequence or ""), HtmlCell(seed, seed)]
        cells += [HtmlCell(str(res.settings.get(k, "")), str(res.settings.get(k, "")))
                  for k in columns]
        cells += [HtmlCell(res.status, res.status), HtmlCell(res.reason or "", res.reason or "")]
        if not flagged_only:
            for key in RUN_METRICS:
                value = res.values.get(key) if res.status in EVALUATED else None
                cells.append(HtmlCell(*metric_text(key, value)))
            frames = (f"{res.frames_processed}/{res.frames_in_sequence}"
                      if res.frames_processed is not None else "")
            cells.append(HtmlCell(frames, str(res.frames_processed or "")))
        table.rows.append(cells)
        table.axes.append(_axis_values(r, labels))
        table.links.append(f"runs/{r.page}.html")
        table.flags.append(r.flagged)
    return table


def axis_choices(data: ReportData, labels: Labels) -> dict[str, list[str]]:
    """Each axis's values over the runs; only axes with two or more values (filters)."""
    values: dict[str, set[str]] = {a: set() for a in AXES}
    for r in data.runs:
        for axis, value in _axis_values(r, labels).items():
            if value:
                values[axis].add(value)
    return {a: sorted(v, key=_natural) for a, v in values.items() if len(v) > 1}


def _natural(text: str) -> tuple[int, float, str]:
    try:
        return 0, float(text), ""
    except ValueError:
        return 1, 0.0, text


def _counted(values: list[str]) -> str:
    counts = Counter(values)
    if len(counts) == 1:
        return next(iter(counts))
    return ", ".join(f"{v} ({n} runs)" for v, n in sorted(counts.items()))


def _revision_text(rev: dict[str, Any] | None) -> str:
    if not rev:
        return "not recorded"
    return str(rev["commit"])[:12] + (" + local changes" if rev.get("modified") else "")


def provenance(data: ReportData) -> list[tuple[str, str]]:
    """``(label, text)`` pairs: what made the runs (code revisions, egs-bench versions,
    machines, dates, presets, devices, seeds) and what made the report."""
    runs = data.runs
    hosts = [r.status.host or "unknown" for r in runs if r.status is not None]
    dates = sorted(r.status.updated_utc for r in runs if r.status is not None
                   and r.status.updated_utc)
    seeds = sorted({r.result.seed for r in runs if r.result.seed is not None})
    now = _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M UTC")
    items = [
        ("Source", f"{data.source} ({data.kind}, {len(runs)} runs)"),
        ("Code revision (runs)", _counted([_revision_text(r.result.code_revision)
                                           for r in runs])),
        ("egs-bench version (runs)", _counted([str(r.info.get("egs_bench_version", "unknown"))
                                               for r in runs])),
        ("Machine", _counted(hosts) if hosts else "unknown"),
        ("Run dates", f"{dates[0]} to {dates[-1]}" if len(dates) > 1 else
         (dates[0] if dates else "unknown")),
        ("Preset", _counted([r.preset or "not recorded" for r in runs])),
        ("Device", _counted([r.device or "not recorded" for r in runs])),
        ("Seeds", ", ".join(map(str, seeds)) or "not recorded"),
        ("Protocols", ", ".join(data.protocols)),
        ("Report", f"written {now} by egs-bench {__version__} "
                   f"(code {_revision_text(code_revision())})"),
    ]
    return items
