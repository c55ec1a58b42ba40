"""``egs-bench sweep``: expand a sweep file, run what is not finished, summarise every run.

Steps: resolve the sequences (built-in names are generated once, here, before any parallel run
could race on them), expand the grid (:mod:`~egs_bench.experiments.spec`), keep the runs of this
shard, decide per run without starting a process when nothing is to be done (finished with the
same configuration, stale, conflict), start the rest on the chosen backend
(:mod:`~egs_bench.experiments.backends`), then write the sweep summary: every run's state, wall
time and failure reason, plus ATE and PSNR where evaluated, to ``<out>/sweep_summary.csv`` and
``<out>/sweep_summary.md``, and the HTML report of its runs to ``<out>/report/``
(:mod:`egs_bench.report`). Starting the same command again after a kill resumes the sweep.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, get_args

import pandas as pd

from egs_bench.errors import ConfigError, EgsBenchError, InputError, UnwritableOutputError
from egs_bench.eval.metrics_file import read_metrics
from egs_bench.eval.results import metric_values
from egs_bench.experiments.backends import Outcome, plan_slots, run_local, run_slurm
from egs_bench.experiments.spec import RunSpec, SweepSpec, expand, in_shard
from egs_bench.experiments.worker import (
    EVALUATE,
    KEEP_FAILED,
    STARTS_WORK,
    decide,
    lock_is_held,
    read_record,
    run_state,
)
from egs_bench.fileio import DISK_FULL, write_text_atomic
from egs_bench.runs.folder import RunFolder
from egs_bench.runs.locations import SUMMARY_CSV, SUMMARY_MD

SweepBackend = Literal["local", "slurm"]
BACKENDS: tuple[SweepBackend, ...] = get_args(SweepBackend)
DONE_STATES = ("done",)


@dataclass
class SweepReport:
    """Result of one sweep invocation.

    Attributes:
        out: the sweep's output folder.
        runs: every run of the sweep (all shards).
        selected: run ids of this invocation's shard.
        summary: the summary table (one row per selected run).
        summary_md: the same as Markdown (also written to ``sweep_summary.md``).
        outcomes: each started run's outcome by run id.
        ungenerated: built-in sequence names of the sweep not generated yet (only with
            ``dry_run`` / ``status_only``, which generate nothing; their runs are not in
            ``runs``).
    """

    out: Path
    runs: list[RunSpec]
    selected: list[str]
    summary: pd.DataFrame
    summary_md: str = ""
    outcomes: dict[str, Outcome] = field(default_factory=dict)
    ungenerated: list[str] = field(default_factory=list)

    @property
    def all_done(self) -> bool:
        return bool(len(self.summary)) and bool((self.summary["state"] == "done").all())

    def full_disk(self) -> UnwritableOutputError | None:
        """The full disk that failed a run of this invocation, naming the file the run could
        not write (from the run's recorded reason), or None."""
        reasons = self.summary["reason"] if "reason" in self.summary else []
        for reason in reasons:
            if isinstance(reason, str) and DISK_FULL in reason:
                where = reason.split(": ", 1)[-1].rsplit(f": {DISK_FULL}", 1)[0]
                return UnwritableOutputError(where or self.out, DISK_FULL)
        return None


def resolve_sequences(spec: SweepSpec, progress: bool = False, generate: bool = True
                      ) -> tuple[dict[str, Path], list[str]]:
    """Each sequence entry of the sweep -> its folder (generating built-in names once), and,
    when ``generate`` is false, the built-in names not generated yet (left out of the mapping).

    Raises:
        InputError: an entry is neither a folder, a name under the data root, nor built in.
    """
    from egs_bench.datasets.registry import BUILTIN_SEQUENCES, resolve_sequence

    found: dict[str, Path] = {}
    ungenerated: list[str] = []
    for entry in spec.sequences:
        try:
            found[entry] = Path(resolve_sequence(entry, generate=generate, progress=progress))
        except InputError:
            if generate or entry not in BUILTIN_SEQUENCES:
                raise
            ungenerated.append(entry)
    return found, ungenerated


def prepare(spec: SweepSpec, out: Path | None = None,
            extra_options: Mapping[str, Any] | None = None, progress: bool = False,
            generate: bool = True) -> tuple[list[RunSpec], list[str]]:
    """Resolve the sequences and expand the grid into run specs; also returns the built-in
    sequences not generated yet (only when ``generate`` is false; their runs are left out)."""
    found, ungenerated = resolve_sequences(spec, progress, generate)
    available = dataclasses.replace(
        spec, sequences=tuple(e for e in spec.sequences if e in found))
    return expand(available, found, out, extra_options), ungenerated


def _metrics(run_dir: Path, protocol: str) -> tuple[float, float]:
    """ATE [cm] and PSNR [dB] of a run's ``metrics.json`` under ``protocol`` (NaN where absent,
    unreadable or made under another protocol)."""
    try:
        metrics = read_metrics(run_dir)
    except EgsBenchError:
        return math.nan, math.nan
    if metrics.protocol != protocol:
        return math.nan, math.nan
    values = metric_values(metrics)
    return 100.0 * values.get("ate", math.nan), values.get("psnr", math.nan)


def _progress(run_dir: Path) -> str:
    """How far a run's method got (``"frame 123/300"``), or ``""`` when it does not say."""
    try:
        return RunFolder.open(run_dir).read_status().progress_text()
    except (OSError, ValueError, EgsBenchError):
        return ""


def run_row(spec: RunSpec, outcome: Outcome | None = None, invoked: bool = True
            ) -> dict[str, Any]:
    """One summary row: identity, state, this invocation's action, wall time, reason, ATE/PSNR.

    States: ``done``, ``failed`` (the method, or the evaluation of its output: reason
    ``evaluation: ...``), ``tracking_lost``, ``interrupted``, ``timeout``, ``running`` (a
    process holds the run), ``pending`` (never started), ``stale`` (finished with another
    configuration), ``conflict`` (a folder the sweep did not create). A ``done`` row whose
    metrics were made under another protocol than the sweep's has no ATE/PSNR and says so.
    """
    run_dir = Path(spec.run_dir)
    record = read_record(run_dir)
    decision = decide(spec)
    wall = math.nan
    reason = ""
    if decision.action in ("stale", "conflict"):
        state, reason = decision.action, decision.why
    elif record is None:
        state = "pending"
    else:
        state = record.get("state", "running")
        if state == "running" and not lock_is_held(spec):
            state, reason = "interrupted", "the worker died before it finished (killed?)"
        elif state == "running":
            reason = f"pid {record.get('pid')} on {record.get('host')}"
            at = _progress(run_dir)
            reason += f", at {at}" if at else ""
        folder_state = run_state(run_dir)
        # the folder refines the record (a tracking loss; a folder changed since), except that
        # a failed evaluation fails a run whose method finished
        if folder_state is not None and (state == "done" or (
                state in ("failed", "tracking_lost") and folder_state != "done")):
            state = folder_state
        reason = reason or record.get("reason") or record.get("evaluation_error") or ""
        if record.get("evaluation_error"):
            reason = f"evaluation: {record['evaluation_error']}"
        if decision.action == EVALUATE:
            reason = decision.why
        elif state == "done" and decision.action == KEEP_FAILED:  # a record from before
            state = "failed"  # evaluation failures failed the run: done, never evaluated
            reason = reason or decision.why
        wall = float(record.get("run_wall_s", math.nan)) + float(record.get("eval_wall_s", 0.0))
    ate, psnr = _metrics(run_dir, spec.protocol) if state == "done" else (math.nan, math.nan)
    action = outcome.action if outcome is not None else (
        "skipped" if invoked and decision.action not in STARTS_WORK and state == "done" else "")
    if outcome is not None and outcome.note and not reason:
        reason = outcome.note
    return {"run": spec.run_id, "method": spec.method, "sequence": spec.sequence_name,
            "settings": spec.settings_name or "", "seed": spec.seed, "state": state,
            "action": action, "wall_s": round(wall, 1) if not math.isnan(wall) else math.nan,
            "ate_cm": ate, "psnr_db": psnr, "reason": reason}


def summary_table(runs: Sequence[RunSpec], outcomes: Mapping[str, Outcome] | None = None,
                  invoked: bool = True) -> pd.DataFrame:
    """The sweep summary: one row per run (see :func:`run_row`)."""
    outcomes = outcomes or {}
    return pd.DataFrame([run_row(r, outcomes.get(r.run_id), invoked) for r in runs],
                        columns=["run", "method", "sequence", "settings", "seed", "state",
                                 "action", "wall_s", "ate_cm", "psnr_db", "reason"])


def summary_markdown(df: pd.DataFrame) -> str:
    """The summary as a Markdown table plus one line of counts per state."""
    shown = df.copy()
    for col, digits in (("wall_s", 1), ("ate_cm", 2), ("psnr_db", 2)):
        shown[col] = [("" if (isinstance(v, float) and math.isnan(v)) else f"{v:.{digits}f}")
                      for v in shown[col]]
    if not shown["settings"].astype(bool).any():
        shown = shown.drop(columns="settings")
    shown = shown.drop(columns=["method", "sequence", "seed"])
    counts = df["state"].value_counts()
    line = ", ".join(f"{n} {s}" for s, n in counts.items())
    return (shown.to_markdown(index=False, disable_numparse=True)
            + f"\n\n{len(df)} runs: {line}.\n")


def write_summary(out: Path, df: pd.DataFrame) -> str:
    """Write ``sweep_summary.csv`` and ``sweep_summary.md`` (atomically); return the Markdown."""
    md = summary_markdown(df)
    out.mkdir(parents=True, exist_ok=True)
    write_text_atomic(out / SUMMARY_CSV, df.to_csv(index=False, lineterminator="\n"))
    write_text_atomic(out / SUMMARY_MD, md)
    return md


def run_sweep(spec: SweepSpec, *, out: Path | None = None,
              extra_options: Mapping[str, Any] | None = None, backend: SweepBackend = "local",
              shard: tuple[int, int] | None = None, force: bool = False,
              retry_failed: bool = False, jobs: int | None = None,
              threads_per_job: int | None = None, cluster: str = "slurm", wait: bool = True,
              dry_run: bool = False, status_only: bool = False, html_report: bool = True,
              say: Callable[[str], None] = print) -> SweepReport:
    """Run (or resume) a sweep and write its summary.

    Args:
        spec: the parsed sweep file.
        out: output folder (default ``spec.out``).
        extra_options: SLAM overrides for every run (``--set``), on top of the file's ``set``.
        backend: ``local`` or ``slurm``.
        shard: ``(i, N)``: only runs whose stable hash falls in shard ``i`` of ``N``.
        force: rerun finished and stale runs (their folders, which the sweep created, are
            replaced).
        retry_failed: rerun failed runs (tracking losses included).
        jobs, threads_per_job: local pool size and threads per run (override the file).
        cluster: submitit cluster for the slurm backend (``slurm``, or ``local``/``debug`` to
            test without a cluster).
        wait: wait for SLURM jobs (otherwise return after submitting).
        dry_run: list what would run, start nothing.
        status_only: only summarise the run folders as they are.
        html_report: write ``<out>/report/`` after the runs (not for a dry run, ``status_only``
            or SLURM without ``wait``); a report that cannot be written is a warning, never a
            failed sweep.

    Raises:
        ConfigError: an unknown backend, or a pool that cannot run these runs.
    """
    if backend not in BACKENDS:
        raise ConfigError(f"unknown backend {backend!r}; choose one of {', '.join(BACKENDS)}")
    out = (out or spec.out).resolve()
    runs, ungenerated = prepare(spec, out, extra_options, generate=not (status_only or dry_run))
    for entry in ungenerated:
        say(f"{entry}: built-in sequence not generated yet (the sweep generates it before its "
            "runs); its runs are not listed")
    selected = [r for r in runs if in_shard(r, shard)]
    outcomes: dict[str, Outcome] = {}
    if not status_only:
        todo = [r for r in selected if decide(r, force, retry_failed).action in STARTS_WORK]
        shard_txt = f" (shard {shard[0]}/{shard[1]})" if shard else ""
        say(f"sweep {out}: {len(runs)} runs, {len(selected)} in this invocation{shard_txt}, "
            f"{len(todo)} to run")
        if dry_run:
            for r in todo:
                say(f"would run {r.run_id} ({decide(r, force, retry_failed).why})")
        elif todo and backend == "local":
            slots = plan_slots(todo, spec.local, jobs, threads_per_job)
            threads = slots[0].env.get("EGS_BENCH_THREADS")
            say(f"local pool: {len(slots)} parallel run(s), {threads} thread(s) each")
            try:
                outcomes = run_local(todo, slots, force=force, retry_failed=retry_failed,
                                     timeout_min=spec.local.timeout_min, say=say)
            except KeyboardInterrupt:
                write_summary(out, summary_table(selected))
                raise
        elif todo:
            outcomes = run_slurm(todo, spec.slurm, cluster=cluster, force=force,
                                 retry_failed=retry_failed, wait=wait, say=say)
    df = summary_table(selected, outcomes, invoked=not status_only)
    # a dry run writes nothing, not even the summary (an earlier real summary stays)
    md = summary_markdown(df) if dry_run else write_summary(out, df)
    if html_report and not (dry_run or status_only) and (wait or backend == "local"):
        from egs_bench.report import SIDE_REPORT_DIR, write_side_report

        write_side_report(out, out / SIDE_REPORT_DIR, say, protocols=[spec.protocol])
    return SweepReport(out, runs, [r.run_id for r in selected], df, md, outcomes, ungenerated)
