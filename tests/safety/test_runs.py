"""Run folders under concurrency and interruption: one writer at a time, stale ``running`` states
read as ``interrupted``, SIGTERM handled like Ctrl-C, evaluation of what an interrupted run
wrote."""

from __future__ import annotations

import json
import signal
import socket
import subprocess
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from egs_bench.errors import InputError, OutputError
from egs_bench.eval.evaluate import evaluate_run
from egs_bench.runs import coordination
from egs_bench.runs.folder import RunFolder
from tests.helpers.cli import assert_cli_error, run_cli
from tests.helpers.safety_helpers import QUICK_RUN, python_subprocess, wait_for


def _status(run_dir: Path) -> dict:
    path = run_dir / "status.json"
    return json.loads(path.read_text()) if path.is_file() else {}


def _start_slow_run(seq: Path, out: Path, cwd: Path) -> subprocess.Popen:
    """``egs-bench run`` in another process, kept busy in its initial mapping."""
    argv = ["run", "--method", "monogs", "--seq", str(seq), "--out", str(out), *QUICK_RUN,
            "--set", "init_iters=100000"]
    proc = python_subprocess(f"import sys; from egs_bench.cli import main; "
                             f"sys.exit(main({argv!r}))", cwd)
    wait_for(lambda: _status(out).get("state") == "running", proc)
    return proc


def test_a_second_writer_is_refused_and_a_killed_run_reads_as_interrupted(
        tmp_path: Path, room_sequence: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "run"
    proc = _start_slow_run(room_sequence, out, tmp_path)
    try:
        # a second run into the same folder while the first is running
        code, _, err = run_cli(capsys, "run", "--method", "monogs", "--seq", room_sequence,
                               "--out", out, *QUICK_RUN, "--overwrite")
        assert_cli_error(code, err, 2, out,
                         f"is being written by another egs-bench process (pid {proc.pid} on ")
        code, _, err = run_cli(capsys, "eval", out)
        assert_cli_error(code, err, 3, out, f"run is still running (pid {proc.pid} on ")
        # SIGKILL (no chance to clean up) leaves status.json at "running"
        proc.send_signal(signal.SIGKILL)
        proc.wait(30)
    finally:
        proc.kill()
        proc.communicate()
    assert _status(out)["state"] == "running"
    status = RunFolder.open(out).read_status()
    assert status.state == "interrupted" and "stopped without finishing" in (status.reason or "")
    code, _, err = run_cli(capsys, "eval", out)
    assert_cli_error(code, err, 3, out, "run was interrupted",
                     "before it wrote trajectory.txt: nothing to evaluate")
    code, _, err = run_cli(capsys, "run", "--method", "monogs", "--seq", room_sequence,
                           "--out", out, *QUICK_RUN)
    assert_cli_error(code, err, 2, f"{out}: already exists; pass --overwrite")
    code, _, err = run_cli(capsys, "run", "--method", "monogs", "--seq", room_sequence,
                           "--out", out, *QUICK_RUN, "--overwrite")
    assert code == 0, err
    assert RunFolder.open(out).read_status().state == "done"


def test_sigterm_marks_the_run_interrupted(tmp_path: Path, room_sequence: Path) -> None:
    out = tmp_path / "run"
    proc = _start_slow_run(room_sequence, out, tmp_path)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 128 + signal.SIGTERM, err
    assert "interrupted by SIGTERM" in err and "Traceback" not in err
    status = RunFolder.open(out).read_status()
    assert status.state == "interrupted" and status.reason == "interrupted by SIGTERM"
    assert "INTERRUPTED: interrupted by SIGTERM" in (out / "log.txt").read_text()


def test_interrupted_run_is_scored_on_what_it_wrote(done_run: RunFolder, tmp_path: Path,
                                                    room_sequence: Path) -> None:
    seq_frames = len(done_run.read_trajectory())
    run = RunFolder.create(tmp_path / "partial", method="m", sequence_name="s",
                           sequence_path=room_sequence)
    traj = done_run.read_trajectory()
    run.write_trajectory(traj.timestamps[:3], traj.poses[:3])
    run.write_render(2, done_run.read_render(2))  # frame 0, which the protocol scores, is missing
    run.mark_interrupted("interrupted by SIGTERM")
    m = evaluate_run(run.path)
    assert m["ate"]["n_matched"] == 3 and m["coverage"]["frames_processed"] == 3 < seq_frames
    assert any("interrupted (interrupted by SIGTERM); metrics cover what it wrote" in n
               for n in m["notes"])
    assert m["rendering"] is None and any("lacks 1 of the renders" in n for n in m["notes"])


def test_running_state_from_another_host_needs_a_recent_heartbeat(done_run: RunFolder) -> None:
    now = time.time()

    def write(heartbeat_age_s: float) -> None:
        stamp = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(now - heartbeat_age_s))
        (done_run.path / "status.json").write_text(json.dumps({
            "state": "running", "reason": None, "tracking_lost": False, "updated_utc": stamp,
            "pid": 1, "host": socket.gethostname() + "-elsewhere", "heartbeat_utc": stamp}))

    write(60)
    assert done_run.read_status().state == "running"
    write(coordination.STALE_AFTER_S + 60)
    status = done_run.read_status()
    assert status.state == "interrupted" and "no heartbeat from pid 1 on" in (status.reason or "")
    with pytest.raises(InputError, match="still running"):
        write(60)
        evaluate_run(done_run.path)


