import json
from pathlib import Path

import numpy as np
import pytest

from egs_bench.errors import InputError, OutputError
from egs_bench.geometry import pose_from_tq
from egs_bench.runs.folder import RunFolder, find_runs


def _poses(n: int) -> np.ndarray:
    t = np.stack([np.linspace(0, 1, n), np.zeros(n), np.zeros(n)], axis=1)
    return pose_from_tq(t, np.tile([0.0, 0.0, 0.0, 1.0], (n, 1)))


def test_run_folder_roundtrip(tmp_path: Path) -> None:
    run = RunFolder.create(tmp_path / "r", method="egs", sequence_name="office0",
                           sequence_path=tmp_path / "seq", config={"lr": np.float32(0.5)})
    assert run.read_status().state == "running"
    run.write_trajectory(np.arange(4) * 0.1, _poses(4))
    run.write_keyframes([3, 0, 0])
    img = np.zeros((4, 6, 3), np.uint8)
    img[1, 2] = (10, 20, 30)
    run.write_render(5, img)
    run.write_timing(total_wall_s=2.0, per_frame_s=[0.5] * 4, render_fps=100.0)
    run.log("hello")
    run.mark_done()

    again = RunFolder.open(tmp_path / "r")
    assert again.method == "egs" and again.sequence_name == "office0"
    assert again.sequence_path == (tmp_path / "seq").resolve()
    assert again.read_config() == {"lr": 0.5}
    assert len(again.read_trajectory()) == 4
    np.testing.assert_array_equal(again.read_keyframes(), [0, 3])
    assert again.render_indices() == [5]
    np.testing.assert_array_equal(again.read_render(5), img)
    timing = again.read_timing()
    assert timing is not None and timing.fps == 2.0 and timing.render_fps == 100.0
    assert again.read_status().state == "done"
    assert "hello" in again.log_path.read_text()
    hidden = [p.relative_to(again.path) for p in again.path.rglob(".*")]
    assert hidden == [Path(".lock")]  # no temporary file left by the atomic writes
    assert find_runs(tmp_path) == [tmp_path / "r"]


def test_run_folder_failure_guard_and_overwrite(tmp_path: Path) -> None:
    run = RunFolder.create(tmp_path / "r", method="m", sequence_name="s", sequence_path=tmp_path)
    with pytest.raises(RuntimeError), run.failure_guard():
        raise RuntimeError("diverged at frame 7")
    status = run.read_status()
    assert status.state == "failed" and "diverged at frame 7" in (status.reason or "")
    with pytest.raises(OutputError, match="already exists; pass --overwrite"):
        RunFolder.create(tmp_path / "r", method="m", sequence_name="s", sequence_path=tmp_path)
    RunFolder.create(tmp_path / "r", method="m", sequence_name="s", sequence_path=tmp_path,
                     overwrite=True)
    assert RunFolder.open(tmp_path / "r").read_status().state == "running"


def test_run_folder_bad_inputs(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="run folder not found"):
        RunFolder.open(tmp_path / "nope")
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="not a run folder"):
        RunFolder.open(tmp_path / "empty")
    run = RunFolder.create(tmp_path / "r", method="m", sequence_name="s", sequence_path=tmp_path)
    with pytest.raises(InputError, match="estimated trajectory not found"):
        run.read_trajectory()
    with pytest.raises(InputError, match="render of frame 3 not found"):
        run.read_render(3)
    (run.path / "status.json").write_text(json.dumps({"state": "weird"}))
    with pytest.raises(InputError, match="state must be one of"):
        run.read_status()


def test_signal_surfacing_as_a_numba_system_error_marks_the_run_interrupted(tmp_path: Path) -> None:
    """A SIGTERM that arrived while numba ran ``bin_tiles`` stopped a sweep's run with
    ``SystemError: CPUDispatcher(...) returned a result with an exception set``, the
    interruption being its cause, and the run read ``failed`` (a sweep keeps those). It must
    read ``interrupted`` (a sweep reruns those), and the interruption must propagate."""
    from egs_bench.errors import Interrupted
    from tests.helpers.interrupt_helpers import raise_sigterm_as_numba_does

    run = RunFolder.create(tmp_path / "r", method="m", sequence_name="s", sequence_path=tmp_path)
    with pytest.raises(Interrupted) as info, run.failure_guard():
        raise_sigterm_as_numba_does()
    assert info.value.exit_code == 143
    status = run.read_status()
    assert status.state == "interrupted" and status.reason == "interrupted by SIGTERM"


def test_signal_after_mark_done_keeps_the_run_done(tmp_path: Path) -> None:
    """A SIGTERM that lands after ``mark_done`` but inside ``failure_guard`` (a sweep's kill
    arriving while the worker leaves the block) propagates but leaves the run ``done``: its
    outputs are complete, and an ``interrupted`` status would make a sweep compute it again."""
    import signal

    from egs_bench.errors import Interrupted

    run = RunFolder.create(tmp_path / "r", method="m", sequence_name="s", sequence_path=tmp_path)
    with pytest.raises(Interrupted), run.failure_guard():
        run.write_trajectory(np.arange(3) * 0.1, _poses(3))
        run.mark_done()
        raise Interrupted(signal.SIGTERM)
    assert run.read_status().state == "done"
    with pytest.raises(RuntimeError), run.failure_guard():
        raise RuntimeError("after done")
    assert run.read_status().state == "done"
