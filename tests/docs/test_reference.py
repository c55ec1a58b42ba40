"""The generated reference pages cover every command, option, configuration field and file of
the formats, and say what the code does (ranges that validation enforces, values the presets
hold)."""

from __future__ import annotations

import dataclasses
import re
import typing
from collections.abc import Callable, Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest
import typer

from egs_bench.cli.app import shown_opts
from egs_bench.errors import ConfigError
from egs_bench.slam import config


def _sections(page: str, level: int) -> dict[str, str]:
    """Heading text -> the section's Markdown, for headings of exactly ``level``."""
    marks = "#" * level
    parts = re.split(rf"^{marks} (.+)$", page, flags=re.MULTILINE)
    return {parts[i].strip(): parts[i + 1] for i in range(1, len(parts), 2)}


def _commands(command: Any, path: str) -> Iterator[tuple[str, Any]]:  # click commands
    yield path, command
    for name, sub in getattr(command, "commands", {}).items():
        if not sub.hidden:
            yield from _commands(sub, f"{path} {name}")


def test_cli_page_has_every_command_and_every_option(gen: Callable[[str], ModuleType]) -> None:
    cli = gen("cli_reference")
    app = cli.egs_bench_app()
    page = cli.render(app)
    sections = _sections(page, 2)
    commands = dict(_commands(typer.main.get_command(app), "egs-bench"))
    assert len(commands) > 20  # the walk reached the registered commands
    for path, command in commands.items():
        section = sections[f"`{path}`"]
        assert (command.help or "").strip().splitlines()[0] in section, path
        for param in command.params:
            if getattr(param, "hidden", False):
                continue
            names = shown_opts(param) + param.secondary_opts \
                if param.param_type_name == "option" else [param.name.upper()]
            for name in names:
                assert f"`{name}`" in section, f"{path}: {name}"


def test_cli_page_renders_groups_types_defaults_and_hides_hidden_commands(
        gen: Callable[[str], ModuleType]
) -> None:
    cli = gen("cli_reference")
    app = typer.Typer()
    tools = typer.Typer(help="Tools.")
    app.add_typer(tools, name="tools")

    @app.command("top")
    def top(count: int = typer.Option(3, "--count", "-c", min=1, help="How many | which.")) \
            -> None:
        """Top command."""

    @tools.command("deep")
    def deep(path: Path = typer.Argument(..., help="A file."),
             flag: bool = typer.Option(False, "--flag", help="A flag.")) -> None:
        """Deep command."""

    @tools.command("secret", hidden=True)
    def secret() -> None:
        """Hidden."""

    page = cli.render(app, prog="prog")
    top_section = _sections(page, 2)["`prog top`"]
    assert "Top command." in top_section
    assert re.search(r"\| `--count`, `-c` +\| `INTEGER, >= 1` +\| `3` +\| How many \\\| which\. "
                     r"+\|", top_section), top_section
    deep_section = _sections(page, 3)["`prog tools deep`"]
    assert "Deep command." in deep_section and "prog tools deep [OPTIONS]" in deep_section
    assert re.search(r"\| `PATH` +\| `PATH` +\| required +\| A file\. +\|", deep_section)
    assert re.search(r"\| `--flag` +\| flag +\| off +\| A flag\. +\|", deep_section)
    assert "secret" not in page


def _row(section: str, name: str) -> list[str]:
    line = next(line for line in section.splitlines() if line.startswith(f"| `{name}` "))
    return [cell.strip() for cell in re.split(r"(?<!\\)\|", line)[1:-1]]


def test_config_page_has_every_field_with_default_preset_values_and_doc(
        gen: Callable[[str], ModuleType]
) -> None:
    ref = gen("config_reference")
    sections = _sections(ref.render(), 2)
    headers = None
    presets = {name: make() for name, make in config.PRESETS.items()}
    for group, cls in config.GROUPS.items():
        section = sections[f"`{group}`"]
        header_line = next(line for line in section.splitlines() if line.startswith("| field"))
        headers = [cell.strip() for cell in header_line.strip("|").split("|")]
        assert headers[3:3 + len(presets)] == list(presets)
        docs = ref.field_docs(cls)
        for f in dataclasses.fields(cls):
            row = dict(zip(headers, _row(section, f.name), strict=True))
            assert row["default"] == ref.value_text(getattr(cls(), f.name))
            for name, preset in presets.items():
                assert row[name].strip("*") == ref.value_text(getattr(getattr(preset, group),
                                                                      f.name))
            assert docs[f.name], f"{group}.{f.name} has no comment in config.py to document it"
            assert row["doc"] == docs[f.name].replace("|", "\\|")
    # the cpu preset's smaller budget shows, in bold
    assert headers is not None
    budget = dict(zip(headers, _row(sections["`budget`"], "tracking_iters"), strict=True))
    assert (budget["default"], budget["paper"], budget["cpu"]) == ("`100`", "`100`", "**`30`**")


