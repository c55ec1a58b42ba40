"""Run one sweep run in this process: decide, run the method, evaluate, record.

``python -m egs_bench.experiments.worker SPEC.json [--force] [--retry-failed]`` is what every
backend starts, one process per run. Under an exclusive lock on the run (so a run is never
executed twice at once, even by two sweeps or a resubmitted cluster job) the worker

1. decides from the run folder's ``sweep.json`` record and ``status.json`` (:func:`decide`):
   a finished run with the same configuration hash is skipped; a run with another hash is
   ``stale`` and left alone unless forced; a folder the sweep did not create is a ``conflict``
   and never touched; an interrupted or killed run (status still ``running``) is run again;
   a run whose method finished (status ``done``) but whose evaluation was interrupted, or was
   made under another protocol than the sweep's, is only evaluated; a failed run is kept unless
   ``--retry-failed`` (a run whose method finished but whose evaluation failed or timed out is
   then only evaluated again);
2. deletes what the sweep and the method wrote into a run folder it is going to replace (always
   one this sweep created); a folder that also holds files egs-bench did not write is left
   as it is and the run fails, naming them;
3. writes the ``sweep.json`` record, runs the method (SIGTERM, e.g. a cluster time limit, is
   handled like Ctrl-C: the run folder and the record are marked ``interrupted``), evaluates a
   finished run with the sweep's protocol, and writes the final record with the state, the
   reason of a failure and the wall time. A failed evaluation fails the run (state
   ``failed``, reason ``evaluation: ...``): a run without metrics is not a result.

The worker's output (progress, numba/torch messages) goes to ``<run>/worker.log``. Thread
counts come from the environment the backend sets (``OMP_NUM_THREADS``, ``NUMBA_NUM_THREADS``,
...), which torch and numba read when they start.
"""

from __future__ import annotations

import argparse
import contextlib
import datetime as _dt
import json
import os
import socket
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from egs_bench.errors import EgsBenchError, interruption_reason, reraise_interruption
from egs_bench.eval.metrics_file import read_metrics
from egs_bench.eval.results import SWEEP_RECORD_FILE
from egs_bench.experiments.spec import RunSpec
from egs_bench.fileio import FileLock, owner_note, write_text_atomic
from egs_bench.fileio import lock_is_held as _file_lock_is_held
from egs_bench.interrupts import raise_if_interrupted, signals_interrupt
from egs_bench.outputs import RUN_PRELUDE_FILES
from egs_bench.runs.locations import STATE_DIR

WORKER_LOG = "worker.log"
# how long a starting worker keeps trying for its run's lock: a status probe (``egs-bench sweep
# --status`` from another shell) holds it for microseconds, which must not turn the worker away
LOCK_GRACE_S = 2.0
# exit codes of the worker process
EXIT_DONE, EXIT_FAILED, EXIT_BUSY, EXIT_NOT_RUN, EXIT_INTERRUPTED = 0, 10, 11, 12, 13

# decisions
RUN, SKIP, STALE, CONFLICT, KEEP_FAILED = "run", "skip", "stale", "conflict", "keep-failed"
EVALUATE = "evaluate"  # the method finished; only its evaluation is missing
STARTS_WORK = (RUN, EVALUATE)


def now_utc() -> str:
    return _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


def read_record(run_dir: str | Path) -> dict[str, Any] | None:
    """The run folder's ``sweep.json`` (``None`` when absent or unreadable)."""
    path = Path(run_dir) / SWEEP_RECORD_FILE
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError, OSError):
        return None
    return data if isinstance(data, dict) else None


def write_record(run_dir: str | Path, record: dict[str, Any]) -> None:
    write_text_atomic(Path(run_dir) / SWEEP_RECORD_FILE, json.dumps(record, indent=1) + "\n")


def run_state(run_dir: str | Path) -> str | None:
    """``status.json``'s state (``done``/``failed``/``running``/...), ``tracking_lost`` for a
    tracking loss, ``None`` when there is no readable status.

    Unlike :meth:`RunFolder.read_status` this never raises: for deciding whether to rerun, an
    unreadable status simply means "not finished"."""
    path = Path(run_dir) / "status.json"
    try:
        data = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError, UnicodeDecodeError):
        return None
    if not isinstance(data, dict):
        return None
    if data.get("state") == "failed" and data.get("tracking_lost"):
        return "tracking_lost"
    return data.get("state") if isinstance(data.get("state"), str) else None


