"""The SLURM backend through submitit's local executor (no cluster here): one job array, a
time limit, the worker's log in the run folder, resume by skipping finished runs."""

import json
from pathlib import Path

import pytest
import yaml

from egs_bench.experiments.spec import load_sweep
from egs_bench.experiments.sweep import run_sweep
from tests.helpers.sweep_fixtures import GOOD_PATH, make_sequence, worker_env

submitit = pytest.importorskip("submitit")


@pytest.mark.slow
def test_slurm_backend_with_submitit_local_executor(tmp_path: Path, monkeypatch: pytest.MonkeyPatch
                                                    ) -> None:
    worker_env(monkeypatch)
    monkeypatch.chdir(tmp_path)
    make_sequence(tmp_path / "data", "sa", 6, 0)
    (tmp_path / "s.yaml").write_text(yaml.safe_dump({
        "methods": [GOOD_PATH], "sequences": ["data/sa"], "seeds": [0, 1],
        "out": "out", "slurm": {"timeout_min": 5, "cpus_per_task": 1, "partition": "gpu",
                                "array_parallelism": 2,
                                "additional_parameters": {"account": "me"}}}))
    lines: list[str] = []
    report = run_sweep(load_sweep(tmp_path / "s.yaml"), backend="slurm", cluster="local",
                       say=lines.append)
    df = report.summary.set_index("run")
    assert (df["state"] == "done").all(), report.summary_md
    assert (df["action"] == "ran").all()
    assert any(line.startswith("submitted 2 job(s) (local)") for line in lines)
    jobs = json.loads((tmp_path / "out/.sweep/slurm_jobs.json").read_text())
    assert set(jobs) == {"sa/good/seed0", "sa/good/seed1"}
    for run_id in jobs:
        run_dir = tmp_path / "out/runs" / run_id
        assert "sweep run " + run_id in (run_dir / "worker.log").read_text()
        assert json.loads((run_dir / "sweep.json").read_text())["threads"] == "1"
    # submitit's own logs and pickles stay in the sweep's state folder
    assert list((tmp_path / "out/.sweep/submitit").rglob("*_log.out"))
    again = run_sweep(load_sweep(tmp_path / "s.yaml"), backend="slurm", cluster="local",
                      say=lines.append)
    assert (again.summary["action"] == "skipped").all()  # nothing resubmitted



def test_slurm_backend_needs_submitit(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import sys

    from egs_bench.errors import ConfigError
    from egs_bench.experiments.backends import run_slurm
    from egs_bench.experiments.spec import SlurmOptions

    monkeypatch.setitem(sys.modules, "submitit", None)  # as if not installed
    with pytest.raises(ConfigError, match=r"pip install 'egs-bench\[slurm\]'"):
        run_slurm([], SlurmOptions())