def test_config_field_docs_are_the_source_comments(gen: Callable[[str], ModuleType]) -> None:
    ref = gen("config_reference")

    @dataclasses.dataclass
    class Demo:
        # first line
        # second line
        a: int = 1  # trailing
        b: float = 2.0

        c: str = "x"  # only this
    assert ref.field_docs(Demo) == {"a": "first line second line trailing", "b": "",
                                    "c": "only this"}


def test_every_number_field_declares_its_range() -> None:
    for group, cls in config.GROUPS.items():
        for name, kind in typing.get_type_hints(cls).items():
            kinds = set(typing.get_args(kind) or (kind,)) - {type(None)}
            if kinds <= {int, float}:
                assert f"{group}.{name}" in config.RANGES, f"{group}.{name} has no range"
    for key in config.RANGES:
        config.resolve_key(key)  # a range of a field that does not exist raises


def _inside_and_outside(bounds: config.Bounds, integer: bool) -> tuple[list, list]:
    step = 1 if integer else 1e-3
    inside: list[float] = []
    outside: list[float] = []
    for bound, sign, is_open in ((bounds.low, -1, bounds.low_open),
                                 (bounds.high, 1, bounds.high_open)):
        if bound is None:
            continue
        bound = int(bound) if integer else float(bound)
        (outside if is_open else inside).append(bound)
        outside.append(bound + sign * step)
        inside.append(bound - sign * step)
    return inside, outside


@pytest.mark.parametrize("key", sorted(config.RANGES))
def test_validation_enforces_each_documented_range(key: str) -> None:
    bounds = config.RANGES[key]
    group, name = key.split(".")
    kind = typing.get_type_hints(config.GROUPS[group])[name]
    integer = int in (typing.get_args(kind) or (kind,))
    inside, outside = _inside_and_outside(bounds, integer)
    base = config.cpu_preset().replace(**{"keyframes.protected": 1})  # window_size 3 may pass
    for value in inside:
        base.replace(**{key: value}).validate()
    for value in outside:
        with pytest.raises(ConfigError, match=re.escape(key)):
            base.replace(**{key: value}).validate()


def test_bounds_describe_their_range() -> None:
    assert config.Bounds(low=0).describe() == ">= 0"
    assert config.Bounds(low=0, low_open=True).describe() == "> 0"
    assert config.Bounds(low=0, high=1, high_open=True).describe() == "in [0, 1)"
    assert config.Bounds(low=0, high=1, low_open=True).describe() == "in (0, 1]"


def test_formats_page_lists_every_run_folder_file_and_sequence_file(
        gen: Callable[[str], ModuleType], tiny_sequence: Path
) -> None:
    from egs_bench.datasets import sequence
    from egs_bench.runs import contract, folder

    formats = gen("formats_reference")
    page = formats.render()
    run_paths = {path.split("/")[0] for path, _ in formats.layout(contract.__doc__)}
    names = {value for name, value in vars(folder).items()
             if re.fullmatch(r"[A-Z]+_(FILE|DIR)", name)}
    assert names and names <= run_paths, names - run_paths
    for path in run_paths:
        assert f"`<run>/{path}" in page
    seq_paths = {path.split("/")[0] for path, _ in formats.layout(sequence.__doc__)}
    written = {p.name for p in tiny_sequence.iterdir()}
    assert written <= seq_paths, written - seq_paths
    assert set(sequence.FRAME_COLUMN_DOCS) == set(sequence.FRAME_COLUMNS)
    meta = sequence.read_meta(tiny_sequence / "meta.yaml")
    assert set(sequence.REQUIRED_META) | set(meta) <= set(sequence.META_KEYS), \
        set(meta) - set(sequence.META_KEYS)
    for key in sequence.META_KEYS:
        assert f"| `{key}` " in page
    for state in folder.STATES:
        assert f"`{state}`" in page


def test_layout_reads_continuation_lines(gen: Callable[[str], ModuleType]) -> None:
    formats = gen("formats_reference")
    doc = "Title.\n\n    <run>/a.txt   first\n                  more\n    <run>/b/      two\n\nEnd."
    assert formats.layout(doc) == [("a.txt", "first more"), ("b/", "two")]


def test_cli_page_lists_the_commands_by_the_help_s_panels(gen: Callable[[str], ModuleType]) -> None:
    from egs_bench.cli.app import PANELS

    cli = gen("cli_reference")
    page = cli.render(cli.egs_bench_app())
    for panel, names in PANELS.items():
        line = next(li for li in page.splitlines() if li.startswith(f"- **{panel}**: "))
        assert [f"[`{n}`](#egs-bench-{n})" for n in names] == line.split(": ", 1)[1].split(", ")
