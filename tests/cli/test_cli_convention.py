"""The CLI's one convention (docs/design.md §10): -o/--out for every output, --quiet for every
progress display, click-style value names, a grouped top-level help, old spellings hidden but
working with a deprecation line."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import typer
from typer._click import Command, Context
from typer.core import TyperGroup

from egs_bench.cli import _register_commands, main
from egs_bench.cli.app import DEPRECATED_OPTIONS, PANELS, app, shown_opts
from egs_bench.errors import EXIT_USAGE


def _commands() -> tuple[TyperGroup, list[tuple[str, Command, Context]]]:
    _register_commands()
    root = typer.main.get_command(app)
    assert isinstance(root, TyperGroup)
    ctx = Context(root, info_name="egs-bench")
    return root, [(name, cmd, Context(cmd, info_name=name, parent=ctx))
                  for name, cmd in root.commands.items() if not cmd.hidden]


def test_every_output_is_o_out_and_every_progress_switch_is_quiet() -> None:
    _, commands = _commands()
    for name, cmd, _ in commands:
        for param in cmd.params:
            if param.param_type_name != "option":
                continue
            opts = set(shown_opts(param)) | set(param.secondary_opts)
            if "-o" in opts or {"--output", "--out"} & set(param.opts):
                assert opts == {"-o", "--out"}, (name, opts)
            if {"--progress", "--no-progress", "--quiet"} & (set(param.opts)
                                                             | set(param.secondary_opts)):
                assert opts == {"--quiet"}, (name, opts)


@pytest.mark.parametrize("command", ["report", "export", "run", "figure", "sweep", "ate",
                                     "leaderboard", "make-synthetic", "import-run"])
def test_help_shows_click_style_value_names(command: str, capsys: pytest.CaptureFixture[str]
                                            ) -> None:
    assert main([command, "--help"]) == 0
    text = capsys.readouterr().out
    # typer's <str>, <path>, <int range>, <list[Path]>, <a|b>
    assert not re.search(r"<(str|int|float|path|bool|\w+ range|list\[[^]]*\]|[\w-]+(\|[\w-]+)+)>",
                         text), text
    assert "{" not in text.splitlines()[0]  # usage: SOURCE, not {source}
    assert re.search(r"\b(PATH|TEXT|INTEGER|FLOAT)\b", text)
    for old in DEPRECATED_OPTIONS:
        assert old not in text


def test_the_top_level_help_lists_every_command_under_a_panel(capsys: pytest.CaptureFixture[str]
                                                              ) -> None:
    _, commands = _commands()
    listed = {name for names in PANELS.values() for name in names}
    assert {name for name, _, _ in commands} == listed
    assert main(["--help"]) == 0
    text = capsys.readouterr().out
    headings = [line[:-1] for line in text.splitlines() if line.endswith(":")
                and not line.startswith(" ")]
    assert headings[-len(PANELS):] == list(PANELS)
    assert "Other commands" not in text


def test_old_spellings_work_with_a_deprecation_line(capsys: pytest.CaptureFixture[str],
                                                    tiny_sequence: Path, tmp_path: Path) -> None:
    assert main(["export", str(tiny_sequence), str(tmp_path / "e"), "-f", "tum-rgbd",
                 "--no-progress"]) == 0
    err = capsys.readouterr().err
    assert "--no-progress is deprecated" in err and "use --quiet" in err
    assert "positional argument is deprecated" in err and (tmp_path / "e").is_dir()
    code = main(["export", str(tiny_sequence), str(tmp_path / "f"), "-o", str(tmp_path / "g"),
                 "-f", "tum-rgbd"])
    assert code == EXIT_USAGE and "given twice" in capsys.readouterr().err
    code = main(["export", str(tiny_sequence), "-f", "tum-rgbd"])
    assert code == EXIT_USAGE and "--out" in capsys.readouterr().err


def test_output_is_an_alias_of_out(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    runs = tmp_path / "runs"
    runs.mkdir()
    main(["leaderboard", str(runs), "--output", str(tmp_path / "board.md")])
    err = capsys.readouterr().err
    assert "--output is deprecated" in err and "use -o/--out" in err
