"""The sequence-folder and run-folder reference pages, rendered from the code that reads and
writes them: the module docstrings' layout blocks, the declared schemas
(:data:`egs_bench.datasets.sequence.META_KEYS`, ``FRAME_COLUMN_DOCS``), the dataclasses'
attribute lists and the constants."""

from __future__ import annotations

import inspect
import re
from typing import Any

from tabulate import tabulate

from egs_bench.datasets import events, sequence
from egs_bench.runs import contract, folder

_ENTRY = re.compile(r"^\s*<(?:seq|run)>/(\S+)\s+(.*)$")
_ROLE = re.compile(r":[a-z]+:`~?([^`]+)`")


def markdown_text(rst: str) -> str:
    """Docstring markup as Markdown: ``code`` -> `code`, :role:`x` -> `x`."""
    return _ROLE.sub(r"`\1`", rst).replace("``", "`")


def _cell(text: str) -> str:
    return " ".join(markdown_text(text).split()).replace("|", "\\|")


def layout(doc: str) -> list[tuple[str, str]]:
    """The ``<seq>/path  description`` lines of a module docstring's layout block, with their
    continuation lines, as (path, description) pairs."""
    entries: list[list[str]] = []
    for line in doc.splitlines():
        match = _ENTRY.match(line)
        if match:
            entries.append([match.group(1), match.group(2)])
        elif entries and line.strip() and not line.strip().startswith("```"):
            entries[-1][1] += " " + line.strip()
        elif entries:
            break
    return [(path, " ".join(text.split())) for path, text in entries]


def attributes(cls: type) -> list[tuple[str, str]]:
    """The ``Attributes:`` section of a Google-style class docstring as (name, text) pairs."""
    doc = inspect.getdoc(cls) or ""
    section = doc.split("Attributes:", 1)[1] if "Attributes:" in doc else ""
    pairs: list[list[str]] = []
    for line in section.splitlines():
        if not line.strip():
            continue
        if not line.startswith("    "):  # the section ended
            break
        if line.startswith("        "):
            pairs[-1][1] += " " + line.strip()
        else:
            name, _, text = line.strip().partition(":")
            pairs.append([name, text.strip()])
    return [(name, text) for name, text in pairs]


def _table(rows: list[list[str]], headers: list[str]) -> str:
    return tabulate(rows, headers=headers, tablefmt="github", disable_numparse=True)


def _layout_table(doc: str, root: str) -> str:
    return _table([[f"`{root}/{path}`", _cell(text)] for path, text in layout(doc)],
                  ["path", "content"])


def _prose_after_layout(doc: str) -> str:
    """The module docstring's paragraphs after its layout block, ``::`` blocks fenced."""
    lines = doc.splitlines()
    last = max(i for i, line in enumerate(lines) if _ENTRY.match(line))
    rest = lines[last + 1:]
    while rest and rest[0].strip():  # the last entry's continuation lines
        rest = rest[1:]
    out: list[str] = []
    in_code = False
    for line in rest:
        if in_code and line.strip() and not line.startswith("    "):
            out.append("```")
            in_code = False
        if in_code:
            if line.strip() or out[-1] != "```python":  # no blank first line in the block
                out.append(line[4:])
        elif line.rstrip().endswith("::"):
            out += [markdown_text(line.rstrip()[:-1]), "", "```python"]
            in_code = True
        else:
            out.append(markdown_text(line))
    if in_code:
        out.append("```")
    return "\n".join(out).strip()


def _paragraph(doc: str, start: str) -> str:
    """The docstring paragraph that begins with ``start``, on one line, as Markdown."""
    paragraph = next(p for p in doc.split("\n\n") if p.startswith(start))
    return markdown_text(" ".join(paragraph.split()))


def _value(value: Any) -> str:
    """A value as it is written in the YAML and JSON files."""
    return f"`{str(value).lower() if isinstance(value, bool) else value}`"


