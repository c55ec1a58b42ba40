"""The run folder: the contract between a method run (ours, a baseline, an import) and evaluation.

Every method run writes one folder; ``egs-bench eval`` reads it and adds ``metrics.json``::

    <run>/run.yaml          identity: method name, sequence name + path, egs-bench version,
                            optional ``groundtruth`` (a TUM file, for runs with no sequence folder),
                            optional ``estimate`` (imports: what the external output covers),
                            ``artifacts`` (method-specific files, e.g. ``map.ply``)
    <run>/config.yaml       the method's fully resolved configuration
    <run>/status.json       {"state": "running"|"done"|"failed"|"interrupted", "reason",
                             "tracking_lost", "pid", "host", "heartbeat_utc",
                             optional "progress": {"done": frames processed, "total"}}
    <run>/trajectory.txt    estimated T_wc, TUM format, one pose per frame at its exposure end
    <run>/keyframes.txt     frame indices (0-based) of the keyframes, one per line
    <run>/renders/%06d.png  LDR sRGB renders from the estimated poses, named by frame index
    <run>/timing.json       total wall time, per-frame wall time, rendering FPS
    <run>/log.txt           free-form human-readable log (append-only)
    <run>/metrics.json      written by evaluation (never by the method)
    <run>/plots/            written by ``egs-bench plot``
    <run>/.lock             held (``flock``) by the process writing the run

Every file except the append-only log is written atomically (temp file + rename), so a reader
never sees a half-written file. One process at a time writes a run folder: :meth:`create` takes
the folder's lock and keeps it until the run is marked done, failed or interrupted; the kernel
releases it when the process dies. A ``running`` status whose writer is gone (lock free on this
host, or no heartbeat from another host for :data:`STALE_AFTER_S`) reads as ``interrupted``.
A typical method run::

    run = RunFolder.create(out_dir, method="egs", sequence_name=seq.name,
                           sequence_path=seq.path, config=resolved_cfg)
    with run.failure_guard():          # failed (or interrupted, on Ctrl-C / SIGTERM) + reason
        for i in range(len(seq)):
            ...
            run.write_render(i, ldr_uint8)
        run.write_trajectory(seq.timestamps_s, est_poses)
        run.write_keyframes(keyframe_ids)
        run.write_timing(total_wall_s=..., per_frame_s=..., render_fps=...)
        save_ply(gmap, run.artifact_path("map.ply"))
        run.mark_done()
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import json
import os
import re
import socket
import threading
import weakref
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from egs_bench import installed_version
from egs_bench.errors import InputError, OutputError, interruption_in, interruption_reason
from egs_bench.fileio import (
    FileLock,
    is_atomic_temp,
    lock_is_held,
    naming_full_disk,
    owner_note,
    read_text,
    read_yaml_mapping,
    to_plain,
    write_text_atomic,
)
from egs_bench.geometry import Trajectory, read_tum, write_tum
from egs_bench.images import read_ldr_image, write_ldr_image
from egs_bench.interrupts import call_on_interrupt, raise_if_interrupted
from egs_bench.outputs import prepare_output
from egs_bench.provenance import code_revision

RUN_FILE = "run.yaml"
CONFIG_FILE = "config.yaml"
STATUS_FILE = "status.json"
TRAJECTORY_FILE = "trajectory.txt"
KEYFRAMES_FILE = "keyframes.txt"
RENDERS_DIR = "renders"
TIMING_FILE = "timing.json"
LOG_FILE = "log.txt"
METRICS_FILE = "metrics.json"
PLOTS_DIR = "plots"
LOCK_FILE = ".lock"
#: the plots ``egs-bench plot`` writes into ``plots/``
PLOT_FILES = ("trajectory_top.png", "ate_over_time.png", "qualitative.png")
_STANDARD_FILES = (RUN_FILE, CONFIG_FILE, STATUS_FILE, TRAJECTORY_FILE, KEYFRAMES_FILE,
                   TIMING_FILE, LOG_FILE, METRICS_FILE)

STATES = ("running", "done", "failed", "interrupted")
#: seconds between two heartbeats of a running run (written to ``status.json``)
HEARTBEAT_S = 60.0
#: a ``running`` run written on another host is interrupted after this long without heartbeat
STALE_AFTER_S = 600.0
#: ``run.yaml`` ``estimate`` keys and their values for a method's own run (every frame has a
#: pose and a render, metric scale). Imports of external outputs record what they really hold.
ESTIMATE_DEFAULTS: dict[str, Any] = {"poses": "all", "renders": "all", "scale_free": False}
ESTIMATE_COVERAGE = ("all", "keyframes", "subset", "none")
_RENDER_NAME = re.compile(r"^(\d{6,})\.png$")


@dataclass(frozen=True)
class RunStatus:
    """Content of ``status.json``, with stale runs detected.

    Attributes:
        state: ``"running"``, ``"done"``, ``"failed"`` or ``"interrupted"`` (stopped by a
            signal, or a ``running`` run whose writing process is gone).
        reason: why the run failed or stopped (``None`` when running or done).
        tracking_lost: the failure was a tracking loss (leaderboards show ``L``, not ``--``).
        updated_utc: ISO-8601 UTC time of the last status change.
        pid, host: the process that wrote the run.
        heartbeat_utc: last sign of life of that process while running.
        progress: ``(done, total)`` frames the method had processed at the last status write
            (a heartbeat while running, the final state when it stopped), or None when the
            method does not report progress.
    """

    state: str
    reason: str | None = None
    tracking_lost: bool = False
    updated_utc: str = ""
    pid: int | None = None
    host: str | None = None
    heartbeat_utc: str | None = None
    progress: tuple[int, int] | None = None

    def progress_text(self) -> str:
        """``"frame 123/300"``, or ``""`` without progress."""
        return f"frame {self.progress[0]}/{self.progress[1]}" if self.progress else ""


@dataclass(frozen=True)
class RunTiming:
    """Content of ``timing.json``.

    Attributes:
        total_wall_s: wall time of the whole SLAM loop (tracking + mapping), seconds.
        per_frame_s: wall time per processed frame, shape [N], seconds.
        render_fps: rendering speed of the final map (frames per second), if measured.
        compile_s: kernel compilation (or cache loading) before the loop, seconds; None in
            runs that did not record it.
    """

    total_wall_s: float
    per_frame_s: np.ndarray
    render_fps: float | None
    compile_s: float | None = None

    @property
    def init_s(self) -> float | None:
        """Frame 0's wall time: the map's initialisation (None without frames)."""
        return float(self.per_frame_s[0]) if len(self.per_frame_s) else None

    @property
    def fps_after_init(self) -> float | None:
        """Frames per second over frames 1.. (tracking and mapping, the steady state);
        None with fewer than two frames."""
        rest = float(np.sum(self.per_frame_s[1:]))
        return (len(self.per_frame_s) - 1) / rest if len(self.per_frame_s) > 1 and rest > 0 \
            else None

    @property
    def fps(self) -> float:
        """Processed frames per second of wall time of the SLAM loop."""
        return len(self.per_frame_s) / self.total_wall_s if self.total_wall_s > 0 else float("nan")


def _now_utc() -> str:
    return _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


def _parse_utc(text: str | None) -> _dt.datetime | None:
    if not text:
        return None
    try:
        return _dt.datetime.strptime(text, "%Y-%m-%dT%H:%M:%SZ").replace(tzinfo=_dt.UTC)
    except ValueError:
        return None


def _read_progress(path: Path, value: Any) -> tuple[int, int] | None:
    """``status.json``'s optional ``progress`` as ``(done, total)``."""
    if value is None:
        return None
    ok = isinstance(value, dict) and all(
        isinstance(value.get(k), int) and not isinstance(value.get(k), bool) and value[k] >= 0
        for k in ("done", "total"))
    if not ok or value["done"] > value["total"]:
        raise InputError(path, "'progress' must be {\"done\": n, \"total\": m} with "
                               f"0 <= n <= m, found {value!r}")
    return int(value["done"]), int(value["total"])


