"""The one rule for where a run folder goes (``egs_bench.runs.locations``), as ``run``, the
demo and sweeps use it."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

from egs_bench.datasets.sequence import Sequence
from egs_bench.runs import registry
from egs_bench.runs.locations import folder_name, relative_run_path, run_location
from tests.helpers.cli import run_cli


def test_runs_sit_under_sequence_then_method_then_variant_and_seed(tmp_path: Path) -> None:
    assert relative_run_path("office", "egs") == "office/egs"
    assert relative_run_path("office", "egs", variant="cpu", seed=2) == "office/egs__cpu/seed2"
    assert run_location(tmp_path, "demo-blur", "monogs") == tmp_path / "runs" / "demo-blur" / \
        "monogs"
    # a method given as module:factory, or a name with spaces or slashes, stays one level
    assert relative_run_path("my seq", "pkg.mod:make", seed=0) == "my_seq/pkg.mod_make/seed0"
    assert folder_name("a/b\\c d") == "a_b_c_d"
    assert folder_name("lambda_d=0.05+x-y") == "lambda_d=0.05+x-y"


class _RecordingMethod:
    """A method that only records the folder it was asked to write."""

    name = "place:recorder"
    description = "records its output folder"

    def __init__(self) -> None:
        self.out: Path | None = None

    def run(self, sequence: Sequence, out: Path, **_: Any) -> SimpleNamespace:
        self.out = Path(out)
        return SimpleNamespace(path=self.out)


def test_the_run_command_without_out_uses_the_rule(tiny_sequence: Path, tmp_path: Path,
                                                   monkeypatch: pytest.MonkeyPatch,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    method = _RecordingMethod()
    monkeypatch.setitem(registry._USER, method.name, method)
    monkeypatch.chdir(tmp_path)
    code, out, err = run_cli(capsys, "run", "--method", method.name, "--seq", tiny_sequence,
                             "--quiet")
    assert code == 0, err
    expected = run_location(Path(), Sequence.open(tiny_sequence).name, method.name)
    assert method.out == expected == Path("runs") / tiny_sequence.name / "place_recorder"
    assert f"run folder: {expected}" in out
