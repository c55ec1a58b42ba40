"""Formatting primitives shared by leaderboards and paper tables (Markdown and LaTeX).

* cells: ``mean +- std`` in the metric's displayed unit, best bold / second underlined, an
  ``(n=k)`` mark where a cell has another number of runs than most cells;
* ranks: dense ranks on the displayed (rounded) means, in the metric's direction;
* LaTeX: escaping, and the float around a ``tabular`` with a caption, an optional label and a
  width policy (natural, shrunk to the column, or a page-wide ``table*``) so that wide tables
  never overflow. The output needs ``\\usepackage{booktabs,graphicx}`` (``amssymb`` for check
  marks in ablation tables).
"""

from __future__ import annotations

import math
import re
from collections import Counter
from collections.abc import Iterable, Sequence
from typing import Literal, get_args

import pandas as pd

from egs_bench.errors import ConfigError
from egs_bench.eval.grouping import Stat
from egs_bench.eval.results import METRICS

#: How wide a LaTeX table is set: by its estimated width, as wide as its content, one column or
#: the page.
TableWidth = Literal["auto", "natural", "column", "page"]
WIDTHS: tuple[TableWidth, ...] = get_args(TableWidth)
#: Estimated natural width above which ``auto`` makes a page-wide ``table*`` (a two-column
#: paper's column is about 240 pt wide).
COLUMN_WIDTH_PT = 240.0
_PT_PER_CHAR = 5.0  # Computer Modern 10 pt digits are 5 pt wide
_PT_PER_COLUMN = 12.0  # 2 x \tabcolsep

_LATEX_SPECIAL = {"\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#",
                  "_": r"\_", "{": r"\{", "}": r"\}", "~": r"\textasciitilde{}",
                  "^": r"\textasciicircum{}"}


def latex_escape(text: str) -> str:
    """Escape LaTeX's special characters in plain text."""
    return re.sub(r"[\\&%$#_{}~^]", lambda m: _LATEX_SPECIAL[m.group(0)], text)


def common_n(counts_per_cell: Iterable[int]) -> int:
    """The most frequent number of runs behind the cells (0 when there is no value)."""
    counts = Counter(int(n) for n in counts_per_cell if n > 0)
    return counts.most_common(1)[0][0] if counts else 0


def format_stat(stat: Stat, key: str, rank: int, style: str, usual_n: int) -> str:
    """One cell: the mean (bold for rank 1, underlined for rank 2), ``+- std`` for n >= 2 and
    ``(n=k)`` when k differs from ``usual_n``; ``n == 0`` marks a derived value (an average
    over sequences) that shows neither. ``style`` is ``"md"`` or ``"latex"``."""
    spec = METRICS[key]
    d = spec.decimals
    text = f"{stat.mean * spec.scale:.{d}f}"
    if style == "md":
        text = f"**{text}**" if rank == 1 else (f"<u>{text}</u>" if rank == 2 else text)
        if stat.n >= 2:
            text += f" ± {stat.std * spec.scale:.{d}f}"
        if stat.n and stat.n != usual_n:
            text += f" (n={stat.n})"
        return text
    text = rf"\textbf{{{text}}}" if rank == 1 else (rf"\underline{{{text}}}" if rank == 2
                                                     else text)
    if stat.n >= 2:
        text += rf"\,{{\scriptsize$\pm${stat.std * spec.scale:.{d}f}}}"
    if stat.n and stat.n != usual_n:
        text += rf"\,{{\scriptsize($n$={stat.n})}}"
    return text


def dense_ranks(means: pd.Series, key: str) -> pd.Series:
    """1 for the best displayed value, 2 for the second, 0 otherwise (NaN never ranks)."""
    spec = METRICS[key]
    shown = (means * spec.scale).round(spec.decimals)
    r = shown.rank(method="dense", ascending=not spec.higher_is_better)
    return r.where(r <= 2, 0).fillna(0).astype(int)


def header(key: str, style: str) -> str:
    """Column header with the unit and the direction arrow."""
    spec = METRICS[key]
    if style == "md":
        return f"{spec.label} {'↑' if spec.higher_is_better else '↓'}"
    arrow = r"$\uparrow$" if spec.higher_is_better else r"$\downarrow$"
    return f"{latex_escape(spec.label)}{arrow}"


def estimate_width_pt(cells: Sequence[Sequence[str]]) -> float:
    """Rough natural width of a tabular in pt from its widest cell per column (LaTeX markup
    stripped); enough to choose between a column-wide and a page-wide float."""
    if not cells:
        return 0.0
    plain = [[re.sub(r"\\[a-zA-Z]+|[{}$]", "", c) for c in row] for row in cells]
    ncol = max(len(r) for r in plain)
    widths = [max((len(r[i]) for r in plain if i < len(r)), default=0) for i in range(ncol)]
    return sum(w * _PT_PER_CHAR + _PT_PER_COLUMN for w in widths)


def wrap_latex_table(tabular: Sequence[str], *, caption: str | None, label: str | None,
                     width: TableWidth = "auto", est_width_pt: float = 0.0,
                     notes: Sequence[str] = ()) -> str:
    """Put ``tabular`` lines into a float.

    Args:
        tabular: the ``\\begin{tabular}`` ... ``\\end{tabular}`` lines.
        caption: caption text (LaTeX, already escaped) or ``None``.
        label: ``\\label`` key or ``None`` (no label).
        width: ``natural`` (a ``table`` at natural size), ``column`` (a ``table`` shrunk to
            the column width when wider), ``page`` (a page-wide ``table*`` shrunk to the text
            width when wider) or ``auto`` (``column`` when the estimated width fits a column,
            else ``page``).
        est_width_pt: estimated natural width (for ``auto``).
        notes: footnote lines printed small under the table (LaTeX, already escaped).
    """
    if width not in WIDTHS:
        raise ConfigError(f"unknown LaTeX width {width!r}; choose one of {', '.join(WIDTHS)}")
    if width == "auto":
        width = "column" if est_width_pt <= COLUMN_WIDTH_PT else "page"
    env = "table*" if width == "page" else "table"
    limit = r"\textwidth" if width == "page" else r"\columnwidth"
    lines = [rf"\begin{{{env}}}[t]", r"\centering"]
    if caption:  # caption above the table: booktabs' \toprule needs a little room below it
        lines.append(rf"\caption{{{caption}}}")
        lines.append(r"\smallskip")
    if label:
        lines.append(rf"\label{{{label}}}")
    if width == "natural":
        lines.extend(tabular)
    else:  # shrink only when wider than the limit (graphicx: \width is the natural width)
        lines.append(rf"\resizebox{{\ifdim\width>{limit}{limit}\else\width\fi}}{{!}}{{%")
        lines.extend(tabular)
        lines.append("}")
    if notes:
        lines.append(r"\par\smallskip\footnotesize " + r" \\ ".join(notes))
    lines.append(rf"\end{{{env}}}")
    return "\n".join(lines) + "\n"


def slug(text: str) -> str:
    """A LaTeX-label-safe slug (letters, digits, ``-``)."""
    return re.sub(r"[^A-Za-z0-9]+", "-", text).strip("-").lower() or "table"


def is_nan(value: float | None) -> bool:
    return value is None or (isinstance(value, float) and math.isnan(value))
