"""`egs-bench sweep` as docs/guide/experiments.md describes it: `--dry-run` writes
nothing, `--status` exits 1 unless every run is done, and the submitit backend leaves no
literal `%j` folder."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from egs_bench.cli import main
from tests.helpers.sweep_fixtures import GOOD_PATH, make_sequence, worker_env


@pytest.fixture
def sweep_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    worker_env(monkeypatch)
    make_sequence(tmp_path / "data", "sa", 6, 0)
    monkeypatch.chdir(tmp_path)
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({"methods": [GOOD_PATH],
                                    "sequences": ["data/sa"], "seeds": [0], "out": "out",
                                    "local": {"jobs": 1}}))
    return path


def test_dry_run_writes_nothing(sweep_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                ) -> None:
    out = tmp_path / "out"
    assert main(["sweep", str(sweep_file), "--dry-run"]) == 0
    assert "would run sa/good/seed0" in capsys.readouterr().out
    assert not (out / "sweep_summary.md").exists() and not (out / "sweep_summary.csv").exists()

    assert main(["sweep", str(sweep_file)]) == 0
    summary = (out / "sweep_summary.md").read_text()
    assert main(["sweep", str(sweep_file), "--dry-run"]) == 0
    assert (out / "sweep_summary.md").read_text() == summary  # the real summary stays


def test_status_exits_1_unless_every_run_is_done(sweep_file: Path, tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    assert main(["sweep", str(sweep_file), "--status"]) == 1  # pending: not complete
    assert main(["sweep", str(sweep_file)]) == 0
    assert main(["sweep", str(sweep_file), "--status"]) == 0
    status_file = out / "runs/sa/good/seed0/status.json"
    status = json.loads(status_file.read_text())
    status.update(state="interrupted", reason="interrupted by SIGTERM")
    status_file.write_text(json.dumps(status))
    capsys.readouterr()
    assert main(["sweep", str(sweep_file), "--status"]) == 1
    assert "interrupted" in capsys.readouterr().out


@pytest.mark.slow
def test_submitit_leaves_no_literal_job_id_folder(sweep_file: Path, tmp_path: Path) -> None:
    pytest.importorskip("submitit")
    assert main(["sweep", str(sweep_file), "--backend", "slurm", "--cluster", "local"]) == 0
    state = tmp_path / "out/.sweep/submitit"
    assert list(state.rglob("*_log.out"))
    assert not [p for p in state.rglob("*") if "%j" in p.name]
