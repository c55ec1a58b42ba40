"""The small ones: a named completion shell, an ``--overwrite`` that replaces only what
``ate`` wrote, a corrupt sweep record named as unreadable."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from tests.helpers.cli import assert_cli_error, run_cli


@pytest.mark.parametrize("shell,marker", [("zsh", "#compdef egs-bench"),
                                          ("bash", "complete -o default -F"),
                                          ("fish", "complete --command egs-bench")])
def test_show_completion_prints_the_named_shells_script(shell: str, marker: str,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run_cli(capsys, "--show-completion", shell)
    assert code == 0, err
    assert marker in out, out


@pytest.fixture
def trajectories(room_sequence: Path, tmp_path: Path) -> tuple[Path, Path]:
    gt = room_sequence / "groundtruth.txt"
    est = Path(shutil.copyfile(gt, tmp_path / "est.txt"))
    return gt, est


def test_ate_overwrite_replaces_only_an_ate_results_file(trajectories: tuple[Path, Path],
                                                         tmp_path: Path,
                                                         capsys: pytest.CaptureFixture[str]
                                                         ) -> None:
    gt, est = trajectories
    report = tmp_path / "report.json"
    report.write_text(json.dumps({"generator": "egs-bench report", "runs": []}))
    before = report.read_bytes()
    code, _, err = run_cli(capsys, "ate", gt, est, "--save_results", report, "--overwrite")
    assert_cli_error(code, err, 2, f"{report}: is not an ATE/RPE results file written by "
                                   "egs-bench: --overwrite only replaces")
    assert report.read_bytes() == before
    results = tmp_path / "ate.json"
    for _ in range(2):  # written, then replaced
        code, _, err = run_cli(capsys, "ate", gt, est, "--save_results", results, "--overwrite")
        assert code == 0, err
    assert json.loads(results.read_text())["metric"] == "ATE"


def test_a_corrupt_sweep_record_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                         ) -> None:
    from tests.helpers.sweep_fixtures import make_sequence

    seq = make_sequence(tmp_path, "sa", frames=5)
    sweep = tmp_path / "s.yaml"
    sweep.write_text(f"methods: ['tests.helpers.sweep_fixtures:GOOD']\nsequences: [{seq}]\n")
    record = tmp_path / "out" / "runs" / "sa" / "good" / "seed0" / "sweep.json"
    record.parent.mkdir(parents=True)
    record.write_bytes(b'{"run_id": "sa/good/se')  # cut short
    code, out, err = run_cli(capsys, "sweep", sweep, "-o", tmp_path / "out", "--dry-run")
    assert code == 0, err
    assert f"{record}: unreadable" in out, out
    assert record.read_bytes() == b'{"run_id": "sa/good/se'
