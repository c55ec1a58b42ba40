"""Group run results into table rows and cells: repeats of one experiment become mean +- std.

A *row* is a method with one set of settings (the run's configuration without its seed), and
whether its runs cover their whole sequences: runs that stop early are never mixed or ranked
with complete ones (they form ``[partial]`` rows). A *cell* is a row on one sequence and holds
every run of it (the seeds); its statistics are the mean, the sample standard deviation and the
number of evaluated runs.

When a method was run with several settings, each row is labelled with the configuration keys
that differ between them (``egs (loss.lambda_d=0.05)``), or with the name a sweep gave the settings.
A run whose settings could not be read (an unreadable ``config.yaml``) takes no part in that
comparison: it forms its own row, ``egs (settings unreadable)``, whose cells are footnoted.

:func:`results_frame` is the long-format table of the same runs, one row per run, labelled the
same way.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from egs_bench.eval.results import EVALUATED, METRICS, ResultSet, RunResult

if TYPE_CHECKING:
    import pandas as pd

MAX_LABEL_KEYS = 3
LOST = "L"
MISSING = "--"
UNREADABLE_SETTINGS = "settings unreadable"


@dataclass(frozen=True)
class RowKey:
    """One table row: a method with one set of settings, complete or partial runs."""

    method: str
    settings_key: str
    complete: bool
    label: str


@dataclass(frozen=True)
class Stat:
    """Mean, sample standard deviation (NaN for one value) and count of one metric, stored unit."""

    mean: float
    std: float
    n: int


@dataclass
class Cell:
    """All runs of one row on one sequence, with the statistics of their metric values."""

    runs: list[RunResult]
    stats: dict[str, Stat] = field(default_factory=dict)

    @property
    def evaluated(self) -> list[RunResult]:
        return [r for r in self.runs if r.status in EVALUATED]

    @property
    def marker(self) -> str:
        """``""`` when the cell has values, ``L`` when its runs lost tracking, else ``--``."""
        if self.evaluated:
            return ""
        return LOST if any(r.status == "tracking_lost" for r in self.runs) else MISSING


def _fmt_value(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def differing_keys(settings: Sequence[dict[str, Any]]) -> list[str]:
    """The keys whose values are not the same in all of ``settings`` (a key missing from some
    counts as differing), sorted."""
    keys = sorted(set().union(*(s.keys() for s in settings)))
    missing = object()
    return [k for k in keys if len({repr(s.get(k, missing)) for s in settings}) > 1]


def settings_labels(runs: Iterable[RunResult]) -> dict[tuple[str, str], str]:
    """``(method, settings_key)`` -> a short label of those settings (``""`` when the method has
    one set of settings only; :data:`UNREADABLE_SETTINGS` for runs whose settings are
    unknown, which are left out of the comparison)."""
    by_method: dict[str, dict[str, RunResult]] = {}
    out: dict[tuple[str, str], str] = {}
    for r in runs:
        if r.method is None:
            continue
        if r.settings_known:
            by_method.setdefault(r.method, {}).setdefault(r.settings_key, r)
        else:
            out[(r.method, r.settings_key)] = UNREADABLE_SETTINGS
    for method, variants in by_method.items():
        if len(variants) == 1:
            out[(method, next(iter(variants)))] = ""
            continue
        diff = differing_keys([r.settings for r in variants.values()])
        for key, r in variants.items():
            if r.settings_name:
                out[(method, key)] = r.settings_name
                continue
            parts = [f"{k.removeprefix('slam.')}={_fmt_value(r.settings.get(k, '-'))}"
                     for k in diff[:MAX_LABEL_KEYS]]
            if len(diff) > MAX_LABEL_KEYS:
                parts.append(f"+{len(diff) - MAX_LABEL_KEYS} more")
            out[(method, key)] = ", ".join(parts) or key
        counts = Counter(out[(method, k)] for k in variants)
        for key in variants:  # truncated labels can collide: make them unique with the hash
            if counts[out[(method, key)]] > 1:
                out[(method, key)] = f"{out[(method, key)]} #{key[:6]}"
    return out


def row_labels(runs: Iterable[RunResult]) -> dict[Path, str]:
    """Run folder -> settings label (see :func:`settings_labels`)."""
    runs = list(runs)
    labels = settings_labels(runs)
    return {r.path: labels.get((r.method, r.settings_key), "") for r in runs
            if r.method is not None}


def row_key(run: RunResult, labels: dict[tuple[str, str], str]) -> RowKey:
    """The row a run belongs to (its label includes the settings label and ``[partial]``)."""
    assert run.method is not None
    settings = labels.get((run.method, run.settings_key), "")
    label = f"{run.method} ({settings})" if settings else run.method
    if not run.complete:
        label += " [partial]"
    return RowKey(run.method, run.settings_key, run.complete, label)


def cell_stats(cell: Cell, metrics: Iterable[str]) -> dict[str, Stat]:
    """Mean / sample std / count of each metric over the cell's evaluated runs."""
    out = {}
    for key in metrics:
        vals = np.array([r.values[key] for r in cell.evaluated if key in r.values], dtype=float)
        if len(vals):
            std = float(vals.std(ddof=1)) if len(vals) > 1 else math.nan
            out[key] = Stat(float(vals.mean()), std, len(vals))
    return out