def test_heartbeat_refreshes_while_running_and_stops_at_the_end(tmp_path: Path, tiny_sequence: Path,
                                                                monkeypatch: pytest.MonkeyPatch
                                                                ) -> None:
    ticks = iter(f"2026-01-01T00:00:{s:02d}Z" for s in range(60))
    monkeypatch.setattr(coordination, "HEARTBEAT_S", 0.02)
    monkeypatch.setattr(coordination, "_now_utc", lambda: next(ticks))
    run = RunFolder.create(tmp_path / "r", method="m", sequence_name="s",
                           sequence_path=tiny_sequence)
    first = _status(run.path)["heartbeat_utc"]
    deadline = time.monotonic() + 10
    while _status(run.path)["heartbeat_utc"] == first and time.monotonic() < deadline:
        time.sleep(0.01)
    assert _status(run.path)["heartbeat_utc"] != first
    assert _status(run.path)["updated_utc"] == first  # the state did not change
    run.mark_done()
    assert f"heartbeat {run.path}" not in {t.name for t in threading.enumerate()}
    assert _status(run.path)["state"] == "done"


def test_library_create_is_locked_too(tmp_path: Path, tiny_sequence: Path) -> None:
    first = RunFolder.create(tmp_path / "r", method="m", sequence_name="s",
                             sequence_path=tiny_sequence)
    with pytest.raises(OutputError, match=r"is being written by another egs-bench process "
                                          r"\(pid \d+ on "):
        RunFolder.create(tmp_path / "r", method="m", sequence_name="s",
                         sequence_path=tiny_sequence, overwrite=True)
    first.mark_failed("test")
    with pytest.raises(OutputError, match="already exists; pass --overwrite"):
        RunFolder.create(tmp_path / "r", method="m", sequence_name="s",
                         sequence_path=tiny_sequence)
    again = RunFolder.create(tmp_path / "r", method="m", sequence_name="s",
                             sequence_path=tiny_sequence, overwrite=True)
    assert again.read_status().state == "running"
    again.mark_done()


