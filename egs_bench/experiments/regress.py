"""Regression check: compare the results of runs with a committed baseline, metric by metric.

Both sides are reduced to one row per (method, settings, sequence, whether the runs cover the
whole sequence, the frames they cover) with the mean over the runs
(the ``csv-summary`` leaderboard format, :func:`egs_bench.eval.leaderboard.summary_frame`), read
from a runs folder or from such a CSV file. Rows are matched on all five: runs over 6 frames are
never compared with a baseline over 12 (the baseline's row is ``missing`` and says what the runs
covered). For every metric with a tolerance, the change is
measured in the metric's bad direction (ATE and LPIPS up, PSNR and SSIM down) and is a
regression when it exceeds ``max(abs, rel * |baseline|)``. A row of the baseline that is missing
from the runs, or whose runs failed or lost tracking, is a regression too; rows only in the
runs are listed as new. Improvements beyond the tolerance are listed as ``better`` (refresh the
baseline to lock them in). A check that would compare nothing fails: an unknown metric or one
without a tolerance is refused, and so is a baseline without a single value of the checked
metrics or with a cell that is not a number.

Tolerances are in the stored units of ``metrics.json`` (ATE in metres, PSNR in dB).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import yaml

from egs_bench.errors import ConfigError, InputError
from egs_bench.eval.protocols import DEFAULT_PROTOCOL
from egs_bench.eval.results import METRICS
from egs_bench.fileio import write_text_atomic

KEY = ["method", "settings", "sequence", "complete", "frames"]
VERDICTS = ("ok", "better", "REGRESSION", "missing", "new")


@dataclass(frozen=True)
class Tolerance:
    """Allowed worsening of a metric: ``max(abs, rel * |baseline|)`` in the stored unit."""

    abs: float = 0.0
    rel: float = 0.0

    def allowed(self, baseline: float) -> float:
        return max(self.abs, self.rel * abs(baseline))


#: Defaults for short CPU runs (deterministic on one machine; the margins absorb benign
#: numerical changes): ATE +25 % or +1 mm, PSNR -0.5 dB, SSIM -0.01, LPIPS +0.02. FPS is not
#: checked (machine load).
DEFAULT_TOLERANCES: dict[str, Tolerance] = {
    "ate": Tolerance(abs=0.001, rel=0.25),
    "psnr": Tolerance(abs=0.5),
    "ssim": Tolerance(abs=0.01),
    "lpips": Tolerance(abs=0.02),
}


def load_tolerances(path: str | Path | None) -> dict[str, Tolerance]:
    """Tolerances from a YAML file (``ate: {abs: 0.002, rel: 0.3}``; ``null`` disables a
    metric), on top of :data:`DEFAULT_TOLERANCES`.

    Raises:
        InputError: unreadable file, unknown metric or key, or a negative / non-numeric value.
    """
    out = dict(DEFAULT_TOLERANCES)
    if path is None:
        return out
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "tolerance file not found")
    try:
        data = yaml.safe_load(path.read_text()) or {}
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise InputError(path, f"not valid YAML ({exc})") from None
    if not isinstance(data, Mapping):
        raise InputError(path, "expected a mapping metric -> {abs, rel}")
    for key, value in data.items():
        if key not in METRICS:
            raise InputError(path, f"unknown metric {key!r}; choose from {', '.join(METRICS)}")
        if value is None:
            out.pop(key, None)
            continue
        if not isinstance(value, Mapping) or set(value) - {"abs", "rel"}:
            raise InputError(path, f"{key}: expected {{abs: X, rel: Y}}, found {value!r}")
        nums = {k: v for k, v in value.items()}
        for k, v in nums.items():
            if isinstance(v, bool) or not isinstance(v, int | float) or v < 0:
                raise InputError(path, f"{key}.{k} must be a number >= 0, found {v!r}")
        out[key] = Tolerance(float(nums.get("abs", 0.0)), float(nums.get("rel", 0.0)))
    return out


def summary_of(source: str | Path, protocol: str = DEFAULT_PROTOCOL,
               evaluate_missing: bool = True) -> pd.DataFrame:
    """The per-(method, settings, sequence) summary of a runs folder or a summary CSV file.

    Raises:
        InputError: missing source, or a CSV without the summary columns.
    """
    from egs_bench.eval.leaderboard import collect, summary_frame

    source = Path(source)
    if source.is_dir():
        return summary_frame(collect(source, protocol, tuple(METRICS), evaluate_missing))
    if not source.is_file():
        raise InputError(source, "not found (give a runs folder or a summary CSV)")
    try:
        df = pd.read_csv(source, keep_default_na=False, na_values=[""],
                         dtype={"settings": str, "method": str, "sequence": str})
    except (pd.errors.ParserError, UnicodeDecodeError, pd.errors.EmptyDataError) as exc:
        raise InputError(source, f"not a CSV file ({exc})") from None
    missing = [c for c in [*KEY, "status"] if c not in df.columns]
    if missing == ["frames"]:
        raise InputError(source, "has no 'frames' column (the frames each row's runs cover, "
                                 "recorded since regression checks match on them): refresh it "
                                 "with `egs-bench regress BASELINE RUNS --update`")
    if not missing and df["complete"].dtype != bool:
        missing = ["complete (True/False)"]
    if missing:
        raise InputError(source, f"not a results summary (no column {missing[0]!r}; write one "
                                 "with `egs-bench leaderboard RUNS --format csv-summary`)")
    df["settings"] = df["settings"].fillna("").astype(str)
    df["frames"] = df["frames"].fillna("").astype(str).str.removesuffix(".0")
    return _numbers(df, source)


def _numbers(df: pd.DataFrame, source: Path) -> pd.DataFrame:
    """``df`` with its count and mean/std columns as floats (an empty cell is NaN).

    Raises:
        InputError: a cell holds something else than a finite number (``abc``, ``nan``,
            ``inf``); the message names the line and the column.
    """
    for col in df.columns:
        if not (col.endswith(("_mean", "_std")) or col.startswith("n_")):
            continue
        values = pd.to_numeric(df[col], errors="coerce").astype(float)
        bad = df[col].notna().to_numpy() & ~np.isfinite(values.to_numpy())
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise InputError(source, f"line {i + 2}: {col} is '{df[col].iloc[i]}', not a "
                                     "number (leave the cell empty for no value)")
        df[col] = values
    return df


def metrics_to_check(metrics: Sequence[str] | None,
                     tolerances: Mapping[str, Tolerance]) -> list[str]:
    """The metrics a check compares: ``metrics``, or all with a tolerance when ``None``.

    Raises:
        ConfigError: an unknown metric, a metric without a tolerance (FPS by default, or one a
            tolerance file set to null), or nothing to check.
    """
    if metrics is None:
        keys = [k for k in tolerances if k in METRICS]
    else:
        keys = list(dict.fromkeys(metrics))
        for k in keys:
            if k not in METRICS:
                raise ConfigError(f"unknown metric {k!r} to check; choose from "
                                  f"{', '.join(METRICS)}")
            if k not in tolerances:
                raise ConfigError(f"metric {k!r} has no tolerance, so it cannot be checked; "
                                  f"give one in a tolerance file ({k}: {{abs: X, rel: Y}})")
    if not keys:
        raise ConfigError("no metric to check (every tolerance is disabled or none was named)")
    return keys


def _mean(row: pd.Series | None, key: str) -> float:
    if row is None:
        return math.nan
    v = row.get(f"{METRICS[key].column}_mean", math.nan)
    try:
        return float(v)
    except (TypeError, ValueError):
        return math.nan


def _siblings(ident: tuple, rows: Mapping[tuple, pd.Series]) -> str:
    """What ``rows`` hold for the method, settings and sequence of ``ident`` under other
    coverage: ``"6 frames (incomplete)"``, ...; empty when nothing."""
    found = [f"{other[4] or 'unknown'} frames ({r['status']})" for other, r in rows.items()
             if other[:3] == ident[:3] and other != ident]
    return ", ".join(found)


def compare(baseline: pd.DataFrame, current: pd.DataFrame,
            tolerances: Mapping[str, Tolerance] = DEFAULT_TOLERANCES,
            metrics: Sequence[str] | None = None) -> pd.DataFrame:
    """One row per (method, settings, sequence, coverage, metric) checked: baseline and current
    means, the change in the bad direction (positive = worse), the allowed change and a verdict
    (stored units). A baseline row without a current row of the same frames is ``missing``,
    with a note naming the frames the runs did cover.

    Raises:
        ConfigError: see :func:`metrics_to_check`.
    """
    keys = metrics_to_check(metrics, tolerances)
    base = {tuple(r[c] for c in KEY): r for _, r in baseline.iterrows()}
    cur = {tuple(r[c] for c in KEY): r for _, r in current.iterrows()}
    rows: list[dict[str, Any]] = []
    for ident in list(base) + [i for i in cur if i not in base]:
        b, c = base.get(ident), cur.get(ident)
        for key in keys:
            bv, cv = _mean(b, key), _mean(c, key)
            if math.isnan(bv) and (c is None or math.isnan(cv)):
                continue
            spec, tol = METRICS[key], tolerances[key]
            row = dict(zip(KEY, ident, strict=True), metric=key, baseline=bv, current=cv,
                       worse_by=math.nan, allowed=math.nan, verdict="ok", note="")
            if b is None or math.isnan(bv):
                row["verdict"] = "new"
                other = _siblings(ident, base) if b is None else ""
                row["note"] = f"the baseline has {other}" if other else ""
            elif c is None or math.isnan(cv):
                row["verdict"] = "missing" if c is None else "REGRESSION"
                other = _siblings(ident, cur) if c is None else ""
                row["note"] = (f"no run over {ident[4] or 'unknown'} frames; the runs cover "
                               f"{other}" if other else "no run" if c is None
                               else f"runs {c['status']}")
            else:
                worse = (bv - cv) if spec.higher_is_better else (cv - bv)
                allowed = tol.allowed(bv)
                row.update(worse_by=worse, allowed=allowed)
                if worse > allowed + 1e-12:
                    row["verdict"] = "REGRESSION"
                elif -worse > allowed + 1e-12:
                    row["verdict"] = "better"
                if c is not None and c.get("status") not in ("ok", "incomplete") and \
                        b is not None and b.get("status") in ("ok", "incomplete"):
                    row["verdict"] = "REGRESSION"
                    row["note"] = f"runs {c['status']}"
            rows.append(row)
    return pd.DataFrame(rows, columns=[*KEY, "metric", "baseline", "current", "worse_by",
                                       "allowed", "verdict", "note"])


def check(baseline: str | Path, runs: str | Path, *, tolerances: str | Path | None = None,
          metrics: Sequence[str] | None = None,
          protocol: str = DEFAULT_PROTOCOL) -> pd.DataFrame:
    """The regression table of ``runs`` against ``baseline`` (see :func:`compare`).

    Args:
        baseline, runs: summary CSV files or runs folders (:func:`summary_of`).
        tolerances: YAML tolerance file (:func:`load_tolerances`), or the defaults.
        metrics: the metrics to check (default: those with a tolerance).
        protocol: evaluation protocol of the numbers.

    Raises:
        ConfigError: a metric that cannot be checked (:func:`metrics_to_check`).
        InputError: a bad file, or a baseline without one value of the checked metrics (a
            check against it would pass while comparing nothing).
    """
    tol = load_tolerances(tolerances)
    keys = metrics_to_check(metrics, tol)
    base = summary_of(baseline, protocol)
    if not any(not math.isnan(_mean(r, k)) for _, r in base.iterrows() for k in keys):
        raise InputError(baseline, f"holds no value of {', '.join(keys)} for any row: "
                                   "nothing to check against")
    return compare(base, summary_of(runs, protocol), tol, keys)


def failed(table: pd.DataFrame) -> bool:
    """Whether the comparison holds a regression or a missing result, or checks nothing."""
    checked = table["verdict"] != "new"
    return bool(table["verdict"].isin(["REGRESSION", "missing"]).any() or not checked.any())


def render(table: pd.DataFrame) -> str:
    """Markdown table in display units (ATE cm) and a verdict line."""
    shown = table.copy()
    for col in ("baseline", "current", "worse_by", "allowed"):
        shown[col] = [
            "" if math.isnan(v) else
            f"{v * METRICS[m].scale:.{METRICS[m].decimals + 2}f}"
            for v, m in zip(table[col], table["metric"], strict=True)]
    shown["metric"] = [METRICS[m].label for m in table["metric"]]
    shown = shown.rename(columns={"worse_by": "worse by"})
    counts = table["verdict"].value_counts()
    bad = int(counts.get("REGRESSION", 0) + counts.get("missing", 0))
    checked = len(table) - int(counts.get("new", 0))  # a new row compares nothing
    verdict = (f"FAILED: {bad} regression(s) in {checked} checks" if bad
               else "FAILED: nothing compared with the baseline" if not checked
               else f"passed: {checked} checks, no regression")
    extra = ", ".join(f"{n} {v}" for v, n in counts.items() if v != "ok")
    if extra:
        verdict += f" ({extra})"
    return shown.to_markdown(index=False, disable_numparse=True) + f"\n\n{verdict}.\n"


def update_baseline(runs: str | Path, baseline: str | Path,
                    protocol: str = DEFAULT_PROTOCOL) -> pd.DataFrame:
    """Write the summary of ``runs`` to the baseline CSV (atomically) and return it.

    Raises:
        OutputError: ``baseline`` is a folder or not a text file.
        InputError: ``runs`` has no run folder.
    """
    baseline = Path(baseline)
    from egs_bench.outputs import prepare_output

    # --update rewrites the baseline by design; the shared rules still refuse a folder, a
    # non-text file or an input
    prepare_output(baseline, "text", overwrite=True, inputs=[runs], option="BASELINE")
    df = summary_of(runs, protocol)
    write_text_atomic(baseline, df.to_csv(index=False, lineterminator="\n"))
    return df
