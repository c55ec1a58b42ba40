"""The EGS-SLAM paper's table layouts from a sweep, as LaTeX (booktabs) and Markdown.

=====================  ==================================================================
``ate``                Tab. II / IV-style tracking table: sequences in rows (plus Avg.),
                       one column per method, ATE [cm]
``rendering``          Tab. I-style rendering table: per method a block of PSNR / SSIM /
                       LPIPS rows, sequences in columns plus Avg. and the rendering FPS
``ablation_events``    Tab. III-style: check-mark columns *Event Tracking* / *Event Mapping*
                       read from each run's configuration, ATE / PSNR / SSIM / LPIPS per
                       sequence
``ablation_crf``       Tab. V-style: *w/o CRF* / *w CRF* rows, ATE per sequence
``edi``                Tab. VI-style: MonoGS, MonoGS+EDI and ours, ATE / PSNR / LPIPS per
                       sequence (made only when ``monogs-edi`` runs exist)
=====================  ==================================================================

Ablation rows are found from the configurations, not from method names: a row belongs to an
ablation when its settings equal the full method's (``egs``) except for the ablated keys. Cells
hold ``mean ± std`` over the seeds with the run count where it differs; the best value of each
comparison is bold, the second underlined. Runs covering fewer frames than their sequence are
never ranked against complete runs (when every run of a comparison is partial, e.g. a sweep with
``max_frames``, they are ranked among themselves and the caption says so).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from egs_bench.eval.grouping import LOST, MISSING, RowKey, Stat
from egs_bench.eval.leaderboard import Leaderboard, build
from egs_bench.eval.protocols import DEFAULT_PROTOCOL
from egs_bench.eval.results import collect_results
from egs_bench.eval.tables import (
    TableWidth,
    common_n,
    dense_ranks,
    estimate_width_pt,
    format_stat,
    header,
    latex_escape,
    wrap_latex_table,
)

TABLES = ("ate", "rendering", "ablation_events", "ablation_crf", "edi")
CHECK, CROSS = "✓", "✗"
_LATEX_SYMBOLS = {CHECK: r"$\checkmark$", CROSS: r"$\times$"}
# configuration switches of the ablations (found in a run's settings by their field name, so
# both config.yaml layouts work: slam.method.crf and the older flat slam.crf)
EVENT_FIELDS = ("event_tracking", "event_mapping")
CRF_FIELD = "crf"
EDI_METHODS = ("monogs", "monogs-edi")


@dataclass(frozen=True)
class Column:
    """A value column: its group header (``""`` for none), its metric (``""``: the row's) and a
    header text replacing the metric's (``""``: the metric's label with its arrow)."""

    group: str
    key: str
    title: str = ""


@dataclass
class PaperTable:
    """A table in the paper's style, independent of the output format.

    Attributes:
        name: file stem (``ate``, ``rendering``, ...).
        caption: caption (plain text).
        stub_headers: headers of the leading text columns.
        stubs: per row, the leading text cells (``✓``/``✗`` become check marks in LaTeX).
        columns: the value columns.
        values: per row and column, a :class:`Stat` (stored units) or ``None``.
        markers: per row and column, ``""``, ``--`` or ``L`` where there is no value.
        complete: per row and column, whether the value comes from complete runs.
        rank_groups: sets of cells ``(row, column)`` compared with each other.
        rules: row indices before which a horizontal rule goes.
        notes: footnotes.
    """

    name: str
    caption: str
    stub_headers: list[str]
    stubs: list[list[str]]
    columns: list[Column]
    values: list[list[Stat | None]]
    markers: list[list[str]]
    complete: list[list[bool]]
    rank_groups: list[list[tuple[int, int]]]
    rules: set[int] = field(default_factory=set)
    notes: list[str] = field(default_factory=list)
    row_keys: list[str] | None = None

    def key_at(self, r: int, c: int) -> str:
        """The metric of a cell: the column's, or the row's for columns with key ``""``."""
        key = self.columns[c].key
        return key or (self.row_keys[r] if self.row_keys else "")

    def ranks(self) -> dict[tuple[int, int], int]:
        """1 (best) / 2 (second) per ranked cell; complete values compete among themselves,
        partial ones only when a comparison holds no complete value."""
        out: dict[tuple[int, int], int] = {}
        for group in self.rank_groups:
            cells = [(r, c) for r, c in group if self.values[r][c] is not None]
            full = [(r, c) for r, c in cells if self.complete[r][c]]
            competing = full or cells
            if len(competing) < 2:
                continue
            key = self.key_at(*competing[0])
            means = pd.Series([_mean(self.values[r][c]) for r, c in competing], dtype=float)
            for cell, rank in zip(competing, dense_ranks(means, key), strict=True):
                if rank:
                    out[cell] = int(rank)
        return out

    @property
    def usual_n(self) -> int:
        return common_n(v.n for row in self.values for v in row if v is not None)


def _cell_text(table: PaperTable, r: int, c: int, ranks: dict, style: str) -> str:
    v = table.values[r][c]
    if v is None:
        return table.markers[r][c]
    return format_stat(v, table.key_at(r, c), ranks.get((r, c), 0), style, table.usual_n)


def _groups(columns: Sequence[Column]) -> list[tuple[str, int]]:
    out: list[tuple[str, int]] = []
    for col in columns:
        if out and out[-1][0] == col.group:
            out[-1] = (col.group, out[-1][1] + 1)
        else:
            out.append((col.group, 1))
    return out


def _legend(table: PaperTable, pm: str = "±") -> str:
    n = table.usual_n
    spread = f" Mean {pm} std over {n} runs (seeds) unless (n=k) says otherwise." if n > 1 else ""
    return (f"Best in bold, second underlined.{spread} {MISSING}: no result; "
            f"{LOST}: tracking lost.")


def render_markdown(table: PaperTable) -> str:
    """GitHub Markdown: group names go into the column headers; footnotes follow."""
    ranks = table.ranks()
    heads = [h.replace("\n", " ") for h in table.stub_headers] + [
        c.title or f"{c.group} {header(c.key, 'md')}".strip() for c in table.columns]
    rows = [list(table.stubs[r]) + [_cell_text(table, r, c, ranks, "md")
                                    for c in range(len(table.columns))]
            for r in range(len(table.stubs))]
    df = pd.DataFrame(rows, columns=heads)
    text = df.to_markdown(index=False, disable_numparse=True,
                          colalign=["left"] * len(table.stub_headers)
                          + ["center"] * len(table.columns))
    notes = "\n".join(f"{i}. {n}" for i, n in enumerate(table.notes, start=1))
    return (f"**{table.caption}**\n\n{text}\n\n{_legend(table)}\n"
            + (f"{notes}\n" if notes else ""))


def _latex_head(text: str) -> str:
    """A stub header; a newline in it stacks the lines (LaTeX kernel's ``shortstack``)."""
    parts = [latex_escape(p) for p in text.split("\n")]
    return parts[0] if len(parts) == 1 else r"\shortstack{" + r"\\".join(parts) + "}"


def _latex_stub(text: str) -> str:
    # a stub may hold a metric's Markdown header (the rendering table's rows): its Unicode
    # arrow becomes the math arrow every other LaTeX header uses
    return _LATEX_SYMBOLS.get(text) or latex_escape(text).replace(
        "↑", r"$\uparrow$").replace("↓", r"$\downarrow$")


def render_latex(table: PaperTable, label: str | None = None, width: TableWidth = "auto") -> str:
    """A booktabs table in a float (``\\usepackage{booktabs,graphicx,amssymb}``); footnotes go
    into LaTeX comments so the table stays paper-ready."""
    ranks = table.ranks()
    groups = _groups(table.columns)
    n_stub = len(table.stub_headers)
    tab = [r"\begin{tabular}{" + "l" * n_stub + "c" * len(table.columns) + "}", r"\toprule"]
    if any(g for g, _ in groups):
        cells, rules, col = [""] * n_stub, [], n_stub + 1
        for g, span in groups:
            cells.append(rf"\multicolumn{{{span}}}{{c}}{{{latex_escape(g)}}}")
            if g:
                rules.append(rf"\cmidrule(lr){{{col}-{col + span - 1}}}")
            col += span
        tab += [" & ".join(cells) + r" \\", " ".join(rules)]
    head = [_latex_head(h) for h in table.stub_headers] + [
        latex_escape(c.title) if c.title else header(c.key, "latex") for c in table.columns]
    tab += [" & ".join(head) + r" \\", r"\midrule"]
    body = []
    for r, stub in enumerate(table.stubs):
        if r in table.rules:
            tab.append(r"\midrule")
        body.append([_latex_stub(s) for s in stub] + [_cell_text(table, r, c, ranks, "latex")
                                                      for c in range(len(table.columns))])
        tab.append(" & ".join(body[-1]) + r" \\")
    tab += [r"\bottomrule", r"\end{tabular}"]
    caption = latex_escape(table.caption) + " " + latex_escape(_legend(table, "PM")).replace(
        "PM", r"$\pm$")
    text = wrap_latex_table(tab, caption=caption, label=label, width=width,
                            est_width_pt=estimate_width_pt([head] + body))
    comments = "".join(f"% note: {n}\n" for n in table.notes)
    return comments + text


# ------------------------------------------------------------------------------ builders
def _rows_with(board: Leaderboard, method: str | None = None) -> list[RowKey]:
    return [r for r in board.rows if method is None or r.method == method]


def _settings(board: Leaderboard, row: RowKey) -> dict:
    for (rk, _), cell in board.cells.items():
        if rk == row and cell.runs:
            return cell.runs[0].settings
    return {}


def _value(board: Leaderboard, row: RowKey, seq: str, key: str) -> tuple[Stat | None, str]:
    if seq == "Avg.":
        st = board.average(row, key)
        return st, "" if st else MISSING
    return board.stat(row, seq, key), board.marker(row, seq) or MISSING


def _matrix(board: Leaderboard, rows: Sequence[RowKey], stubs: list[list[str]],
            columns: list[Column], seq_of: Callable[[Column], str]
            ) -> tuple[list[list[Stat | None]], list[list[str]], list[list[bool]]]:
    values: list[list[Stat | None]] = []
    markers: list[list[str]] = []
    complete: list[list[bool]] = []
    for row in rows:
        vs, ms = [], []
        for col in columns:
            st, mk = _value(board, row, seq_of(col), col.key)
            vs.append(st)
            ms.append(mk)
        values.append(vs)
        markers.append(ms)
        complete.append([row.complete] * len(columns))
    return values, markers, complete


def _down_columns(n_rows: int, n_cols: int) -> list[list[tuple[int, int]]]:
    return [[(r, c) for r in range(n_rows)] for c in range(n_cols)]


def _partial_note(rows: Sequence[RowKey]) -> list[str]:
    if rows and all(not r.complete for r in rows):
        return ["All runs cover only part of their sequences (a frame limit): values are over "
                "the frames processed and ranked among themselves."]
    return []


def ate_table(board: Leaderboard) -> PaperTable | None:
    """Sequences in rows (plus Avg.), one ATE column per method row (Tab. II / IV)."""
    rows = _rows_with(board)
    if not rows or "ate" not in board.metrics:
        return None
    seqs = board.sequences + (["Avg."] if len(board.sequences) > 1 else [])
    columns = [Column(r.label, "ate") for r in rows]
    values: list[list[Stat | None]] = [[None] * len(rows) for _ in seqs]
    markers = [[""] * len(rows) for _ in seqs]
    complete = [[r.complete for r in rows] for _ in seqs]
    for i, s in enumerate(seqs):
        for j, row in enumerate(rows):
            values[i][j], markers[i][j] = _value(board, row, s, "ate")
    return PaperTable(
        "ate", "Tracking accuracy: ATE RMSE [cm] per sequence.", ["Scenes"],
        [[s] for s in seqs], columns, values, markers, complete,
        [[(i, j) for j in range(len(rows))] for i in range(len(seqs))],
        rules={len(board.sequences)} if len(seqs) > len(board.sequences) else set(),
        notes=_partial_note(rows))


def rendering_table(board: Leaderboard) -> PaperTable | None:
    """Per method a block of PSNR / SSIM / LPIPS rows; sequences in columns plus Avg. and the
    rendering FPS (Tab. I)."""
    keys: list[str] = [k for k in ("psnr", "ssim", "lpips") if k in board.metrics]
    rows = _rows_with(board)
    if not keys or not rows:
        return None
    seqs = board.sequences + (["Avg."] if len(board.sequences) > 1 else [])
    has_fps = any(_fps(board, r) is not None for r in rows)
    columns = [Column("", "", s) for s in seqs] + ([Column("", "render_fps")] if has_fps else [])
    stubs: list[list[str]] = []
    values: list[list[Stat | None]] = []
    markers: list[list[str]] = []
    complete: list[list[bool]] = []
    row_keys: list[str] = []
    rules: set[int] = set()
    for row in rows:
        if stubs:
            rules.add(len(stubs))
        for i, k in enumerate(keys):
            stubs.append([row.label if i == 0 else "", header(k, "md")])
            cells = [_value(board, row, s, k) for s in seqs]
            if has_fps:
                fps = _fps(board, row) if i == 0 else None
                cells.append((fps, MISSING if i == 0 and fps is None else ""))
            values.append([v for v, _ in cells])
            markers.append([m for _, m in cells])
            complete.append([row.complete] * len(columns))
            row_keys.append(k)
    groups = [[(r, c) for r in range(len(stubs)) if row_keys[r] == k]
              for c in range(len(seqs)) for k in keys]
    if has_fps:
        groups.append([(r, len(seqs)) for r in range(len(stubs)) if row_keys[r] == keys[0]])
    return PaperTable("rendering", "Rendering quality against the sharp ground truth "
                      "(PSNR [dB], SSIM, LPIPS) and rendering FPS.", ["Method", "Metric"],
                      stubs, columns, values, markers, complete, groups, rules,
                      _partial_note(rows), row_keys)


def _mean(stat: Stat | None) -> float:
    return math.nan if stat is None else stat.mean


def _fps(board: Leaderboard, row: RowKey) -> Stat | None:
    stats = [s for s in (board.stat(row, q, "render_fps") for q in board.sequences)
             if s is not None]
    if not stats:
        return None
    return Stat(float(np.mean([s.mean for s in stats])), math.nan, 0)


def _setting_key(settings: dict, name: str) -> str | None:
    """The settings key of SLAM field ``name`` (``slam.method.crf`` or ``slam.crf``)."""
    for key in (f"slam.method.{name}", f"slam.{name}"):
        if key in settings:
            return key
    return None


def _ablation_rows(board: Leaderboard, fields: Sequence[str], full: str
                   ) -> list[tuple[RowKey, dict]]:
    """Rows whose settings equal the full method's except for the SLAM ``fields``; each with
    its values of those fields."""
    refs = [r for r in board.rows if r.method == full]
    if not refs:
        return []
    ref = _settings(board, refs[0])
    keys = [_setting_key(ref, f) for f in fields]
    if any(k is None for k in keys):
        return []
    rest = {k: v for k, v in ref.items() if k not in keys}
    out = []
    for row in board.rows:
        s = _settings(board, row)
        if all(k in s for k in keys) and {k: v for k, v in s.items() if k not in keys} == rest:
            out.append((row, {f: s[k] for f, k in zip(fields, keys, strict=True)}))
    return out


def ablation_events_table(board: Leaderboard, full: str = "egs") -> PaperTable | None:
    """Check-mark columns Event Tracking / Event Mapping, ATE / PSNR / SSIM / LPIPS per
    sequence (Tab. III; with ATE only it is Tab. IV)."""
    found = _ablation_rows(board, EVENT_FIELDS, full)
    if len({(s[EVENT_FIELDS[0]], s[EVENT_FIELDS[1]]) for _, s in found}) < 2:
        return None
    found.sort(key=lambda rs: (bool(rs[1][EVENT_FIELDS[0]]), bool(rs[1][EVENT_FIELDS[1]]),
                               not rs[0].complete, rs[0].label))
    rows = [r for r, _ in found]
    stubs = [[CHECK if s[EVENT_FIELDS[0]] else CROSS, CHECK if s[EVENT_FIELDS[1]] else CROSS]
             for _, s in found]
    keys = [k for k in ("ate", "psnr", "ssim", "lpips") if k in board.metrics]
    columns = [Column(s, k) for s in board.sequences for k in keys]
    values, markers, complete = _matrix(board, rows, stubs, columns, lambda c: c.group)
    notes = _partial_note(rows) + [f"Rows: {', '.join(r.label for r in rows)} (settings equal "
                                   f"to {full}'s except event tracking / mapping)."]
    return PaperTable("ablation_events", "Ablation: event information in tracking and mapping.",
                      ["Event\nTracking", "Event\nMapping"], stubs, columns, values, markers,
                      complete, _down_columns(len(rows), len(columns)), notes=notes)


def ablation_crf_table(board: Leaderboard, full: str = "egs") -> PaperTable | None:
    """``w/o CRF`` / ``w CRF`` rows, ATE per sequence (Tab. V)."""
    found = _ablation_rows(board, (CRF_FIELD,), full)
    if len({s[CRF_FIELD] for _, s in found}) < 2:
        return None
    names = {"identity": "w/o CRF", "learnable": "w CRF"}
    found.sort(key=lambda rs: (rs[1][CRF_FIELD] == "learnable", rs[0].label))
    rows = [r for r, _ in found]
    stubs = [[names.get(s[CRF_FIELD], f"CRF {s[CRF_FIELD]}") + (f" ({r.label})" if r.method != full
                                                            else " (ours)")]
             for r, s in found]
    columns = [Column(s, "ate") for s in board.sequences]
    values, markers, complete = _matrix(board, rows, stubs, columns, lambda c: c.group)
    return PaperTable("ablation_crf", "Ablation: the camera response function (ATE [cm]).",
                      ["Settings"], stubs, columns, values, markers, complete,
                      _down_columns(len(rows), len(columns)), notes=_partial_note(rows))


def edi_table(board: Leaderboard, ours: str = "egs") -> PaperTable | None:
    """MonoGS, MonoGS+EDI and ours: ATE / PSNR / LPIPS per sequence (Tab. VI)."""
    if not any(r.method == "monogs-edi" for r in board.rows):
        return None
    rows = [r for m in (*EDI_METHODS, ours) for r in board.rows if r.method == m]
    keys = [k for k in ("ate", "psnr", "lpips") if k in board.metrics]
    columns = [Column(s, k) for s in board.sequences for k in keys]
    stubs = [[r.label] for r in rows]
    values, markers, complete = _matrix(board, rows, stubs, columns, lambda c: c.group)
    rules = {i for i, r in enumerate(rows) if r.method == ours and i > 0}
    return PaperTable("edi", "Single-image deblurring (EDI) before MonoGS versus ours.",
                      ["Method"], stubs, columns, values, markers, complete,
                      _down_columns(len(rows), len(columns)), rules=set(sorted(rules)[:1]),
                      notes=_partial_note(rows))


BUILDERS: dict[str, Callable[[Leaderboard], PaperTable | None]] = {
    "ate": ate_table, "rendering": rendering_table, "ablation_events": ablation_events_table,
    "ablation_crf": ablation_crf_table, "edi": edi_table,
}


def runs_root_of(sweep_dir: str | Path) -> Path:
    """A sweep folder's ``runs/`` when present, else the folder itself."""
    p = Path(sweep_dir)
    return p / "runs" if (p / "runs").is_dir() else p


def build_tables(sweep_dir: str | Path, protocol: str = DEFAULT_PROTOCOL,
                 evaluate_missing: bool = True, tables: Sequence[str] = TABLES
                 ) -> tuple[dict[str, PaperTable], list[str]]:
    """The tables that the sweep's runs can fill, and a line per table that cannot be made."""
    from egs_bench.errors import ConfigError

    for t in tables:
        if t not in BUILDERS:
            raise ConfigError(f"unknown table {t!r}; choose from {', '.join(BUILDERS)}")
    results = collect_results(runs_root_of(sweep_dir), protocol, evaluate_missing)
    board = build(results, ("ate", "psnr", "ssim", "lpips", "render_fps"))
    made, skipped = {}, []
    why = {"ablation_events": "needs runs whose settings differ from egs only in event "
                              "tracking / mapping (egs-no-event-tracking, egs-no-event-mapping, "
                              "egs-no-events)",
           "ablation_crf": "needs egs and egs-no-crf runs",
           "edi": "needs monogs-edi runs",
           "rendering": "no rendering metrics", "ate": "no ATE"}
    for name in tables:
        table = BUILDERS[name](board)
        if table is None:
            skipped.append(f"{name}: not made ({why[name]})")
        else:
            table.notes = list(dict.fromkeys(table.notes + board.notes))
            made[name] = table
    return made, skipped


def write_tables(tables: dict[str, PaperTable], out_dir: str | Path, *, label_prefix: str = "tab:",
                 width: TableWidth = "auto", overwrite: bool = False) -> list[Path]:
    """Write ``<name>.tex`` and ``<name>.md`` per table and ``tables.tex`` (a minimal document
    that inputs them all, for checking with pdflatex); returns the written paths.

    Raises:
        OutputError: an output exists and ``overwrite`` is false, or is not a text file;
            ``out_dir`` exists and is not a folder.
    """
    from egs_bench.errors import OutputError
    from egs_bench.experiments.latex_check import minimal_document
    from egs_bench.fileio import write_text_atomic
    from egs_bench.outputs import prepare_output

    out = Path(out_dir)
    if out.exists() and not out.is_dir():  # the named output exists, of another kind
        raise OutputError(out, "already exists and is not a folder; choose another --out")
    targets = [out / f"{n}.{ext}" for n in tables for ext in ("tex", "md")] + [out / "tables.tex"]
    for target in targets:  # all checked before anything is written
        prepare_output(target, "text", overwrite=overwrite, option="--out")
    written = []
    for name, table in tables.items():
        write_text_atomic(out / f"{name}.tex", render_latex(table, f"{label_prefix}{name}",
                                                            width))
        write_text_atomic(out / f"{name}.md", render_markdown(table))
        written += [out / f"{name}.tex", out / f"{name}.md"]
    doc = minimal_document([rf"\input{{{name}.tex}}" for name in tables])
    write_text_atomic(out / "tables.tex", doc)
    return written + [out / "tables.tex"]
