"""Signals are never lost: one whose exception Python swallows (it ran inside a ``__del__`` or a
weakref callback) still stops the work before anything is published, and a repeated signal does
not abort the clean-up of the first (both seen as flaky CI failures: a SIGTERM'd generator
exited 0, a sweep run stayed "running")."""

from __future__ import annotations

import os
import signal
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from egs_bench import interrupts
from egs_bench.cli import main
from egs_bench.errors import Interrupted
from egs_bench.fileio import atomic_dir
from egs_bench.interrupts import raise_if_interrupted, received_interruption, signals_interrupt
from egs_bench.render import GaussianMap
from egs_bench.runs.folder import RunFolder
from egs_bench.slam.components import SlamComponents
from egs_bench.slam.crf import CameraResponse
from egs_bench.slam.tracker import TrackRequest, TrackResult


class _SignalsInDel:
    """Sends SIGTERM to this process from ``__del__``: the handler runs inside ``__del__``,
    where Python prints and drops its exception (as it does in a weakref callback run by the
    garbage collector)."""

    def __del__(self) -> None:
        os.kill(os.getpid(), signal.SIGTERM)


def _swallowed_sigterm() -> None:
    _SignalsInDel()  # created and collected at once; no exception reaches the caller


def test_a_swallowed_signal_is_recorded_and_raised_at_the_next_check() -> None:
    with signals_interrupt():
        _swallowed_sigterm()
        assert received_interruption() is not None
        with pytest.raises(Interrupted) as info:
            raise_if_interrupted()
    assert info.value.exit_code == 128 + signal.SIGTERM
    raise_if_interrupted()  # outside a block there is nothing to raise


def test_a_swallowed_signal_leaves_no_output_published(tmp_path: Path) -> None:
    out = tmp_path / "seq"
    with signals_interrupt(), pytest.raises(Interrupted), atomic_dir(out) as tmp:
        tmp.mkdir()
        (tmp / "frames.txt").write_text("partial\n")
        _swallowed_sigterm()
    assert list(tmp_path.iterdir()) == []  # neither the output nor a staging folder


def test_a_swallowed_signal_marks_the_run_interrupted_not_done(tmp_path: Path) -> None:
    run = RunFolder.create(tmp_path / "r", method="m", sequence_name="s", sequence_path=tmp_path)
    with signals_interrupt(), pytest.raises(Interrupted), run.failure_guard():
        _swallowed_sigterm()
        run.mark_done()
    assert run.read_status().state == "interrupted"


def _status_file(run_dir: Path) -> dict:
    import json

    return json.loads((run_dir / "status.json").read_text())


def test_a_signal_before_the_run_is_guarded_still_marks_it_interrupted(tmp_path: Path) -> None:
    """``kill`` as soon as status.json said "running": the handler ran between
    RunFolder.create and the run's failure_guard, and the run stayed "running" (seen in one of
    six tries of the SIGTERM test)."""
    out = tmp_path / "r"
    with pytest.raises(Interrupted), signals_interrupt():
        run = RunFolder.create(out, method="m", sequence_name="s", sequence_path=tmp_path)
        os.kill(os.getpid(), signal.SIGTERM)  # the handler raises at the next check
        with run.failure_guard():
            pytest.fail("the signal should have landed before the guard")
    status = _status_file(out)
    assert (status["state"], status["reason"]) == ("interrupted", "interrupted by SIGTERM")
    assert RunFolder.create(out, method="m", sequence_name="s", sequence_path=tmp_path,
                            overwrite=True).read_status().state == "running"  # lock released