def metrics_protocol(run_dir: str | Path) -> str | None:
    """The protocol name in the run's ``metrics.json`` (``None`` when absent or unreadable)."""
    try:
        return read_metrics(run_dir).protocol
    except EgsBenchError:
        return None


@dataclass(frozen=True)
class Decision:
    """What to do with a run, and why (one line for the summary)."""

    action: str
    why: str = ""


def decide(spec: RunSpec, force: bool = False, retry_failed: bool = False) -> Decision:
    """Whether ``spec`` must run, from its folder (see the module docstring)."""
    run_dir = Path(spec.run_dir)
    if not run_dir.exists():
        return Decision(RUN, "new")
    record = read_record(run_dir)
    if record is None and (run_dir / SWEEP_RECORD_FILE).is_file():
        return Decision(CONFLICT, f"{run_dir / SWEEP_RECORD_FILE}: unreadable (not a JSON "
                                  "object: truncated or corrupt); the run folder is left "
                                  "untouched (move it away or choose another --out)")
    if record is None or record.get("run_id") != spec.run_id:
        if run_dir.is_dir() and not any(run_dir.iterdir()):
            return Decision(RUN, "new")
        return Decision(CONFLICT, f"{run_dir} exists and was not created by this sweep; "
                                  "left untouched (move it away or choose another --out)")
    if record.get("config_hash") != spec.config_hash:
        if force:
            return Decision(RUN, "configuration changed; --force")
        return Decision(STALE, "finished with another configuration (hash "
                               f"{record.get('config_hash')} != {spec.config_hash}); kept: "
                               "rerun with --force or use another --out")
    state = run_state(run_dir)
    recorded = record.get("state")
    if recorded == "timeout" and not force:  # stopped at the time limit: again only if asked
        if not retry_failed:
            return Decision(KEEP_FAILED, "stopped at its time limit (rerun with --retry-failed)")
        if state == "done":
            return Decision(EVALUATE, "retrying the evaluation that hit the time limit")
        return Decision(RUN, "retrying a run that hit its time limit")
    if record.get("refused_foreign_files") and state is None:
        return Decision(RUN, "its folder held files egs-bench did not write; trying again")
    # a record still "running" means the worker died (the caller holds or tested the lock);
    # the method marks its folder done only after writing every output, so a done folder under
    # an unfinished record lost only its evaluation (hours of SLAM are not redone for that)
    if recorded in ("interrupted", "running") or state in (None, "running"):
        if state == "done" and not force:
            return Decision(EVALUATE, "the method finished; its evaluation was interrupted")
        return Decision(RUN, "interrupted before it finished")
    if force:
        return Decision(RUN, "--force")
    if state == "done" and recorded == "done" and record.get("evaluated") is not None:
        # metrics.json holds one protocol (``egs-bench eval --protocol`` may have replaced the
        # sweep's since): only evaluated again when it is missing or another protocol's
        found = metrics_protocol(run_dir)
        if found == spec.protocol:
            return Decision(SKIP, "finished earlier")
        return Decision(EVALUATE, "metrics.json is missing" if found is None else
                        f"evaluated under protocol {found!r}; the sweep asks for "
                        f"{spec.protocol!r}")
    if state == "done":  # the method finished, its evaluation failed or timed out
        if retry_failed:
            return Decision(EVALUATE, "retrying the failed evaluation of a finished run")
        return Decision(KEEP_FAILED, "its evaluation failed earlier (evaluate again with "
                                     "--retry-failed)")
    if retry_failed:
        return Decision(RUN, "retrying a failed run")
    return Decision(KEEP_FAILED, "failed earlier (rerun with --retry-failed)")


def _lock_path(spec: RunSpec) -> Path:
    return Path(spec.sweep_dir) / STATE_DIR / "locks" / f"{spec.key}.lock"


@contextlib.contextmanager
def run_lock(spec: RunSpec, grace_s: float = 0.0) -> Iterator[bool]:
    """Exclusive lock of one run (:class:`~egs_bench.fileio.FileLock`; released when the
    process dies), tried for up to ``grace_s`` seconds.

    Yields True when this process holds the lock, False when another process does.
    """
    path = _lock_path(spec)
    path.parent.mkdir(parents=True, exist_ok=True)
    lock = FileLock(path)
    deadline = time.monotonic() + grace_s
    while not lock.acquire(owner_note()):
        if time.monotonic() >= deadline:
            yield False
            return
        time.sleep(0.05)
    try:
        yield True
    finally:
        lock.release()


def lock_is_held(spec: RunSpec) -> bool:
    """Whether some process currently holds the run's lock (a shared-lock probe that creates
    nothing, so it works on a read-only sweep folder)."""
    return bool(_file_lock_is_held(_lock_path(spec)))


