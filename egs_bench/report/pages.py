"""HTML of the report's pages from their content (Jinja2 templates shipped with the package,
every value escaped)."""

from __future__ import annotations

import os
import re
from functools import cache
from pathlib import Path
from typing import Any

from jinja2 import Environment, PackageLoader, StrictUndefined, select_autoescape


@cache
def environment() -> Environment:
    """The templates under ``egs_bench/report/templates`` (HTML autoescaped, undefined names
    an error)."""
    env = Environment(loader=PackageLoader("egs_bench.report", "templates"),
                      autoescape=select_autoescape(["html"]), undefined=StrictUndefined,
                      trim_blocks=False, lstrip_blocks=False, keep_trailing_newline=True)
    env.globals["is_number"] = _is_number
    return env


def _is_number(text: str) -> bool:
    try:
        float(text)
    except (TypeError, ValueError):
        return False
    return text != ""


def render(template: str, **context: Any) -> str:
    """Render ``template`` (``index.html``, ``sequence.html`` or ``run.html``)."""
    return environment().get_template(template).render(**context)


# an absolute POSIX path inside a message: starts with "/" after a space, quote, bracket or the
# start, runs until whitespace or punctuation that ends a path in a sentence
_ABSOLUTE = re.compile(r"(?<![\w./~-])/[^\s:;,'\"()<>]+")


def relative_paths(text: str, page_dir: Path) -> str:
    """``text`` with every absolute path in it rewritten relative to ``page_dir`` (where the
    page will finally live), so a shared page names no folder of the machine that wrote it
    and its paths still lead to the files from the page."""
    base = page_dir.resolve()
    return _ABSOLUTE.sub(lambda m: Path(os.path.relpath(m.group(0), base)).as_posix(), text)
