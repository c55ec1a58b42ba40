"""Where sweep runs execute: a local process pool, or SLURM array jobs through submitit.

Both start the same worker (:mod:`egs_bench.experiments.worker`), one process per run, so a run
behaves the same everywhere and a resubmitted or resumed sweep skips what is finished.

* **local** (default): a pool of slots. When the runs use CUDA, one slot per visible GPU (each
  pinned with ``CUDA_VISIBLE_DEVICES``); otherwise slots share a CPU-thread budget (default: the
  CPUs this process may use), and each worker's torch / numba / OpenMP threads are set to its
  share, so parallel runs do not oversubscribe the cores. Optional per-run time limit.
* **slurm**: one submitit array (``map_array``) with a time limit, CPUs, GPUs, memory, partition
  and an array-parallelism cap; ``cluster="local"`` runs the same code with submitit's local
  executor (no cluster needed: how the tests exercise it). Needs ``pip install
  'egs-bench[slurm]'``.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from egs_bench.errors import ConfigError
from egs_bench.experiments.spec import LocalOptions, RunSpec, SlurmOptions
from egs_bench.experiments.worker import (
    EXIT_BUSY,
    EXIT_DONE,
    EXIT_FAILED,
    EXIT_INTERRUPTED,
    EXIT_NOT_RUN,
    read_record,
    write_record,
)
from egs_bench.fileio import write_text_atomic
from egs_bench.interrupts import raise_if_interrupted, signals_interrupt
from egs_bench.runs.locations import STATE_DIR

TERM_GRACE_S = 30.0
_THREAD_VARS = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS",
                "EGS_BENCH_THREADS")


@dataclass(frozen=True)
class Outcome:
    """What happened to one run in this invocation (``action``: ran / busy / not-run /
    interrupted / timeout / crashed / submitted) and an optional note."""

    action: str
    note: str = ""


def thread_env(threads: int) -> dict[str, str]:
    """Environment that limits torch, numba and BLAS/OpenMP pools to ``threads``."""
    return {v: str(threads) for v in _THREAD_VARS}


def cpu_budget() -> int:
    """CPUs this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def cuda_devices() -> list[str]:
    """Visible CUDA devices as ``CUDA_VISIBLE_DEVICES`` entries (empty without CUDA)."""
    import torch

    n = torch.cuda.device_count() if torch.cuda.is_available() else 0
    visible = os.environ.get("CUDA_VISIBLE_DEVICES")
    if visible:
        listed = [d.strip() for d in visible.split(",") if d.strip()]
        return listed[:n]
    return [str(i) for i in range(n)]


@dataclass(frozen=True)
class Slot:
    """One parallel lane of the local pool: its environment and a name for messages."""

    name: str
    env: dict[str, str]


