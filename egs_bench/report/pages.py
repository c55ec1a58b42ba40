"""HTML of the report's pages from their content (Jinja2 templates shipped with the package,
every value escaped)."""

from __future__ import annotations

from functools import cache
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
