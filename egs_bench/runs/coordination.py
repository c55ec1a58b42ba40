"""Coordination of run folders: one writer at a time (a file lock), a heartbeat while running,
and whether a ``running`` status still has a live writer.

:class:`RunFolder` is a :class:`~egs_bench.runs.contract.RunFiles` (the file contract) that a
method run creates: :meth:`RunFolder.create` takes the folder's lock (``.lock``, ``flock``) and
keeps it until the run is marked done, failed or interrupted; the kernel releases it when the
process dies. While running, a background thread rewrites ``status.json``'s heartbeat every
:data:`HEARTBEAT_S`. A ``running`` status whose writer is gone (lock free on this host, or no
heartbeat from another host for :data:`STALE_AFTER_S`) reads as ``interrupted``. A signal
that ends the process marks every run it left ``running`` as ``interrupted``.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import json
import os
import socket
import threading
import weakref
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from egs_bench.errors import InputError, OutputError, interruption_in, interruption_reason
from egs_bench.fileio import FileLock, lock_is_held, owner_note, write_text_atomic
from egs_bench.interrupts import call_on_interrupt, raise_if_interrupted
from egs_bench.outputs import prepare_output
from egs_bench.runs.contract import (
    CONFIG_FILE,
    ESTIMATE_COVERAGE,
    LOCK_FILE,
    RUN_FILE,
    STATUS_FILE,
    RunFiles,
    RunStatus,
    _dump_yaml,
    _now_utc,
    _parse_utc,
    read_json_object,
    run_identity,
)

#: seconds between two heartbeats of a running run (written to ``status.json``)
HEARTBEAT_S = 60.0
#: a ``running`` run written on another host is interrupted after this long without heartbeat
STALE_AFTER_S = 600.0


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


#: runs this process has marked running and not finished (see _interrupt_unfinished_runs)
_RUNNING: weakref.WeakSet[RunFolder] = weakref.WeakSet()


def _interrupt_unfinished_runs(interruption: KeyboardInterrupt) -> None:
    """Mark ``interrupted`` every run this process left ``running`` when a signal ended it: one
    that landed before the run's :meth:`RunFolder.failure_guard` was entered (inside
    :meth:`RunFolder.create`, or right after it) has no guard to do so."""
    for run in list(_RUNNING):
        with contextlib.suppress(OSError, InputError, OutputError):
            run.mark_interrupted(interruption_reason(interruption))


call_on_interrupt(_interrupt_unfinished_runs)


class RunFolder(RunFiles):
    """One method run on one sequence: its files (:class:`~egs_bench.runs.contract.RunFiles`)
    and, for a run this process writes, the folder's lock and heartbeat.

    Use :meth:`create` to start a run and :meth:`open` to read an existing one.
    """

    def __init__(self, path: Path, info: dict[str, Any]) -> None:
        super().__init__(path, info)
        self._lock: FileLock | None = None
        self._status_lock = threading.Lock()
        self._state: str | None = None
        self._started_utc = ""
        self._beat_stop = threading.Event()
        self._beat_thread: threading.Thread | None = None
        self._progress: tuple[int, int] | None = None

    # ---------------------------------------------------------------- creation
    @classmethod
    def create(
        cls,
        path: str | Path,
        *,
        method: str,
        sequence_name: str,
        sequence_path: str | Path | None,
        config: Mapping[str, Any] | None = None,
        groundtruth: str | Path | None = None,
        overwrite: bool = False,
        estimate: Mapping[str, Any] | None = None,
        inputs: Sequence[str | Path] = (),
    ) -> RunFolder:
        """Create a run folder, take its lock, write ``run.yaml`` + ``config.yaml`` and mark
        it ``running``.

        Args:
            path: the folder to create (parents are created); an empty folder is used as is.
            method: method name as it should appear in leaderboards (e.g. ``"egs"``).
            sequence_name: name of the sequence (leaderboard column).
            sequence_path: folder of the canonical sequence the run used (stored absolute), or
                ``None`` for imported runs that only have a ground-truth trajectory.
            config: the method's resolved configuration (plain data, stored as YAML).
            groundtruth: optional TUM ground-truth file; used by evaluation instead of the
                sequence's ``groundtruth.txt`` (required when ``sequence_path`` is ``None``).
            overwrite: replace an existing run folder written by egs-bench. Only the files a
                run writes are removed (the standard files, ``renders/NNNNNN.png``, the plots,
                the ``artifacts`` of ``run.yaml``); anything else in the folder is kept.
            estimate: what the estimate covers, for imported external outputs: ``poses`` and
                ``renders`` each ``"all"``, ``"keyframes"``, ``"subset"`` or ``"none"``,
                ``scale_free`` (monocular: evaluated with Sim(3)), plus free-form ``source`` /
                ``format`` entries. Omitted: :data:`ESTIMATE_DEFAULTS`.
            inputs: further input files or folders the output may not replace (the sequence
                folder and ground truth are always protected).

        Raises:
            OutputError: the folder holds a run and ``overwrite`` is false, is not a run folder,
                is another process's running run, or is (or contains) an input.
        """
        path = Path(path)
        if not method or not sequence_name:
            raise ValueError("method and sequence_name must be non-empty")
        if sequence_path is None and groundtruth is None:
            raise ValueError("a run needs a sequence_path or a groundtruth trajectory")
        for key in ("poses", "renders"):
            if estimate is not None and estimate.get(key, "all") not in ESTIMATE_COVERAGE:
                raise ValueError(f"estimate {key} must be one of {ESTIMATE_COVERAGE}")
        protected = [p for p in (sequence_path, groundtruth, *inputs) if p is not None]
        cls._refuse_if_locked(path)
        prepare_output(path, "run", overwrite=overwrite, inputs=protected)
        created = not path.exists()
        path.mkdir(parents=True, exist_ok=True)
        lock = FileLock(path / LOCK_FILE)
        if not lock.acquire(owner_note()):
            cls._refuse_if_locked(path)
            raise OutputError(path, "is being written by another egs-bench process")
        run: RunFolder | None = None
        try:
            # checked again under the lock: another process may have finished a run here
            # between the first check and the lock
            prepare_output(path, "run", overwrite=overwrite, inputs=protected)
            stale = cls.remove_run_files(path) if (path / RUN_FILE).exists() else []
            info = run_identity(method, sequence_name, sequence_path, groundtruth, estimate)
            write_text_atomic(path / RUN_FILE, _dump_yaml(info))
            run = cls(path, info)
            run._lock = lock
            run.write_config(config or {})
            run.mark_running()
        except BaseException as exc:
            if run is not None and run._state == "running":
                run._record_stop(exc)  # a signal right after the status went out
            else:
                lock.release()
                if created:  # e.g. a full disk: no half-made run without a status is left
                    for name in (RUN_FILE, CONFIG_FILE, LOCK_FILE):
                        (path / name).unlink(missing_ok=True)
                    with contextlib.suppress(OSError):
                        path.rmdir()
            raise
        if stale:
            run.log(f"kept {len(stale)} file(s) of the replaced run folder that a run does not "
                    f"write: {', '.join(stale[:5])}")
        return run

    @staticmethod
    def _refuse_if_locked(path: Path) -> None:
        if lock_is_held(path / LOCK_FILE):
            who = ""
            with contextlib.suppress(InputError):
                data = read_json_object(path / STATUS_FILE)
                if data.get("pid") is not None:
                    who = f" (pid {data.get('pid')} on {data.get('host')})"
            raise OutputError(path, f"is being written by another egs-bench process{who}; "
                                    "wait for it to finish or choose another --out")

    # ---------------------------------------------------------------- status
    # ---------------------------------------------------------------- status
    def _write_status(self, state: str, reason: str | None = None,
                      tracking_lost: bool = False) -> None:
        now = _now_utc()
        if state != self._state:
            self._started_utc = now
        data: dict[str, Any] = {
            "state": state,
            "reason": reason,
            "tracking_lost": tracking_lost,
            "updated_utc": self._started_utc,
            "pid": os.getpid(),
            "host": socket.gethostname(),
            "heartbeat_utc": now,
        }
        if self._progress is not None:
            data["progress"] = {"done": self._progress[0], "total": self._progress[1]}
        write_text_atomic(self.path / STATUS_FILE, json.dumps(data, indent=2) + "\n",
                          in_place_when_full=True)
        self._state = state

    def _finish(self, state: str, reason: str | None = None, tracking_lost: bool = False
                ) -> None:
        _RUNNING.discard(self)
        self._beat_stop.set()
        try:
            with self._status_lock:
                self._write_status(state, reason, tracking_lost)
            beat = self._beat_thread
            # not alive: a signal may have landed inside its start(), before it ran
            if beat is not None and beat.is_alive() and beat is not threading.current_thread():
                beat.join(timeout=5)
        finally:
            if self._lock is not None:
                self._lock.release()
                self._lock = None

    def _heartbeat_loop(self) -> None:
        while not self._beat_stop.wait(HEARTBEAT_S):
            with self._status_lock:
                if self._state != "running" or self._beat_stop.is_set():
                    return
                try:
                    self._write_status("running")
                except (OSError, InputError, OutputError):
                    return  # the folder went away: nothing left to keep alive

    def set_progress(self, done: int, total: int) -> None:
        """Record that ``done`` of ``total`` frames are processed. Nothing is written now: the
        next heartbeat (at most :data:`HEARTBEAT_S` later) or the final status carries it, so
        a per-frame call costs no file write."""
        self._progress = (int(done), int(total))

    def mark_running(self) -> None:
        """Set the status to ``running``; while running, a background thread refreshes the
        heartbeat every :data:`HEARTBEAT_S` seconds."""
        with self._status_lock:
            self._write_status("running")
        if self._lock is not None:
            _RUNNING.add(self)
        if self._lock is not None and self._beat_thread is None:
            self._beat_stop.clear()
            self._beat_thread = threading.Thread(target=self._heartbeat_loop, daemon=True,
                                                 name=f"heartbeat {self.path}")
            self._beat_thread.start()

    def mark_done(self) -> None:
        """Set the status to ``done`` (call after every output file is written); releases the
        folder's lock. Raises :class:`egs_bench.errors.Interrupted` instead if a signal arrived
        whose exception was swallowed (see :mod:`egs_bench.interrupts`)."""
        raise_if_interrupted()
        self._finish("done")

    def mark_failed(self, reason: str, *, tracking_lost: bool = False) -> None:
        """Set the status to ``failed`` with a one-line ``reason``; releases the lock.

        Args:
            reason: human-readable cause (shown in leaderboard footnotes).
            tracking_lost: the method lost tracking (shown as ``L`` rather than ``--``).
        """
        self._finish("failed", reason, tracking_lost)
        self.log(f"FAILED: {reason}")

    def mark_interrupted(self, reason: str) -> None:
        """Set the status to ``interrupted`` (stopped by a signal, e.g. Ctrl-C or a cluster's
        SIGTERM) with a one-line ``reason``; releases the lock."""
        self._finish("interrupted", reason)
        self.log(f"INTERRUPTED: {reason}")

    def read_status(self) -> RunStatus:
        """Read ``status.json``; a ``running`` run whose writer is gone reads as
        ``interrupted`` (with the evidence in ``reason``).

        The writer is gone when, on this host, the folder's lock is free (or, without a lock
        file, its pid is dead), and, from another host, when its heartbeat is older than
        :data:`STALE_AFTER_S`.

        Raises:
            InputError: missing or malformed file, or an unknown state.
        """
        status = self.read_status_file()
        if status.state == "running":
            gone = self._writer_gone(status)
            if gone:
                return replace(status, state="interrupted", reason=gone, tracking_lost=False)
        return status

    def _writer_gone(self, status: RunStatus) -> str | None:
        """Why the process writing a ``running`` run is known to be gone, or None."""
        who = f"pid {status.pid} on {status.host}" if status.pid is not None else "its writer"
        if status.host is None or status.host == socket.gethostname():
            held = lock_is_held(self.path / LOCK_FILE)
            if held is False:
                return f"{who} stopped without finishing the run (killed?)"
            if held is None and status.pid is not None and not _pid_alive(status.pid):
                return f"{who} is gone without finishing the run (killed?)"
            if held is not None or status.pid is not None:
                return None
        beat = _parse_utc(status.heartbeat_utc or status.updated_utc)
        if beat is None:
            return None
        age = (_dt.datetime.now(_dt.UTC) - beat).total_seconds()
        if age > STALE_AFTER_S:
            return f"no heartbeat from {who} since {status.heartbeat_utc or status.updated_utc}"
        return None

    @contextlib.contextmanager
    def failure_guard(self) -> Iterator[RunFolder]:
        """Context manager: on an exception mark the run ``failed`` with it (``interrupted`` on
        Ctrl-C or SIGTERM, see :class:`egs_bench.errors.Interrupted`), then re-raise.

        A run already marked ``done`` keeps that status: every output was written before
        :meth:`mark_done`, and a signal that lands after it (while the heartbeat thread is
        joined or the lock released, still inside the block) must not send a finished run
        back to be computed again."""
        try:
            yield self
        except BaseException as exc:
            if self._state == "done":
                raise
            interrupt = self._record_stop(exc)
            if interrupt is None or interrupt is exc:
                raise
            raise interrupt from None

    def _record_stop(self, exc: BaseException) -> KeyboardInterrupt | None:
        """Mark the run ``interrupted`` when a signal is behind ``exc`` (also one that surfaced
        inside numba), else ``failed`` with ``exc`` as the reason; returns the interruption."""
        interrupt = interruption_in(exc)
        if interrupt is not None:
            self.mark_interrupted(interruption_reason(interrupt))
            return interrupt
        reason = f"{type(exc).__name__}: {exc}".strip()
        self.mark_failed(reason.splitlines()[0] if reason else type(exc).__name__)
        return None