def plan_slots(runs: Sequence[RunSpec], options: LocalOptions, jobs: int | None = None,
               threads: int | None = None, gpus: list[str] | None = None) -> list[Slot]:
    """Slots of the local pool (see the module docstring).

    Args:
        jobs, threads: command-line values overriding ``options``.
        gpus: visible CUDA devices (default: asked from torch when a run uses CUDA).

    Raises:
        ConfigError: runs need CUDA but no GPU is visible, or a non-positive count.
    """
    jobs = jobs if jobs is not None else options.jobs
    threads = threads if threads is not None else options.threads_per_job
    if (jobs is not None and jobs < 1) or (threads is not None and threads < 1):
        raise ConfigError("--jobs and --threads-per-job must be positive")
    budget = options.cpu_budget or cpu_budget()
    if any(r.device == "cuda" for r in runs):
        gpus = cuda_devices() if gpus is None else gpus
        if not gpus:
            raise ConfigError("the sweep has runs on device cuda, but no CUDA GPU is visible")
        n = jobs or len(gpus)
        per = threads or max(1, budget // n)
        return [Slot(f"gpu{gpus[i % len(gpus)]}",
                     {**thread_env(per), "CUDA_VISIBLE_DEVICES": gpus[i % len(gpus)]})
                for i in range(n)]
    if jobs is None:
        jobs = max(1, budget // threads) if threads else budget
    jobs = max(1, min(jobs, max(1, len(runs))))
    per = threads or max(1, budget // jobs)
    return [Slot(f"cpu{i}", thread_env(per)) for i in range(jobs)]


def spec_file(spec: RunSpec) -> Path:
    """Write the run spec for its worker (content-deterministic, so rewriting is harmless)."""
    path = Path(spec.sweep_dir) / STATE_DIR / "specs" / f"{spec.key}.json"
    write_text_atomic(path, spec.to_json())
    return path


def worker_command(spec_path: Path, force: bool, retry_failed: bool) -> list[str]:
    cmd = [sys.executable, "-m", "egs_bench.experiments.worker", str(spec_path)]
    return cmd + (["--force"] if force else []) + (["--retry-failed"] if retry_failed else [])


def _outcome(code: int, log: Path) -> Outcome:
    return {EXIT_DONE: Outcome("ran"), EXIT_FAILED: Outcome("ran"),
            EXIT_BUSY: Outcome("busy", "running in another process"),
            EXIT_NOT_RUN: Outcome("not-run", "another process finished it meanwhile"),
            EXIT_INTERRUPTED: Outcome("interrupted")}.get(
        code, Outcome("crashed", f"worker exited with code {code}; see {log}"))


def mark_timeout(spec: RunSpec, minutes: float) -> None:
    """Record that the run hit its time limit (the run folder itself says failed)."""
    record = read_record(spec.run_dir)
    if record is not None and record.get("run_id") == spec.run_id:
        record.update(state="timeout", reason=f"time limit of {minutes:g} min reached")
        write_record(spec.run_dir, record)


def run_local(runs: Sequence[RunSpec], slots: Sequence[Slot], *, force: bool = False,
              retry_failed: bool = False, timeout_min: float | None = None,
              say: Callable[[str], None] = print) -> dict[str, Outcome]:
    """Run ``runs`` on the local pool; returns each run's outcome by run id.

    Ctrl-C or SIGTERM stops the pool: running workers get SIGTERM (they record themselves as
    interrupted, so the next invocation reruns them), then the signal is re-raised.
    """
    queue = deque(runs)
    free = list(range(len(slots)))
    active: dict[int, tuple[subprocess.Popen, RunSpec, float, Path]] = {}
    outcomes: dict[str, Outcome] = {}
    done_count, total = 0, len(runs)
    with signals_interrupt():
        try:
            while queue or active:
                raise_if_interrupted()  # one whose exception was swallowed: start no more
                while queue and free:
                    slot_i = free.pop(0)
                    spec = queue.popleft()
                    log = Path(spec.sweep_dir) / STATE_DIR / "logs" / f"{spec.key}.log"
                    log.parent.mkdir(parents=True, exist_ok=True)
                    with open(log, "ab") as f:
                        proc = subprocess.Popen(
                            worker_command(spec_file(spec), force, retry_failed),
                            env={**os.environ, **slots[slot_i].env}, stdout=f,
                            stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
                    active[slot_i] = (proc, spec, time.monotonic(), log)
                    say(f"start  {spec.run_id} [{slots[slot_i].name}]")
                time.sleep(0.2)
                for slot_i, (proc, spec, t0, log) in list(active.items()):
                    elapsed = time.monotonic() - t0
                    if proc.poll() is None:
                        if timeout_min is not None and elapsed > 60 * timeout_min:
                            _stop(proc)
                            mark_timeout(spec, timeout_min)
                            outcomes[spec.run_id] = Outcome("timeout",
                                                            f"time limit {timeout_min:g} min")
                        else:
                            continue
                    else:
                        outcomes[spec.run_id] = _outcome(proc.returncode, log)
                    del active[slot_i]
                    free.append(slot_i)
                    done_count += 1
                    record = read_record(spec.run_dir) or {}
                    state = record.get("state", outcomes[spec.run_id].action)
                    say(f"[{done_count}/{total}] {state:13s} {spec.run_id} ({elapsed:.1f} s)")
        except KeyboardInterrupt:
            for proc, _spec, _, _ in active.values():
                _stop(proc, wait=False)
            deadline = time.monotonic() + TERM_GRACE_S
            for proc, spec, _, _ in active.values():
                _wait_or_kill(proc, deadline)
                outcomes[spec.run_id] = Outcome("interrupted")
            raise
    return outcomes


def _stop(proc: subprocess.Popen, wait: bool = True) -> None:
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
        if wait:
            _wait_or_kill(proc, time.monotonic() + TERM_GRACE_S)


def _wait_or_kill(proc: subprocess.Popen, deadline: float) -> None:
    try:
        proc.wait(timeout=max(0.1, deadline - time.monotonic()))
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


# ------------------------------------------------------------------------------------- SLURM
def slurm_job(spec_path: str, force: bool, retry_failed: bool, threads: int) -> int:
    """The function each array task runs: the worker as a subprocess (its output goes to the
    run folder's ``worker.log``; submitit's own logs stay in ``<sweep>/.sweep/submitit``)."""
    env = {**os.environ, **thread_env(max(1, threads))}
    proc = subprocess.run(worker_command(Path(spec_path), force, retry_failed), env=env,
                          check=False)
    return proc.returncode


def run_slurm(runs: Sequence[RunSpec], options: SlurmOptions, *, cluster: str = "slurm",
              force: bool = False, retry_failed: bool = False, wait: bool = True,
              say: Callable[[str], None] = print) -> dict[str, Outcome]:
    """Submit ``runs`` as one submitit job array; wait for them unless ``wait`` is false.

    Raises:
        ConfigError: submitit is not installed, or the cluster refuses the parameters.
    """
    try:
        import submitit
    except ImportError:
        raise ConfigError("the slurm backend needs submitit: pip install 'egs-bench[slurm]'") \
            from None
    if not runs:
        return {}
    sweep_dir = Path(runs[0].sweep_dir)
    # one folder for every job: submitit names its files by job id; a "%j" in the folder would
    # also be created literally, as an empty folder named %j
    executor = submitit.AutoExecutor(folder=sweep_dir / STATE_DIR / "submitit",
                                     cluster=cluster)
    params = {"timeout_min": int(round(options.timeout_min)), "name": options.name,
              "cpus_per_task": options.cpus_per_task, "gpus_per_node": options.gpus_per_node,
              "mem_gb": options.mem_gb, "slurm_partition": options.partition,
              "slurm_array_parallelism": options.array_parallelism,
              "slurm_additional_parameters": options.additional_parameters or None}
    try:
        executor.update_parameters(**{k: v for k, v in params.items() if v is not None})
    except (NameError, AssertionError) as exc:
        raise ConfigError(f"submitit rejected the slurm options: {exc}") from None
    paths = [str(spec_file(s)) for s in runs]
    jobs = executor.map_array(slurm_job, paths, [force] * len(runs), [retry_failed] * len(runs),
                              [options.cpus_per_task] * len(runs))
    ids = {s.run_id: j.job_id for s, j in zip(runs, jobs, strict=True)}
    write_text_atomic(sweep_dir / STATE_DIR / "slurm_jobs.json", json.dumps(ids, indent=1) + "\n")
    say(f"submitted {len(jobs)} job(s) ({cluster}): {jobs[0].job_id} ... {jobs[-1].job_id}")
    if not wait:
        return {s.run_id: Outcome("submitted", f"job {ids[s.run_id]}") for s in runs}
    outcomes: dict[str, Outcome] = {}
    for n, (spec, job) in enumerate(zip(runs, jobs, strict=True), start=1):
        try:
            code = job.result()
            outcomes[spec.run_id] = _outcome(int(code), Path(spec.run_dir) / "worker.log")
        except Exception as exc:  # submitit raises its own types for a dead job
            reason = f"{type(exc).__name__}: {exc}".splitlines()[0][:200]
            if "timed out" in reason.lower() or "timeout" in reason.lower():
                mark_timeout(spec, options.timeout_min)
                outcomes[spec.run_id] = Outcome("timeout", reason)
            else:
                outcomes[spec.run_id] = Outcome("crashed", f"job {job.job_id}: {reason}")
        record = read_record(spec.run_dir) or {}
        say(f"[{n}/{len(runs)}] {record.get('state', outcomes[spec.run_id].action):13s} "
            f"{spec.run_id}")
    return outcomes