def group_runs(runs: Iterable[RunResult], metrics: Sequence[str]
               ) -> tuple[list[RowKey], list[str], dict[tuple[RowKey, str], Cell]]:
    """Rows (complete first, then by label), sequences (sorted) and cells of ``runs``.

    Runs without a method or sequence (unreadable ``run.yaml``) are left out; the caller
    reports them.
    """
    runs = [r for r in runs if r.method is not None and r.sequence is not None]
    labels = settings_labels(runs)
    cells: dict[tuple[RowKey, str], Cell] = {}
    for r in runs:
        cells.setdefault((row_key(r, labels), r.sequence or ""), Cell([])).runs.append(r)
    for cell in cells.values():
        cell.runs.sort(key=lambda r: (r.seed if r.seed is not None else -1, r.rel))
        cell.stats = cell_stats(cell, metrics)
    rows = sorted({k for k, _ in cells}, key=lambda k: (not k.complete, k.label))
    sequences = sorted({s for _, s in cells})
    return rows, sequences, cells


def cell_notes(row: RowKey, sequence: str, cell: Cell | None) -> list[str]:
    """Footnotes of one cell: missing, failed, lost, running, broken, partial, repeated seeds."""
    what = f"{row.label} on {sequence}"
    if cell is None:
        return [f"{MISSING}: no run of {row.label} on {sequence}"]
    notes = []
    several = len(cell.runs) > 1
    for r in cell.runs:
        who = f"{what} (seed {r.seed})" if several and r.seed is not None else what
        if r.status == "tracking_lost":
            notes.append(f"{LOST}: {who} lost tracking ({r.reason})")
        elif r.status == "failed":
            notes.append(f"{MISSING}: {who} failed ({r.reason})")
        elif r.status == "running":
            notes.append(f"{MISSING}: {who} is not finished ({r.reason})")
        elif r.status in ("broken", "not_evaluated"):
            notes.append(f"{MISSING}: {who}: {r.reason}")
    partial = Counter(r.reason for r in cell.runs if r.status == "incomplete")
    for reason, count in partial.items():
        runs = f" ({count} runs)" if count > 1 else ""
        notes.append(f"{what}: {reason}{runs}; never ranked against complete runs")
    if cell.evaluated and len(cell.evaluated) < len(cell.runs):
        notes.append(f"{what}: mean over {len(cell.evaluated)} of {len(cell.runs)} runs")
    seeds = Counter(r.seed for r in cell.runs if r.seed is not None)
    for seed, count in sorted(seeds.items()):
        if count > 1:
            notes.append(f"{what}: {count} runs share seed {seed}; all are counted")
    return notes


def results_frame(results: ResultSet, metrics: tuple[str, ...] | list[str] = tuple(METRICS)
                  ) -> pd.DataFrame:
    """Long-format table: one row per run, metric columns in stored units, a status column.

    Columns: ``method, settings, sequence, seed, status, frames_processed, frames_in_sequence``,
    one column per metric named with its unit (``ate_rmse_m``, ``psnr_db``, ``ssim``, ``lpips``,
    ``fps``), ``reason`` and ``run``. Metric columns are float (NaN where there is no value), so
    a tracking loss never turns a column into strings.
    """
    import pandas as pd

    labels = row_labels(results.runs)
    rows = []
    for r in results.runs:
        row: dict[str, object] = {
            "method": r.method, "settings": labels.get(r.path, ""), "sequence": r.sequence,
            "seed": r.seed, "status": r.status, "frames_processed": r.frames_processed,
            "frames_in_sequence": r.frames_in_sequence}
        for key in metrics:
            v = r.values.get(key) if r.status in EVALUATED else None
            row[METRICS[key].column] = math.nan if v is None else v
        row["reason"] = r.reason or ""
        row["run"] = r.rel
        rows.append(row)
    df = pd.DataFrame(rows)
    for col in ("seed", "frames_processed", "frames_in_sequence"):
        df[col] = df[col].astype("Int64")
    for key in metrics:
        df[METRICS[key].column] = df[METRICS[key].column].astype(float)
    return df