def test_max_frames_zero_and_an_event_method_without_events_are_refused(
        seq_copy: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run_cli(capsys, "run", "--method", "monogs", "--seq", seq_copy, "--out",
                           tmp_path / "r0", "--max-frames", "0", "--quiet")
    assert_cli_error(code, err, 2, "Invalid value for '--max-frames'", "greater than or equal to 1")
    assert not (tmp_path / "r0").exists()
    meta = seq_copy / "meta.yaml"
    meta.write_text(meta.read_text().replace("has_events: true", "has_events: false"))
    code, _, err = run_cli(capsys, "run", "--method", "egs", "--seq", seq_copy, "--out",
                           tmp_path / "r1", *QUICK_RUN)
    assert_cli_error(code, err, 3, f"{meta}: has_events is false, but the method uses events "
                     "(event_tracking, event_mapping)")
    assert not (tmp_path / "r1").exists()


def test_user_methods_without_overwrite_support_are_told_so(tmp_path: Path, tiny_sequence: Path,
                                                            capsys: pytest.CaptureFixture[str],
                                                            monkeypatch: pytest.MonkeyPatch
                                                            ) -> None:
    (tmp_path / "plain_method.py").write_text(
        "class M:\n    name = 'plain'\n    description = 'no overwrite'\n"
        "    def run(self, sequence, out, *, preset, device, seed, max_frames, progress):\n"
        "        raise AssertionError('must not run')\n"
        "METHOD = M()\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    code, _, err = run_cli(capsys, "run", "--method", "plain_method:METHOD", "--seq", tiny_sequence,
                           "--out", tmp_path / "r", "--overwrite")
    assert_cli_error(code, err, 2, "plain", "does not support --overwrite")
    assert np.all([not (tmp_path / "r").exists()])


def test_a_signal_surfacing_inside_numba_exits_as_an_interruption(monkeypatch: pytest.MonkeyPatch,
                                                                  capsys: pytest.CaptureFixture[str]
                                                                  ) -> None:
    """numba turns a signal handler's exception into ``SystemError: ... returned a result with
    an exception set`` (the interruption as its cause): the CLI must exit 128 + 15 with one
    line, not report an internal error (70)."""
    from egs_bench.datasets import synthetic
    from tests.helpers.interrupt_helpers import raise_sigterm_as_numba_does

    monkeypatch.setattr(synthetic, "list_scenes", raise_sigterm_as_numba_does)
    code, _, err = run_cli(capsys, "list-scenes")
    assert code == 143, err
    assert err.strip() == "interrupted by SIGTERM"


def test_progress_rides_on_the_heartbeat_and_stays_in_the_final_status(
        tmp_path: Path, tiny_sequence: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``set_progress`` writes nothing itself; the next heartbeat carries it (what a sweep
    status shows for a long run) and the final state keeps where the run ended."""
    monkeypatch.setattr(coordination, "HEARTBEAT_S", 0.02)
    run = RunFolder.create(tmp_path / "r", method="m", sequence_name="s",
                           sequence_path=tiny_sequence)
    assert "progress" not in _status(run.path) and run.read_status().progress_text() == ""
    run.set_progress(123, 300)
    deadline = time.monotonic() + 10
    while "progress" not in _status(run.path) and time.monotonic() < deadline:
        time.sleep(0.01)
    assert _status(run.path)["progress"] == {"done": 123, "total": 300}
    status = run.read_status()
    assert status.state == "running" and status.progress_text() == "frame 123/300"
    run.set_progress(124, 300)
    run.mark_interrupted("interrupted by SIGTERM")
    assert run.read_status().progress == (124, 300)


@pytest.mark.parametrize("progress", [{"done": 4}, {"done": 5, "total": 4}, [1, 2],
                                      {"done": -1, "total": 4}, {"done": True, "total": 4}])
def test_a_malformed_progress_names_the_file(done_run: RunFolder, progress: Any) -> None:
    data = _status(done_run.path)
    (done_run.path / "status.json").write_text(json.dumps({**data, "progress": progress}))
    with pytest.raises(InputError, match="status.json.*'progress' must be"):
        done_run.read_status()