def render_sequence() -> str:
    """The sequence-folder section (Markdown)."""
    doc = sequence.__doc__ or ""
    meta_rows = [[f"`{key}`", "yes" if key in sequence.REQUIRED_META else "", _cell(text)]
                 for key, text in sequence.META_KEYS.items()]
    frame_rows = [[f"`{column}`", _cell(sequence.FRAME_COLUMN_DOCS[column])]
                  for column in sequence.FRAME_COLUMNS]
    event_rows = [[f"`{name}`", _cell(text)] for name, text in attributes(events.Events)]
    parts = [
        "## Sequence folder",
        "",
        "From `egs_bench/datasets/sequence.py` and `egs_bench/datasets/events.py`. Every "
        "method reads a sequence in this layout; `egs-bench info SEQ` validates one.",
        "",
        "### Files",
        "",
        _layout_table(doc, "<seq>"),
        "",
        f"### `meta.yaml` (format version {sequence.FORMAT_VERSION})",
        "",
        markdown_text(" ".join((inspect.getdoc(sequence.read_meta) or "").split())),
        "",
        _table(meta_rows, ["key", "required", "content"]),
        "",
        "### `frames.csv`",
        "",
        _table(frame_rows, ["column", "content"]),
        "",
        "### `events.h5`",
        "",
        markdown_text(" ".join((events.__doc__ or "").split())),
        "",
        "In memory, a batch of events (`Events`) holds:",
        "",
        _table(event_rows, ["array", "content"]),
        "",
        "### Checks when a sequence is opened",
        "",
        _paragraph(inspect.getdoc(sequence.Sequence.open) or "", "Checks:"),
        "",
    ]
    return "\n".join(parts)


def render_run_folder() -> str:
    """The run-folder section (Markdown)."""
    doc = contract.__doc__ or ""
    status_rows = [[f"`{name}`", _cell(text)] for name, text in attributes(folder.RunStatus)]
    timing_rows = [[f"`{name}`", _cell(text)] for name, text in attributes(folder.RunTiming)]
    estimate_rows = [[f"`{key}`", _value(value)] for key, value in
                     folder.ESTIMATE_DEFAULTS.items()]
    parts = [
        "## Run folder",
        "",
        "From `egs_bench/runs/contract.py`. " + markdown_text(doc.splitlines()[0]),
        "",
        "### Files",
        "",
        _layout_table(doc, "<run>"),
        "",
        _prose_after_layout(doc),
        "",
        "### `status.json`",
        "",
        "States: " + ", ".join(_value(state) for state in folder.STATES) + f". A running "
        f"process rewrites its heartbeat every {folder.HEARTBEAT_S:g} s; a `running` run "
        f"written on another host with no heartbeat for {folder.STALE_AFTER_S:g} s reads as "
        "`interrupted`. Read as `RunStatus`:",
        "",
        _table(status_rows, ["field", "content"]),
        "",
        "### `timing.json`",
        "",
        "Read as `RunTiming`:",
        "",
        _table(timing_rows, ["field", "content"]),
        "",
        "### `run.yaml`: `estimate`",
        "",
        "What the estimate covers. A method's own run records these defaults; an import of "
        "an external output records what it holds (`poses` and `renders` one of "
        + ", ".join(_value(c) for c in folder.ESTIMATE_COVERAGE) + "):",
        "",
        _table(estimate_rows, ["key", "default"]),
        "",
        "### `plots/`",
        "",
        "`egs-bench plot` writes " + ", ".join(_value(f) for f in folder.PLOT_FILES) + ".",
        "",
    ]
    return "\n".join(parts)


def render() -> str:
    """The formats page (Markdown): the sequence folder, then the run folder."""
    intro = ["# Data formats", "",
             "Generated from the code that reads and writes these folders when the site is "
             "built.", ""]
    return "\n".join(intro) + render_sequence() + "\n" + render_run_folder()