def test_a_signal_inside_create_after_the_status_went_out(tmp_path: Path,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    mark_running = RunFolder.mark_running

    def mark_running_then_signal(self: RunFolder) -> None:
        mark_running(self)
        os.kill(os.getpid(), signal.SIGTERM)
        raise_if_interrupted()  # where the handler's exception lands is up to Python

    monkeypatch.setattr(RunFolder, "mark_running", mark_running_then_signal)
    out = tmp_path / "r"
    with pytest.raises(Interrupted), signals_interrupt():
        RunFolder.create(out, method="m", sequence_name="s", sequence_path=tmp_path)
    status = _status_file(out)
    assert (status["state"], status["reason"]) == ("interrupted", "interrupted by SIGTERM")
    monkeypatch.undo()
    assert RunFolder.create(out, method="m", sequence_name="s", sequence_path=tmp_path,
                            overwrite=True).read_status().state == "running"


def test_a_signal_inside_the_heartbeat_start_still_marks_and_logs(tmp_path: Path,
                                                                  monkeypatch: pytest.MonkeyPatch
                                                                  ) -> None:
    """The handler can run inside ``Thread.start()`` (it waits for the thread): the thread
    never started, and joining it raised over the clean-up (no log line, lock kept)."""
    import threading

    start = threading.Thread.start

    def start_or_signal(self: threading.Thread) -> None:
        if self.name.startswith("heartbeat"):
            raise Interrupted(signal.SIGTERM)
        start(self)

    monkeypatch.setattr(threading.Thread, "start", start_or_signal)
    out = tmp_path / "r"
    with pytest.raises(Interrupted), signals_interrupt():
        RunFolder.create(out, method="m", sequence_name="s", sequence_path=tmp_path)
    monkeypatch.undo()
    assert _status_file(out)["state"] == "interrupted"
    assert "INTERRUPTED: interrupted by SIGTERM" in (out / "log.txt").read_text()
    assert RunFolder.create(out, method="m", sequence_name="s", sequence_path=tmp_path,
                            overwrite=True).read_status().state == "running"


def test_a_generator_with_a_swallowed_signal_exits_as_interrupted(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    from egs_bench.datasets.sequence import SequenceWriter

    add_frame = SequenceWriter.add_frame

    def add_frame_then_signal(self: SequenceWriter, *args: Any, **kwargs: Any) -> None:
        add_frame(self, *args, **kwargs)
        _swallowed_sigterm()

    monkeypatch.setattr(SequenceWriter, "add_frame", add_frame_then_signal)
    code = main(["make-synthetic", "--scene", "office", "--out", str(tmp_path / "seq"),
                 "--frames", "6", "--width", "32", "--height", "24", "--no-progress"])
    assert code == 128 + signal.SIGTERM, capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_a_repeated_signal_does_not_abort_the_clean_up_of_the_first() -> None:
    cleaned = False
    with signals_interrupt(), pytest.raises(Interrupted):
        try:
            os.kill(os.getpid(), signal.SIGTERM)
        finally:
            os.kill(os.getpid(), signal.SIGTERM)  # e.g. a pool stopping its workers
            cleaned = True
    assert cleaned


def test_a_repeat_after_the_grace_period_raises_again(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(interrupts, "REPEAT_GRACE_S", 0.0)
    with signals_interrupt():
        with pytest.raises(Interrupted):
            os.kill(os.getpid(), signal.SIGTERM)
        with pytest.raises(Interrupted):
            os.kill(os.getpid(), signal.SIGTERM)


def test_handlers_are_restored_after_the_block() -> None:
    before = signal.getsignal(signal.SIGTERM)
    with signals_interrupt():
        assert signal.getsignal(signal.SIGTERM) is not before
    assert signal.getsignal(signal.SIGTERM) is before


def _register_monogs_with(monkeypatch: pytest.MonkeyPatch, name: str,
                          components: SlamComponents) -> str:
    """Register ``monogs`` with its SLAM ``components`` replaced, as ``name`` (for this test);
    the CLI runs it like any method."""
    import dataclasses

    from egs_bench.runs import registry
    from egs_bench.slam.methods import BUILTIN

    method = dataclasses.replace(BUILTIN["monogs"], name=name, components=components)
    monkeypatch.setitem(registry._USER, name, method)
    return name


def test_a_run_with_a_swallowed_signal_stops_at_the_next_frame(tmp_path: Path, room_sequence: Path,
                                                               capsys: pytest.CaptureFixture[str],
                                                               monkeypatch: pytest.MonkeyPatch
                                                               ) -> None:
    """The SLAM loop checks once per frame: a signal swallowed while frame 1 was tracked stops
    the run before frame 2, marked interrupted with the trajectory of what it processed."""
    from egs_bench.slam.components import SlamComponents
    from egs_bench.slam.tracker import GradientTracker
    from tests.helpers.safety_helpers import QUICK_RUN

    tracked: list[int] = []

    class TrackThenSignal(GradientTracker):
        def track(self, gmap: GaussianMap, crf: CameraResponse, request: TrackRequest
                  ) -> TrackResult:
            result = super().track(gmap, crf, request)
            tracked.append(result.state.index)
            if len(tracked) == 1:
                _swallowed_sigterm()
            return result

    method = _register_monogs_with(monkeypatch, "monogs-signal-in-tracking",
                                   SlamComponents(tracker=TrackThenSignal))
    out = tmp_path / "run"
    code = main(["run", "--method", method, "--seq", str(room_sequence), "--out", str(out),
                 *QUICK_RUN])
    assert code == 128 + signal.SIGTERM, capsys.readouterr().err
    assert tracked == [1]
    status = RunFolder.open(out).read_status()
    assert status.state == "interrupted" and status.reason == "interrupted by SIGTERM"
    assert len(RunFolder.open(out).read_trajectory()) == 2  # frames 0 and 1
    assert status.progress is not None and status.progress[0] == 2  # says where it stopped


def test_a_signal_swallowed_in_map_initialisation_stops_it(tmp_path: Path, room_sequence: Path,
                                                           capsys: pytest.CaptureFixture[str],
                                                           monkeypatch: pytest.MonkeyPatch) -> None:
    """Map initialisation runs minutes without reaching the frame loop: it checks every
    iteration, so a signal swallowed during its first iteration stops it at the second."""
    from egs_bench.slam.components import SlamComponents
    from egs_bench.slam.mapper import Mapper
    from tests.helpers.safety_helpers import QUICK_RUN

    mappers: list[Mapper] = []

    class SignalInFirstIteration(Mapper):
        def optimise(self, *args: Any, report: Callable[[int, int], None] | None = None,
                     **kwargs: Any) -> float:
            def report_then_signal(done: int, total: int) -> None:
                if done == 0:
                    _swallowed_sigterm()

            mappers.append(self)
            return super().optimise(*args, report=report_then_signal, **kwargs)

    method = _register_monogs_with(monkeypatch, "monogs-signal-in-map-init",
                                   SlamComponents(mapper=SignalInFirstIteration))
    out = tmp_path / "run"
    code = main(["run", "--method", method, "--seq", str(room_sequence), "--out", str(out),
                 *QUICK_RUN, "--set", "init_iters=1000"])
    assert code == 128 + signal.SIGTERM, capsys.readouterr().err
    assert len(mappers) == 1 and mappers[0].iteration == 1  # stopped at the second iteration
    assert RunFolder.open(out).read_status().state == "interrupted"
