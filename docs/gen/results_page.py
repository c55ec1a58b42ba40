"""The Results page, generated from the run-results CSVs committed in ``docs/notes/``.

Every ``*.csv`` there needs an entry in ``docs/notes/results_manifest.yaml`` saying when, where
and with which command its rows were measured (the manifest's header lists the fields). For each
CSV the page shows one row per configuration (the entry's ``group_by`` columns): every metric
as mean +- sample standard deviation over the configuration's runs (seeds), and their count n.
No number on the page is typed by hand: all come from the CSVs, dates and machines from the
manifest or from the CSV's own columns.

Run ``python docs/gen/results_page.py [NOTES_DIR]`` to print the page; ``make docs`` builds it
into the site.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import pandas as pd
from tabulate import tabulate

from egs_bench.errors import InputError
from egs_bench.fileio import read_yaml_mapping

MANIFEST = "results_manifest.yaml"
#: metric column -> (heading, decimals)
METRICS = {"ate_cm": ("ATE cm", 2), "psnr_db": ("PSNR dB", 2), "ssim": ("SSIM", 3),
           "lpips": ("LPIPS", 3), "fps": ("FPS", 3)}
REQUIRED = ("title", "date", "machine", "command", "group_by")


def read_manifest(notes: Path) -> dict[str, dict[str, Any]]:
    """The manifest's entries by CSV name, each checked for the required fields.

    Raises:
        InputError: the manifest is missing, not a YAML mapping, or an entry lacks a field.
    """
    path = notes / MANIFEST
    manifest = read_yaml_mapping(path, "results manifest")
    for name, entry in manifest.items():
        missing = [f for f in REQUIRED if not isinstance(entry, dict) or f not in entry]
        if missing:
            raise InputError(path, f"entry {name!r} lacks {', '.join(missing)}")
    return manifest


def _stated(value: Any, rows: pd.DataFrame, csv: Path, field: str) -> str:
    """A manifest field's text: as written, or ``{column: NAME}``'s distinct values."""
    if not isinstance(value, dict):
        return " ".join(str(value).split())
    column = value.get("column")
    if column not in rows.columns:
        raise InputError(csv, f"has no column {column!r} (the manifest's {field})")
    values = sorted({str(v) for v in rows[column].dropna()})
    if field == "date" and len(values) > 1:
        return f"{values[0]} to {values[-1]}"
    return ", ".join(values) or "none recorded"


def _mean_std(values: pd.Series, decimals: int) -> str:
    values = values.dropna()
    if values.empty:
        return ""
    if len(values) == 1:
        return f"{values.iloc[0]:.{decimals}f}"
    return f"{values.mean():.{decimals}f} ± {values.std(ddof=1):.{decimals}f}"


def summary(rows: pd.DataFrame, group_by: list[str], metrics: list[str]) -> pd.DataFrame:
    """One row per configuration, in the CSV's order: the ``group_by`` values, n, and each
    metric as ``"mean ± std"`` (``"value"`` for one run, ``""`` for none)."""
    out = []
    for key, group in rows.groupby(group_by, sort=False, dropna=False):
        keys = key if isinstance(key, tuple) else (key,)
        record: dict[str, Any] = {col: ("" if pd.isna(v) else v)
                                  for col, v in zip(group_by, keys, strict=True)}
        record["n"] = len(group)
        if "seed" in group.columns:
            record["seeds"] = ", ".join(str(s) for s in sorted(group["seed"]))
        for metric in metrics:
            heading, decimals = METRICS.get(metric, (metric, 3))
            record[heading] = _mean_std(group[metric], decimals)
        out.append(record)
    return pd.DataFrame(out)


def csv_section(csv: Path, entry: dict[str, Any]) -> str:
    """The page section of one CSV.

    Raises:
        InputError: the CSV cannot be read or lacks a column the entry names.
    """
    try:
        rows = pd.read_csv(csv)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise InputError(csv, f"not a readable CSV table ({' '.join(str(exc).split())})") \
            from None
    group_by = list(entry["group_by"])
    metrics = list(entry.get("metrics") or [m for m in METRICS if m in rows.columns])
    where = dict(entry.get("where") or {})
    missing = [c for c in [*group_by, *metrics, *where] if c not in rows.columns]
    if missing:
        raise InputError(csv, f"has no column {', '.join(map(repr, missing))} (named in "
                              f"{MANIFEST})")
    for column, value in where.items():
        rows = rows[rows[column].astype(str) == str(value)]
    lines = [f"## {entry['title']}", "",
             f"- **date:** {_stated(entry['date'], rows, csv, 'date')}",
             f"- **machine:** {_stated(entry['machine'], rows, csv, 'machine')}",
             f"- **command:** `{_stated(entry['command'], rows, csv, 'command')}`",
             f"- **rows:** [`{csv.name}`](notes/{csv.name})"
             + (f", those with {', '.join(f'{k} = {v}' for k, v in where.items())}"
                if where else ""),
             ""]
    if entry.get("note"):
        lines += [" ".join(str(entry["note"]).split()), ""]
    if rows.empty:
        lines += ["No runs recorded yet.", ""]
    else:
        table = summary(rows, group_by, metrics)
        lines += [tabulate(table, headers="keys", tablefmt="github", showindex=False,
                           disable_numparse=True), ""]
    return "\n".join(lines)


def render(notes: Path) -> str:
    """The Results page (Markdown) from the CSVs and the manifest in ``notes``.

    Raises:
        InputError: a CSV without a manifest entry, or a bad manifest or CSV.
    """
    manifest = read_manifest(notes)
    csvs = sorted(notes.glob("*.csv"))
    unlisted = [c.name for c in csvs if c.name not in manifest]
    if unlisted:
        raise InputError(notes / MANIFEST, f"no entry for {', '.join(unlisted)} (say when, "
                                           "where and how its rows were measured)")
    present = {c.name for c in csvs}
    sections = [csv_section(notes / name, entry) for name, entry in manifest.items()
                if name in present]
    intro = ["# Results", "",
             "Generated when the site is built from the run tables committed in `docs/notes/` "
             f"and their entries in `docs/notes/{MANIFEST}` (date, machine, command). Each row "
             "is one configuration: its metrics as mean ± standard deviation over its runs "
             "(n, one per seed; a single run shows its value). Other machines give slightly "
             "different trajectories, so compare against the spread, not the last digit.", ""]
    return "\n".join(intro + sections)


def main(argv: list[str]) -> int:
    """Print the page for the notes folder ``argv[0]`` (default: this repository's)."""
    notes = Path(argv[0]) if argv else Path(__file__).resolve().parents[1] / "notes"
    try:
        print(render(notes))
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 3
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
