"""Sweeps on the local pool: a 2-method x 2-sequence x 2-seed sweep killed and resumed with the
same command, stale and conflicting folders never reused, failures, retries and time limits."""

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
import yaml

from egs_bench.eval.leaderboard import collect, render_markdown
from egs_bench.experiments.spec import RunSpec, load_sweep
from egs_bench.experiments.sweep import run_sweep
from egs_bench.experiments.worker import lock_is_held
from egs_bench.slam.config import cpu_preset
from tests.helpers.sweep_fixtures import BAD_PATH, GOOD_PATH, make_sequence, worker_env

EGS_BENCH = [sys.executable, "-c", "from egs_bench.cli import run; run()"]


@pytest.fixture
def sweep_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    worker_env(monkeypatch)
    make_sequence(tmp_path / "data", "sa", 8, 0)
    make_sequence(tmp_path / "data", "sb", 8, 1)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _write(path: Path, data: dict) -> Path:
    path.write_text(yaml.safe_dump(data))
    return path


def _records(out: Path) -> dict[str, dict]:
    return {str(p.parent.relative_to(out / "runs")): json.loads(p.read_text())
            for p in (out / "runs").rglob("sweep.json")}


@pytest.mark.slow
def test_sweep_survives_kill_and_resumes(sweep_dir: Path) -> None:
    sweep = _write(sweep_dir / "s.yaml", {
        "methods": [GOOD_PATH, BAD_PATH],
        "sequences": ["data/sa", "data/sb"], "seeds": [0, 1], "local": {"jobs": 2}})
    out = sweep_dir / "sweeps" / "s"
    env = {**os.environ, "FAKE_SLEEP_S": "2"}
    proc = subprocess.Popen([*EGS_BENCH, "sweep", str(sweep)], env=env, start_new_session=True,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:  # kill the launcher and its workers mid-sweep
        states = [r.get("state") for r in _records(out).values()] if out.exists() else []
        if states.count("done") >= 2 and "running" in states:
            break
        time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    specs = [RunSpec.from_dict(json.loads(p.read_text()))
             for p in (out / ".sweep/specs").glob("*.json")]
    deadline = time.monotonic() + 30  # the killed workers' locks go with their processes
    while any(lock_is_held(s) for s in specs) and time.monotonic() < deadline:
        time.sleep(0.1)
    before = _records(out)
    finished = {k: r["finished_utc"] for k, r in before.items() if r.get("state") == "done"}
    assert 2 <= len(finished) < 8, before

    # the same command resumes: finished runs are skipped, killed and pending ones run
    report = run_sweep(load_sweep(sweep), say=lambda m: None)
    df = report.summary.set_index("run")
    assert (df["state"] == "done").all(), report.summary_md
    assert len(df) == 8
    after = _records(out)
    for key, stamp in finished.items():
        assert df.loc[key, "action"] == "skipped"
        assert after[key]["finished_utc"] == stamp  # not rerun
    assert (df["action"] == "ran").sum() == 8 - len(finished)
    assert (out / "sweep_summary.md").read_text() == report.summary_md
    csv = pd.read_csv(out / "sweep_summary.csv")
    assert list(csv.columns[:8]) == ["run", "method", "sequence", "settings", "seed", "state",
                                     "action", "wall_s"]
    assert csv["wall_s"].gt(0).all()

    # the runs aggregate into mean +- std over the two seeds
    md = render_markdown(collect(out / "runs"))
    assert "mean ± std over 2 runs" in md
    good = next(line for line in md.splitlines() if line.startswith("| good"))
    assert good.count("±") == 8 and "**" in good

    # a changed configuration is never silently reused: stale, folders untouched, exit 1
    changed = _write(sweep_dir / "s.yaml", {**yaml.safe_load(sweep.read_text()), "max_frames": 5})
    cli = subprocess.run([*EGS_BENCH, "sweep", str(changed)], capture_output=True, text=True)
    assert cli.returncode == 1, cli.stdout + cli.stderr
    assert cli.stdout.count("| stale") == 8 and "rerun with --force" in cli.stdout
    assert _records(out) == after


def _sweep_stopped_after_the_method(sweep_dir: Path) -> tuple[Path, subprocess.Popen, Path]:
    """Start a one-run sweep whose method sleeps after marking its folder done; return the
    sweep file, the launcher and the run folder once the method is done (evaluation pending)."""
    sweep = _write(sweep_dir / "e.yaml", {"methods": [GOOD_PATH],
                                          "sequences": ["data/sa"], "out": "out"})
    run_dir = sweep_dir / "out/runs/sa/good/seed0"
    env = {**os.environ, "FAKE_SLEEP_AFTER_S": "60"}
    proc = subprocess.Popen([*EGS_BENCH, "sweep", str(sweep)], env=env, start_new_session=True,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    # a wait bound, not a tolerance (the method reaches "done" in ~5 s on one core): past it
    # the test fails here instead of stopping a run that never got there and then reading
    # the legitimate rerun as a wrongly rerun finished run
    deadline = time.monotonic() + 300
    while not ((run_dir / "status.json").is_file()
               and json.loads((run_dir / "status.json").read_text())["state"] == "done"):
        assert time.monotonic() < deadline and proc.poll() is None, (
            f"the sweep's method did not mark {run_dir} done (launcher exit code {proc.poll()})")
        time.sleep(0.05)
    return sweep, proc, run_dir


@pytest.mark.slow
def test_run_interrupted_after_the_method_finished_is_only_evaluated(sweep_dir: Path) -> None:
    """SIGTERM after the method marked its folder done (before the evaluation): the next
    invocation evaluates the kept outputs instead of rerunning the method."""
    sweep, proc, run_dir = _sweep_stopped_after_the_method(sweep_dir)
    os.killpg(proc.pid, signal.SIGTERM)
    proc.wait(timeout=60)
    record = json.loads((run_dir / "sweep.json").read_text())
    assert record["state"] == "interrupted" and not (run_dir / "metrics.json").exists()
    trajectory = (run_dir / "trajectory.txt").stat()

    report = run_sweep(load_sweep(sweep), say=lambda m: None)
    row = report.summary.set_index("run").loc["sa/good/seed0"]
    assert row["state"] == "done" and row["action"] == "ran", report.summary_md
    assert (run_dir / "trajectory.txt").stat().st_mtime_ns == trajectory.st_mtime_ns
    assert (run_dir / "trajectory.txt").stat().st_ino == trajectory.st_ino  # not rerun
    assert json.loads((run_dir / "metrics.json").read_text())["ate"]["rmse_m"] > 0
    record = json.loads((run_dir / "sweep.json").read_text())
    assert record["state"] == "done" and record["evaluated"] and record["run_wall_s"] > 0
    assert "evaluation of finished run sa/good/seed0" in (run_dir / "worker.log").read_text()


def test_repeated_sigterms_do_not_leave_the_run_recorded_running(sweep_dir: Path) -> None:
    """``kill`` of the process group, then the pool stopping its workers: a worker gets several
    SIGTERMs. One arriving while the first was being recorded killed the worker with its record
    still ``running`` (this burst caught the old code in 1 of 6 tries; the deterministic check
    is in test_sweep_spec.py)."""
    _, proc, run_dir = _sweep_stopped_after_the_method(sweep_dir)
    worker_pid = json.loads((run_dir / "sweep.json").read_text())["pid"]
    for _ in range(40):
        with contextlib.suppress(ProcessLookupError):
            os.kill(worker_pid, signal.SIGTERM)
        time.sleep(0.0005)
    proc.wait(timeout=60)
    assert json.loads((run_dir / "sweep.json").read_text())["state"] == "interrupted"


@pytest.mark.slow
def test_sweep_failures_conflicts_and_retries(sweep_dir: Path, monkeypatch: pytest.MonkeyPatch
                                              ) -> None:
    data = {"methods": [GOOD_PATH], "sequences": ["data/sa"], "seeds": [0, 1, 2],
            "local": {"jobs": 2}, "out": "out"}
    sweep = _write(sweep_dir / "f.yaml", data)
    out = sweep_dir / "out"
    foreign = out / "runs" / "sa" / "good" / "seed0"
    foreign.mkdir(parents=True)
    (foreign / "notes.txt").write_text("a user's file")
    monkeypatch.setenv("FAKE_FAIL", "good:1")
    monkeypatch.setenv("FAKE_LOST", "good:2")
    report = run_sweep(load_sweep(sweep), say=lambda m: None)
    df = report.summary.set_index("run")
    assert df.loc["sa/good/seed0", "state"] == "conflict"
    assert "not created by this sweep" in df.loc["sa/good/seed0", "reason"]
    assert (foreign / "notes.txt").read_text() == "a user's file"
    assert sorted(p.name for p in foreign.iterdir()) == ["notes.txt"]
    assert df.loc["sa/good/seed1", "state"] == "failed"
    assert df.loc["sa/good/seed1", "reason"] == "RuntimeError: injected failure"
    assert df.loc["sa/good/seed2", "state"] == "tracking_lost"
    assert "injected tracking loss" in df.loc["sa/good/seed2", "reason"]
    assert not report.all_done

    monkeypatch.delenv("FAKE_FAIL")
    monkeypatch.delenv("FAKE_LOST")
    again = run_sweep(load_sweep(sweep), say=lambda m: None).summary.set_index("run")
    assert again.loc["sa/good/seed1", "state"] == "failed"  # kept without --retry-failed
    assert again.loc["sa/good/seed1", "action"] == ""
    retried = run_sweep(load_sweep(sweep), retry_failed=True, say=lambda m: None)
    df = retried.summary.set_index("run")
    assert df.loc["sa/good/seed1", "state"] == "done" == df.loc["sa/good/seed2", "state"]
    assert df.loc["sa/good/seed0", "state"] == "conflict"

    # --force reruns a stale run (a folder this sweep made) but never the foreign one
    changed = _write(sweep_dir / "f.yaml", {**data, "seeds": [0, 1], "max_frames": 5})
    stale = run_sweep(load_sweep(changed), say=lambda m: None).summary.set_index("run")
    assert stale.loc["sa/good/seed1", "state"] == "stale"
    forced = run_sweep(load_sweep(changed), force=True, say=lambda m: None)
    df = forced.summary.set_index("run")
    assert df.loc["sa/good/seed1", "state"] == "done" and df.loc["sa/good/seed1", "action"] == "ran"
    assert json.loads((out / "runs/sa/good/seed1/sweep.json").read_text())["identity"][
        "max_frames"] == 5
    assert df.loc["sa/good/seed0", "state"] == "conflict"
    assert (foreign / "notes.txt").read_text() == "a user's file"


@pytest.mark.slow
def test_sweep_time_limit_and_dry_run(sweep_dir: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    sweep = _write(sweep_dir / "t.yaml", {"methods": [GOOD_PATH],
                                          "sequences": ["data/sa"], "seeds": [0],
                                          "local": {"timeout_min": 0.15}, "out": "out"})
    lines: list[str] = []
    dry = run_sweep(load_sweep(sweep), dry_run=True, say=lines.append)
    assert "would run sa/good/seed0 (new)" in lines and dry.summary["state"].tolist() == \
        ["pending"]
    monkeypatch.setenv("FAKE_SLEEP_S", "120")
    t0 = time.monotonic()
    report = run_sweep(load_sweep(sweep), say=lambda m: None)
    assert time.monotonic() - t0 < 60
    row = report.summary.iloc[0]
    assert row["state"] == "timeout" and row["action"] == "timeout"
    assert "time limit of 0.15 min reached" in row["reason"]
    status = json.loads((sweep_dir / "out/runs/sa/good/seed0/status.json").read_text())
    assert status["state"] == "interrupted" and status["reason"] == "interrupted by SIGTERM"


@pytest.mark.slow
def test_sweep_of_a_builtin_method_with_named_settings(tmp_path: Path,
                                                       monkeypatch: pytest.MonkeyPatch,
                                                       tiny_sequence: Path) -> None:
    """The real MonoGS-style method on the tiny plane sequence: overrides reach the run's
    resolved configuration, and the settings names label the leaderboard rows."""
    worker_env(monkeypatch)
    monkeypatch.chdir(tmp_path)
    sweep = _write(tmp_path / "b.yaml", {
        "methods": ["monogs"], "sequences": [str(tiny_sequence)], "preset": "cpu",
        "max_frames": 3, "settings": {"base": {}, "short": {"tracking_iters": 5}},
        "local": {"jobs": 2}, "out": "out"})
    report = run_sweep(load_sweep(sweep), say=lambda m: None)
    out = tmp_path / "out/runs/plane"
    for folder in ("monogs__base", "monogs__short"):  # the method finished in both
        assert json.loads((out / folder / "seed0/status.json").read_text())["state"] == "done"
    cfg_base = yaml.safe_load((out / "monogs__base/seed0/config.yaml").read_text())
    cfg_short = yaml.safe_load((out / "monogs__short/seed0/config.yaml").read_text())
    assert cfg_short["slam"]["budget"]["tracking_iters"] == 5
    # the cpu budget's (not the other setting's)
    assert cfg_base["slam"]["budget"]["tracking_iters"] == cpu_preset().budget.tracking_iters != 5
    record = json.loads((out / "monogs__short/seed0/sweep.json").read_text())
    assert record["identity"]["resolved"] == cfg_short["slam"]
    # the plane sequence's camera moves on a line: Umeyama alignment is degenerate, so the
    # evaluation fails, which fails the run (no metrics, no result); the summary and the
    # leaderboard say why
    assert (report.summary["state"] == "failed").all(), report.summary_md
    assert report.summary["reason"].str.contains("evaluation: .*Degenerate").all()
    md = render_markdown(collect(tmp_path / "out/runs"))
    assert "| monogs (base) " in md and "| monogs (short) " in md
    assert "Umeyama alignment is not possible" in md


def test_ctrl_c_stops_workers_and_they_rerun(sweep_dir: Path) -> None:
    sweep = _write(sweep_dir / "c.yaml", {"methods": [GOOD_PATH],
                                          "sequences": ["data/sa"], "seeds": [0],
                                          "out": "out"})
    proc = subprocess.Popen([*EGS_BENCH, "sweep", str(sweep)],
                            env={**os.environ, "FAKE_SLEEP_S": "120"},
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    record = sweep_dir / "out/runs/sa/good/seed0/sweep.json"
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and not (
            record.is_file() and json.loads(record.read_text())["state"] == "running"):
        time.sleep(0.2)
    proc.send_signal(signal.SIGINT)  # Ctrl-C reaches the launcher only
    out, _ = proc.communicate(timeout=60)
    assert proc.returncode == 130, out
    assert json.loads(record.read_text())["state"] == "interrupted"
    assert "interrupted" in (sweep_dir / "out/sweep_summary.md").read_text()
    again = run_sweep(load_sweep(sweep), say=lambda m: None)
    assert again.summary["action"].tolist() == ["ran"]
    assert again.summary["state"].tolist() == ["done"]
