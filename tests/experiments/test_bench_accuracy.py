"""``benchmarks/bench_slam_accuracy.py`` end to end with fast fake methods: a relative
``--out``, ``--status`` before anything ran (pending rows, nothing started), the run and its
egs/monogs ratio, and a second invocation that resumes instead of rerunning."""

import subprocess
import sys
from pathlib import Path

import pandas as pd
from sweep_fixtures import make_sequence, worker_env

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_slam_accuracy.py"
METHODS = "sweep_fixtures:FAKE_EGS,sweep_fixtures:FAKE_MONOGS"


def _bench(*extra: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(SCRIPT), "--seq", "data/sa", "--methods", METHODS,
                           "--out", "out", *extra], cwd=cwd, capture_output=True, text=True,
                          timeout=300)


def test_status_run_and_resume(tmp_path: Path, monkeypatch) -> None:
    worker_env(monkeypatch)
    make_sequence(tmp_path / "data", "sa", 8, 0)

    status = _bench("--status", cwd=tmp_path)
    assert status.returncode == 0, status.stderr
    pending = pd.read_csv(tmp_path / "out/runs.csv")
    assert list(pending["error"]) == ["pending: not started"] * 2
    assert not (tmp_path / "out/runs").exists() or not any((tmp_path / "out/runs").rglob("*.json"))
    assert "ATE(egs)/ATE(monogs)" not in status.stdout

    first = _bench(cwd=tmp_path)
    assert first.returncode == 0, first.stderr
    runs = pd.read_csv(tmp_path / "out/runs.csv").set_index("method")
    assert set(runs.index) == {"egs", "monogs"}
    assert runs["ate_cm"].notna().all() and "error" not in runs
    # the fake estimates are the ground truth plus 1 cm / 3 cm of noise per axis
    assert runs.loc["egs", "ate_cm"] < runs.loc["monogs", "ate_cm"]
    ratio = runs.loc["egs", "ate_cm"] / runs.loc["monogs", "ate_cm"]
    assert f"sa: ATE(egs)/ATE(monogs) = {ratio:.3f}" in first.stdout
    assert (tmp_path / "out/accuracy.md").read_text().count("| sa ") == 2

    first_csv = (tmp_path / "out/runs.csv").read_text()
    again = _bench(cwd=tmp_path)
    assert again.returncode == 0, again.stderr
    assert "2 runs, 2 in this invocation, 0 to run" in again.stdout
    assert (tmp_path / "out/runs.csv").read_text() == first_csv