def clear_run_folder(spec: RunSpec) -> list[str]:
    """Delete what this sweep and its run wrote into the run folder (only called for folders
    whose ``sweep.json`` names this run); returns the entries it kept because egs-bench did not
    write them (then the folder is not emptied and cannot hold a new run)."""
    from egs_bench.runs.folder import LOCK_FILE, RunFolder

    run_dir = Path(spec.run_dir)
    if run_dir.is_symlink():  # the folder is elsewhere; what else it holds is not known here
        return [f"{run_dir.name} (a symbolic link to {os.readlink(run_dir)})"]
    if not run_dir.is_dir():
        return []
    for name in RUN_PRELUDE_FILES - {LOCK_FILE}:
        entry = run_dir / name
        if entry.is_file() and not entry.is_symlink():
            entry.unlink()
    # the folder and its .lock stay (a lock file is never deleted: another process may hold
    # it open); a folder holding only the prelude files counts as free for the new run
    return RunFolder.remove_run_files(run_dir)


def _redirect_output(path: Path) -> None:
    """Send this process's stdout/stderr (file descriptors too) to ``path`` (append)."""
    sys.stdout.flush()
    sys.stderr.flush()
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    os.dup2(fd, 1)
    os.dup2(fd, 2)
    os.close(fd)


def _identity_fields(spec: RunSpec) -> dict[str, Any]:
    """The record fields that say which run and configuration a folder holds."""
    return {"run_id": spec.run_id, "config_hash": spec.config_hash, "seed": spec.seed,
            "settings_name": spec.settings_name, "identity": spec.identity}


