"""The package version (one place: the installed metadata), `egs-bench --version`, run.yaml's
record of it, and shell completion."""

from __future__ import annotations

import importlib.metadata
from pathlib import Path

import pytest
import yaml

import egs_bench
from egs_bench.cli import main
from egs_bench.runs.folder import RUN_FILE, RunFolder


def _metadata_says(monkeypatch: pytest.MonkeyPatch, version: str) -> None:
    """Make the package metadata report ``version`` (a value no source file holds)."""
    monkeypatch.setattr(egs_bench, "version",
                        lambda dist: version if dist == egs_bench.DISTRIBUTION else "?")


def test_version_comes_from_the_installed_metadata() -> None:
    assert egs_bench.__version__ == importlib.metadata.version("egs-bench")


def test_version_of_a_source_tree_never_installed(monkeypatch: pytest.MonkeyPatch) -> None:
    def not_installed(dist: str) -> str:
        raise importlib.metadata.PackageNotFoundError(dist)

    monkeypatch.setattr(egs_bench, "version", not_installed)
    assert egs_bench.installed_version() == egs_bench.UNKNOWN_VERSION


def test_cli_version_prints_the_metadata_version(monkeypatch: pytest.MonkeyPatch,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    _metadata_says(monkeypatch, "9.8.7")
    assert main(["--version"]) == 0
    assert capsys.readouterr().out == "egs-bench 9.8.7\n"


def test_run_yaml_records_the_metadata_version(monkeypatch: pytest.MonkeyPatch, tmp_path: Path
                                               ) -> None:
    _metadata_says(monkeypatch, "9.8.7")
    run = RunFolder.create(tmp_path / "r", method="m", sequence_name="s", sequence_path=tmp_path)
    run.mark_done()
    info = yaml.safe_load((tmp_path / "r" / RUN_FILE).read_text())
    assert info["egs_bench_version"] == "9.8.7"


@pytest.mark.parametrize("shell, marker", [
    ("bash", "complete -o default -F _egs_bench_completion egs-bench"),
    ("zsh", "#compdef egs-bench"),
])
def test_show_completion_prints_the_shell_script(monkeypatch: pytest.MonkeyPatch,
                                                 capsys: pytest.CaptureFixture[str], shell: str,
                                                 marker: str) -> None:
    # typer's switch to take the shell as a value instead of detecting the parent process's
    monkeypatch.setenv("_TYPER_COMPLETE_TEST_DISABLE_SHELL_DETECTION", "1")
    assert main(["--show-completion", shell]) == 0
    script = capsys.readouterr().out
    assert marker in script
    assert "_EGS_BENCH_COMPLETE=complete_" + shell in script


def test_completion_answers_command_and_choice_names(monkeypatch: pytest.MonkeyPatch,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    """What the installed script asks the command: candidates for the word being typed."""
    monkeypatch.setenv("_EGS_BENCH_COMPLETE", "complete_bash")
    monkeypatch.setenv("COMP_WORDS", "egs-bench demo --preset ")
    monkeypatch.setenv("COMP_CWORD", "3")
    assert main([]) == 0
    assert capsys.readouterr().out.split() == ["auto", "paper", "cpu"]
    monkeypatch.setenv("COMP_WORDS", "egs-bench make-")
    monkeypatch.setenv("COMP_CWORD", "1")
    assert main([]) == 0
    # commands come in registration order, which depends on what was imported first
    assert sorted(capsys.readouterr().out.split()) == ["make-calib", "make-eventreplica",
                                                       "make-synthetic"]