def read_json_object(path: Path) -> dict[str, Any]:
    """A JSON file whose top level is an object; anything else is an :class:`InputError`
    naming the file."""
    text = read_text(path)
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(path, f"not valid JSON ({exc})") from None
    if not isinstance(data, dict):
        raise InputError(path, "expected a JSON object")
    return data


def _read_yaml(path: Path) -> dict[str, Any]:
    return read_yaml_mapping(path, empty_is_mapping=True)


def _dump_yaml(data: Mapping[str, Any]) -> str:
    return yaml.safe_dump(to_plain(data), sort_keys=False, default_flow_style=False)


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


class RunFolder:
    """One method run on one sequence (see the module docstring for the layout).

    Use :meth:`create` to start a run and :meth:`open` to read an existing one.
    """

    def __init__(self, path: Path, info: dict[str, Any]) -> None:
        self.path = path
        self._info = info
        self._lock: FileLock | None = None
        self._status_lock = threading.Lock()
        self._state: str | None = None
        self._started_utc = ""
        self._beat_stop = threading.Event()
        self._beat_thread: threading.Thread | None = None
        self._progress: tuple[int, int] | None = None

    # ---------------------------------------------------------------- creation / opening
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
            info: dict[str, Any] = {
                "method": str(method),
                "sequence": {
                    "name": str(sequence_name),
                    "path": str(Path(sequence_path).resolve()) if sequence_path is not None
                    else None,
                },
                "groundtruth": str(Path(groundtruth).resolve()) if groundtruth is not None
                else None,
                "egs_bench_version": installed_version(),
                "code": code_revision(),
                "created_utc": _now_utc(),
                "artifacts": [],
            }
            if estimate is not None:
                info["estimate"] = {**ESTIMATE_DEFAULTS, **dict(estimate)}
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

    @staticmethod
    def remove_run_files(path: Path) -> list[str]:
        """Delete what a run wrote into ``path`` (its standard files, recorded artifacts,
        ``renders/NNNNNN.png``, the plots, and the temporary files of atomic writes a killed
        process left); returns the names of other entries, which are kept. Symbolic links are
        never followed: a linked ``renders/`` is kept whole."""
        try:
            artifacts = _read_yaml(path / RUN_FILE).get("artifacts") or []
        except InputError:
            artifacts = []
        names = set(_STANDARD_FILES) | {str(a) for a in artifacts if isinstance(a, str)}

        def ours_to_delete(entry: Path, ours: bool) -> bool:
            return (ours or is_atomic_temp(entry.name)) and entry.is_file() \
                and not entry.is_symlink()

        for entry in list(path.iterdir()):
            if "/" not in entry.name and ours_to_delete(entry, entry.name in names):
                entry.unlink()
        for sub, allowed in ((RENDERS_DIR, None), (PLOTS_DIR, set(PLOT_FILES))):
            folder = path / sub
            if not folder.is_dir() or folder.is_symlink():
                continue
            for f in list(folder.iterdir()):
                ours = _RENDER_NAME.match(f.name) if allowed is None else f.name in allowed
                if ours_to_delete(f, bool(ours)):
                    f.unlink()
            if not any(folder.iterdir()):
                folder.rmdir()
        kept = []
        for entry in sorted(path.iterdir()):
            if entry.name == LOCK_FILE:
                continue
            if entry.name in (RENDERS_DIR, PLOTS_DIR) and entry.is_dir() \
                    and not entry.is_symlink():
                kept += [f"{entry.name}/{f.name}" for f in sorted(entry.iterdir())]
                continue
            kept.append(entry.name)
        return kept

    @classmethod
    def open(cls, path: str | Path) -> RunFolder:
        """Open an existing run folder (validates ``run.yaml``).

        Raises:
            InputError: the folder or its ``run.yaml`` is missing or malformed.
        """
        path = Path(path)
        if not path.is_dir():
            raise InputError(path, "run folder not found")
        if not (path / RUN_FILE).is_file():
            raise InputError(path, f"not a run folder (no {RUN_FILE})")
        info = _read_yaml(path / RUN_FILE)
        seq = info.get("sequence")
        if not isinstance(info.get("method"), str) or not info["method"]:
            raise InputError(path / RUN_FILE, "missing 'method'")
        if not isinstance(seq, dict) or not isinstance(seq.get("name"), str) or not seq["name"]:
            raise InputError(path / RUN_FILE, "missing 'sequence: {name, path}'")
        if seq.get("path") is not None and not isinstance(seq.get("path"), str):
            raise InputError(path / RUN_FILE, "'sequence.path' must be a path")
        if info.get("groundtruth") is not None and not isinstance(info["groundtruth"], str):
            raise InputError(path / RUN_FILE, "'groundtruth' must be a path")
        if not seq.get("path") and not info.get("groundtruth"):
            raise InputError(path / RUN_FILE, "needs 'sequence.path' or 'groundtruth'")
        return cls(path, info)

    @staticmethod
    def is_run_folder(path: str | Path) -> bool:
        """Whether ``path`` looks like a run folder (has ``run.yaml``)."""
        return (Path(path) / RUN_FILE).is_file()

    # ---------------------------------------------------------------- identity
    @property
    def method(self) -> str:
        """Method name (leaderboard row)."""
        return str(self._info["method"])

    @property
    def sequence_name(self) -> str:
        """Sequence name (leaderboard column)."""
        return str(self._info["sequence"]["name"])

    @property
    def sequence_path(self) -> Path | None:
        """Folder of the canonical sequence, or ``None`` for trajectory-only imports."""
        p = self._info["sequence"].get("path")
        return Path(p) if p else None

    @property
    def groundtruth_path(self) -> Path | None:
        """Explicit ground-truth TUM file overriding the sequence's, if any."""
        p = self._info.get("groundtruth")
        return Path(p) if p else None

    @property
    def estimate(self) -> dict[str, Any]:
        """What the estimate covers (``run.yaml`` ``estimate``, defaults for own runs)."""
        value = self._info.get("estimate")
        return {**ESTIMATE_DEFAULTS, **(value if isinstance(value, dict) else {})}

    @property
    def code_revision(self) -> dict[str, Any] | None:
        """``{"commit", "modified"}`` of the egs_bench checkout that wrote the run
        (:func:`egs_bench.provenance.code_revision`); None for runs written from an installed
        package, without git, or before run folders recorded it."""
        value = self._info.get("code")
        return dict(value) if isinstance(value, dict) and isinstance(value.get("commit"), str) \
            else None

    @property
    def info(self) -> dict[str, Any]:
        """The parsed ``run.yaml``."""
        return dict(self._info)

    # ---------------------------------------------------------------- config
    def write_config(self, config: Mapping[str, Any]) -> None:
        """Write the method's resolved configuration to ``config.yaml`` (atomically)."""
        write_text_atomic(self.path / CONFIG_FILE, _dump_yaml(config))

    def read_config(self) -> dict[str, Any]:
        """Read ``config.yaml``."""
        return _read_yaml(self.path / CONFIG_FILE)

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
        path = self.path / STATUS_FILE
        data = read_json_object(path)
        state = data.get("state")
        if state not in STATES:
            raise InputError(path, f"state must be one of {', '.join(STATES)}, found {state!r}")
        reason, pid, host = data.get("reason"), data.get("pid"), data.get("host")
        if reason is not None and not isinstance(reason, str):
            raise InputError(path, f"'reason' must be text or null, found {reason!r}")
        if not isinstance(data.get("tracking_lost", False), bool):
            raise InputError(path, "'tracking_lost' must be true or false")
        if pid is not None and (isinstance(pid, bool) or not isinstance(pid, int)):
            raise InputError(path, f"'pid' must be an integer, found {pid!r}")
        if host is not None and not isinstance(host, str):
            raise InputError(path, f"'host' must be text, found {host!r}")
        progress = _read_progress(path, data.get("progress"))
        status = RunStatus(
            state=state,
            reason=reason,
            tracking_lost=bool(data.get("tracking_lost", False)),
            updated_utc=str(data.get("updated_utc", "")),
            pid=pid,
            host=host,
            heartbeat_utc=str(data["heartbeat_utc"]) if data.get("heartbeat_utc") else None,
            progress=progress,
        )
        if state == "running":
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

    # ---------------------------------------------------------------- artifacts
    def artifact_path(self, name: str) -> Path:
        """Path for a method-specific output file (e.g. ``map.ply``), recorded in ``run.yaml``
        so that ``--overwrite`` removes it with the rest of the run."""
        if "/" in name or name in _STANDARD_FILES or name.startswith("."):
            raise ValueError(f"artifact name must be a plain new file name, not {name!r}")
        artifacts = list(self._info.get("artifacts") or [])
        if name not in artifacts:
            artifacts.append(name)
            self._info["artifacts"] = artifacts
            write_text_atomic(self.path / RUN_FILE, _dump_yaml(self._info))
        return self.path / name

    # ---------------------------------------------------------------- trajectory / keyframes
    @property
    def trajectory_path(self) -> Path:
        return self.path / TRAJECTORY_FILE

    def write_trajectory(self, timestamps_s: np.ndarray, poses: np.ndarray) -> None:
        """Write the estimated trajectory (TUM, atomically).

        Args:
            timestamps_s: exposure-end time of each frame, shape [N], seconds.
            poses: estimated ``T_wc`` per frame, shape [N, 4, 4], float64.
        """
        write_tum(self.trajectory_path, timestamps_s, poses)

    def read_trajectory(self, min_poses: int = 1) -> Trajectory:
        """Read the estimated trajectory; raises :class:`InputError` if missing or malformed."""
        if not self.trajectory_path.is_file():
            raise InputError(self.trajectory_path, "estimated trajectory not found "
                                                   "(the run did not write one)")
        return read_tum(self.trajectory_path, min_poses=min_poses)

    def write_keyframes(self, indices: Sequence[int] | np.ndarray) -> None:
        """Write keyframe frame indices (0-based, sorted, unique) to ``keyframes.txt``."""
        idx = np.unique(np.asarray(indices, dtype=np.int64))
        if len(idx) and idx[0] < 0:
            raise ValueError("keyframe indices must be >= 0")
        write_text_atomic(self.path / KEYFRAMES_FILE, "".join(f"{i}\n" for i in idx))

    def read_keyframes(self) -> np.ndarray | None:
        """Keyframe indices [K] int64, or ``None`` when the run wrote no ``keyframes.txt``."""
        path = self.path / KEYFRAMES_FILE
        if not path.is_file():
            return None
        out = []
        for lineno, line in enumerate(read_text(path).splitlines(), start=1):
            line = line.strip()
            if not line or line.startswith("#"):
                continue
            try:
                value = int(line)
            except ValueError:
                raise InputError(path, f"line {lineno}: not an integer frame index") from None
            if value < 0:
                raise InputError(path, f"line {lineno}: negative frame index")
            out.append(value)
        return np.unique(np.asarray(out, dtype=np.int64))

    # ---------------------------------------------------------------- renders
    @property
    def renders_dir(self) -> Path:
        return self.path / RENDERS_DIR

    def render_path(self, frame_index: int) -> Path:
        """Path of the render of frame ``frame_index`` (``renders/%06d.png``)."""
        return self.renders_dir / f"{int(frame_index):06d}.png"

    def write_render(self, frame_index: int, image: np.ndarray) -> None:
        """Write an LDR render as PNG (atomically).

        Args:
            frame_index: 0-based frame index in the sequence.
            image: sRGB render, uint8 [H, W, 3] (float input is rejected: quantise first).
        """
        write_ldr_image(self.render_path(frame_index), image)

    def render_indices(self) -> list[int]:
        """Sorted frame indices that have a render."""
        if not self.renders_dir.is_dir():
            return []
        out = []
        for f in self.renders_dir.iterdir():
            m = _RENDER_NAME.match(f.name)
            if m:
                out.append(int(m.group(1)))
        return sorted(out)

    def read_render(self, frame_index: int) -> np.ndarray:
        """Read a render as uint8 [H, W, 3]; raises :class:`InputError` if missing/unreadable."""
        path = self.render_path(frame_index)
        if not path.is_file():
            raise InputError(path, f"render of frame {frame_index} not found")
        return read_ldr_image(path)

    # ---------------------------------------------------------------- timing
    def write_timing(
        self,
        *,
        total_wall_s: float,
        per_frame_s: Sequence[float] | np.ndarray,
        render_fps: float | None = None,
        compile_s: float | None = None,
    ) -> None:
        """Write ``timing.json`` (atomically).

        Args:
            total_wall_s: wall time of the SLAM loop, seconds (kernel compilation excluded).
            per_frame_s: wall time per processed frame, [N] seconds (frame 0: the map's
                initialisation).
            render_fps: rendering speed of the final map (renders per second), if measured.
            compile_s: seconds spent compiling or loading kernels before the loop.
        """
        per_frame = np.asarray(per_frame_s, dtype=np.float64)
        timing = RunTiming(float(total_wall_s), per_frame, render_fps, compile_s)
        data = {
            "total_wall_s": float(total_wall_s),
            "frames": int(len(per_frame)),
            "fps": float(len(per_frame) / total_wall_s) if total_wall_s > 0 else None,
            "render_fps": float(render_fps) if render_fps is not None else None,
            "compile_s": float(compile_s) if compile_s is not None else None,
            "init_s": timing.init_s,
            "fps_after_init": timing.fps_after_init,
            "per_frame_s": [float(v) for v in per_frame],
        }
        write_text_atomic(self.path / TIMING_FILE, json.dumps(data, indent=1) + "\n")

    def read_timing(self) -> RunTiming | None:
        """Read ``timing.json``; ``None`` when the run wrote none (e.g. imported runs)."""
        path = self.path / TIMING_FILE
        if not path.is_file():
            return None
        data = read_json_object(path)
        try:
            total = float(data["total_wall_s"])
            per_frame = np.asarray(data.get("per_frame_s", []), dtype=np.float64)
            fps = data.get("render_fps")
            compile_s = data.get("compile_s")
            return RunTiming(total, per_frame, float(fps) if fps is not None else None,
                             float(compile_s) if compile_s is not None else None)
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(path, f"malformed timing ({exc})") from None

    # ---------------------------------------------------------------- log / outputs
    @property
    def log_path(self) -> Path:
        return self.path / LOG_FILE

    def log(self, message: str) -> None:
        """Append a time-stamped line to ``log.txt`` (append-only, flushed per line)."""
        with naming_full_disk(self.log_path), self.log_path.open("a") as f:
            f.write(f"{_now_utc()} {message}\n")

    @property
    def metrics_path(self) -> Path:
        return self.path / METRICS_FILE

    @property
    def plots_dir(self) -> Path:
        return self.path / PLOTS_DIR


def find_runs(root: str | Path) -> list[Path]:
    """All run folders under ``root`` (recursive; a run folder's own subfolders are skipped).

    Returns paths sorted for deterministic output.
    """
    root = Path(root)
    if not root.is_dir():
        raise InputError(root, "runs folder not found")
    found = sorted(p.parent for p in root.rglob(RUN_FILE))
    out: list[Path] = []
    for p in found:
        if not any(parent in out for parent in p.parents):
            out.append(p)
    return out