def execute(spec: RunSpec, redirect: bool = True, evaluate_only: bool = False
            ) -> dict[str, Any]:
    """Run the method of ``spec`` into its (prepared) run folder, evaluate it, and return the
    final record (also written to ``sweep.json``).

    With ``evaluate_only`` the folder holds a finished run (status ``done``) whose evaluation
    was interrupted: the method's outputs are kept and only evaluated. SIGTERM during the
    evaluation leaves the record ``interrupted``, so the next invocation evaluates again.
    """
    run_dir = Path(spec.run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    earlier = read_record(run_dir) if evaluate_only else None
    record: dict[str, Any] = {
        **_identity_fields(spec), "state": "running",
        "host": socket.gethostname(), "pid": os.getpid(),
        "started_utc": (earlier or {}).get("started_utc") or now_utc(),
        "threads": os.environ.get("EGS_BENCH_THREADS"),
        "cuda_visible_devices": os.environ.get("CUDA_VISIBLE_DEVICES"),
    }
    write_record(run_dir, record)
    if redirect:
        _redirect_output(run_dir / WORKER_LOG)
    what = "evaluation of finished run" if evaluate_only else "sweep run"
    print(f"{now_utc()} {what} {spec.run_id} (hash {spec.config_hash}) pid {os.getpid()}",
          flush=True)
    try:
        if evaluate_only:
            record["state"] = "done"
            if (method_wall := _method_wall_s(run_dir)) is not None:
                record["run_wall_s"] = method_wall
        else:
            _run_method(spec, run_dir, record)
        if record["state"] == "done":
            _evaluate(spec, run_dir, record)
        raise_if_interrupted()  # a signal whose exception was swallowed: evaluate again later
    except KeyboardInterrupt as exc:
        record.update(state="interrupted", reason=interruption_reason(exc))
    record["finished_utc"] = now_utc()
    write_record(run_dir, record)
    print(f"{now_utc()} finished: {record['state']} {record.get('reason', '')}", flush=True)
    return record


def _run_method(spec: RunSpec, run_dir: Path, record: dict[str, Any]) -> None:
    """Run the method; set the record's state, reason and ``run_wall_s`` (interruptions
    propagate, with ``run_wall_s`` set)."""
    from egs_bench.datasets.sequence import Sequence
    from egs_bench.experiments.spec import typed_options
    from egs_bench.runs.registry import get_method, with_options

    t0 = time.perf_counter()
    try:
        chosen = get_method(spec.method)
        method = with_options(chosen, typed_options(spec.options or {}, chosen))
        sequence = Sequence.open(spec.sequence)
        method.run(sequence, run_dir, preset=spec.preset, device=spec.device, seed=spec.seed,
                   max_frames=spec.max_frames, progress=False)
        state = run_state(run_dir)
        record["state"] = state if state in ("done", "failed", "tracking_lost") else "failed"
        if record["state"] != "done":
            record["reason"] = _status_reason(run_dir) or "the method did not mark the run done"
    except Exception as exc:  # any failure of one run is recorded, not raised
        reraise_interruption(exc)
        record.update(state=run_state(run_dir) if run_state(run_dir) == "tracking_lost"
                      else "failed", reason=f"{type(exc).__name__}: {exc}".splitlines()[0])
    finally:
        record["run_wall_s"] = round(time.perf_counter() - t0, 3)


def _evaluate(spec: RunSpec, run_dir: Path, record: dict[str, Any]) -> None:
    """Evaluate a finished run with the sweep's protocol; an evaluation error fails the run
    (state ``failed``, ``evaluation_error``), since a run without metrics is no result."""
    from egs_bench.eval.evaluate import evaluate_run

    t1 = time.perf_counter()
    try:
        evaluate_run(run_dir, spec.protocol, write=True)
        record["evaluated"] = spec.protocol
    except Exception as exc:
        reraise_interruption(exc)
        error = f"{type(exc).__name__}: {exc}".splitlines()[0]
        record.update(state="failed", evaluation_error=error, reason=f"evaluation: {error}")
    finally:
        record["eval_wall_s"] = round(time.perf_counter() - t1, 3)


def _method_wall_s(run_dir: Path) -> float | None:
    """The method's own wall time from ``timing.json`` (for a run evaluated later; ``None``
    when the folder has no readable timing)."""
    from egs_bench.runs.folder import RunFolder

    try:
        timing = RunFolder.open(run_dir).read_timing()
    except EgsBenchError:
        return None
    return round(timing.total_wall_s, 3) if timing is not None else None


def _status_reason(run_dir: Path) -> str | None:
    try:
        data = json.loads((run_dir / "status.json").read_text())
        return data.get("reason") if isinstance(data, dict) else None
    except (OSError, json.JSONDecodeError, UnicodeDecodeError):
        return None


def _refuse_foreign_files(spec: RunSpec, kept: list[str]) -> dict[str, Any]:
    """Record (and return) a failed run whose folder holds files egs-bench did not write."""
    shown = ", ".join(kept[:5]) + (f" and {len(kept) - 5} more" if len(kept) > 5 else "")
    record = {**_identity_fields(spec),
              "state": "failed", "finished_utc": now_utc(), "refused_foreign_files": kept,
              "reason": f"{spec.run_dir} holds files egs-bench did not write ({shown}); kept "
                        "them and did not start the run: move them away and run again"}
    write_record(spec.run_dir, record)
    print(f"{spec.run_id}: {record['reason']}", file=sys.stderr)
    return record


def run_one(spec: RunSpec, force: bool = False, retry_failed: bool = False,
            redirect: bool = True) -> int:
    """Decide and (if needed) execute one run under its lock; returns a worker exit code."""
    with run_lock(spec, grace_s=LOCK_GRACE_S) as mine:
        if not mine:
            print(f"{spec.run_id}: running in another process; not started", file=sys.stderr)
            return EXIT_BUSY
        decision = decide(spec, force, retry_failed)
        if decision.action not in STARTS_WORK:
            print(f"{spec.run_id}: {decision.action} ({decision.why})", file=sys.stderr)
            return EXIT_NOT_RUN
        if decision.action == EVALUATE:
            record = execute(spec, redirect=redirect, evaluate_only=True)
        elif kept := clear_run_folder(spec):
            record = _refuse_foreign_files(spec, kept)
        else:
            record = execute(spec, redirect=redirect)
    return {"done": EXIT_DONE, "interrupted": EXIT_INTERRUPTED}.get(record["state"], EXIT_FAILED)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="Run one sweep run (started by egs-bench sweep).")
    ap.add_argument("spec", type=Path, help="run spec JSON written by the sweep launcher")
    ap.add_argument("--force", action="store_true")
    ap.add_argument("--retry-failed", action="store_true")
    args = ap.parse_args(argv)
    spec = RunSpec.from_dict(json.loads(args.spec.read_text()))
    # SIGTERM (a cluster's time limit, the sweep pool stopping, ``kill``) unwinds like Ctrl-C:
    # the method marks its run folder interrupted, the record says so, the next invocation
    # reruns it. Installed for the whole worker, so that no signal finds the default action
    # (death with the record still "running") while a record is being written.
    with signals_interrupt():
        try:
            return run_one(spec, args.force, args.retry_failed)
        except KeyboardInterrupt:  # before the run started or after its record was written
            return EXIT_INTERRUPTED


if __name__ == "__main__":
    sys.exit(main())
