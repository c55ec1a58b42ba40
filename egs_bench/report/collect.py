"""Read what a report shows: every run of a run folder, runs root or sweep, as typed records.

Reading never aborts on one bad run: :func:`egs_bench.eval.results.collect_results` turns an
unreadable folder into a ``broken`` result with its reason, and the optional files a run page
shows (``timing.json``, ``slam_stats.json``, ``keyframes.txt``, ``metrics.json``) that cannot
be read become a line in :attr:`RunRecord.problems` instead of an exception.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from egs_bench.errors import EgsBenchError, InputError
from egs_bench.eval.leaderboard import Leaderboard, build
from egs_bench.eval.metrics_file import RunMetrics, read_metrics
from egs_bench.eval.protocols import DEFAULT_PROTOCOL, get_protocol
from egs_bench.eval.results import METRICS, RunResult, collect_results
from egs_bench.eval.tables import slug
from egs_bench.runs.folder import (
    METRICS_FILE,
    RunFolder,
    RunStatus,
    RunTiming,
    find_runs,
    read_json_object,
)
from egs_bench.runs.locations import STATE_DIR, SUMMARY_CSV

#: ``slam_stats.json`` (written by the built-in SLAM runner next to the map).
SLAM_STATS_FILE = "slam_stats.json"
#: What the report was made from.
SOURCE_KINDS = ("run", "runs", "sweep")


@dataclass(frozen=True)
class RunRecord:
    """One run as its pages show it.

    Attributes:
        result: identity, status, reason and metric values (stored units) under the report's
            first protocol.
        page: file stem of the run's page (unique in the report).
        info: the parsed ``run.yaml`` (empty when unreadable).
        config: the parsed ``config.yaml`` (empty when absent or unreadable).
        status: ``status.json`` (``None`` when unreadable).
        metrics: the run's ``metrics.json`` when it is under the first protocol (``None`` if
            none).
        timing: ``timing.json`` (``None`` when absent or unreadable).
        slam_stats: ``slam_stats.json`` (``None`` when absent or unreadable).
        keyframes: keyframe frame indices (empty when none were written).
        files: names of the run's own files and folders, relative to the run folder.
        problems: one line per optional file that could not be read (names the file).
    """

    result: RunResult
    page: str
    info: dict[str, Any] = field(default_factory=dict)
    config: dict[str, Any] = field(default_factory=dict)
    status: RunStatus | None = None
    metrics: RunMetrics | None = None
    timing: RunTiming | None = None
    slam_stats: dict[str, Any] | None = None
    keyframes: list[int] = field(default_factory=list)
    files: list[str] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)

    @property
    def preset(self) -> str | None:
        value = self.config.get("preset")
        return value if isinstance(value, str) else None

    @property
    def device(self) -> str | None:
        value = self.config.get("device")
        return value if isinstance(value, str) else None

    @property
    def flagged(self) -> bool:
        """Needs the reader's attention: not a complete, evaluated run."""
        return self.result.status != "ok"


@dataclass
class ReportData:
    """Everything the pages are rendered from.

    Attributes:
        source: the folder the report was made from.
        kind: ``run`` (one run folder), ``runs`` (a folder of runs) or ``sweep``.
        protocols: the protocols with a leaderboard, first one used on the run pages.
        boards: protocol -> its leaderboard.
        runs: one record per run folder found (sorted by folder).
    """

    source: Path
    kind: str
    protocols: list[str]
    boards: dict[str, Leaderboard]
    runs: list[RunRecord]

    @property
    def sequences(self) -> list[str]:
        return sorted({r.result.sequence for r in self.runs if r.result.sequence})


def source_kind(source: Path) -> str:
    """``run``, ``sweep`` (a sweep's output folder) or ``runs`` (any folder holding runs)."""
    if RunFolder.is_run_folder(source):
        return "run"
    if (source / STATE_DIR).is_dir() or (source / SUMMARY_CSV).is_file():
        return "sweep"
    return "runs"


def metrics_protocols(run_dirs: list[Path]) -> list[str]:
    """The protocols named by the runs' ``metrics.json`` files, the default one first; only the
    default when no run has been evaluated. Unreadable files are skipped (the run's record
    reports them)."""
    found: set[str] = set()
    for path in run_dirs:
        if not (path / METRICS_FILE).is_file():
            continue
        try:
            name = read_metrics(path).protocol
        except EgsBenchError:
            continue
        try:
            get_protocol(name)
        except EgsBenchError:
            continue
        found.add(name)
    return sorted(found or {DEFAULT_PROTOCOL}, key=lambda p: (p != DEFAULT_PROTOCOL, p))


def _page_name(result: RunResult, taken: set[str]) -> str:
    base = slug(result.rel) if result.rel else "run"
    name, k = base, 2
    while name in taken:  # slugs fold case and punctuation: keep them unique
        name, k = f"{base}-{k}", k + 1
    taken.add(name)
    return name


def _own_files(path: Path) -> list[str]:
    """The run folder's entries (hidden ones left out), renders as one folder entry."""
    try:
        return sorted(p.name + ("/" if p.is_dir() else "") for p in path.iterdir()
                      if not p.name.startswith("."))
    except OSError:
        return []


def read_run_record(result: RunResult, page: str, protocol: str) -> RunRecord:
    """Read the files a run page shows; problems become lines, never exceptions."""
    problems: list[str] = []
    record: dict[str, Any] = {"result": result, "page": page, "files": _own_files(result.path)}
    try:
        run = RunFolder.open(result.path)
    except (EgsBenchError, OSError, ValueError) as exc:
        return RunRecord(**record, problems=[str(exc)])
    record["info"] = run.info

    def attempt(what: str, read: Any) -> Any:
        try:
            return read()
        except (EgsBenchError, OSError, ValueError, TypeError) as exc:
            problems.append(str(exc) if isinstance(exc, EgsBenchError)
                            else f"{result.path / what}: {exc}")
            return None

    record["config"] = attempt("config.yaml", lambda: run.read_config()
                               if (run.path / "config.yaml").is_file() else {}) or {}
    record["status"] = attempt("status.json", run.read_status)
    record["timing"] = attempt("timing.json", run.read_timing)
    stats_path = run.path / SLAM_STATS_FILE
    record["slam_stats"] = attempt(SLAM_STATS_FILE, lambda: read_json_object(stats_path)
                                   if stats_path.is_file() else None)
    keyframes = attempt("keyframes.txt", run.read_keyframes)
    record["keyframes"] = [] if keyframes is None else [int(k) for k in keyframes]
    if run.metrics_path.is_file():
        metrics = attempt(METRICS_FILE, lambda: read_metrics(run.path))
        if metrics is not None and metrics.protocol == protocol:
            record["metrics"] = metrics
    return RunRecord(**record, problems=problems)


def collect_report(source: str | Path, protocols: list[str] | None = None,
                   evaluate_missing: bool = True, metrics: tuple[str, ...] = tuple(METRICS)
                   ) -> ReportData:
    """Read every run under ``source`` and build one leaderboard per protocol.

    Args:
        source: a run folder, a folder of run folders, or a sweep's output folder.
        protocols: the leaderboards' protocols (default: those the runs were evaluated under).
        evaluate_missing: evaluate runs without ``metrics.json`` under the first protocol
            (written into the run folder, as ``egs-bench leaderboard`` does).
        metrics: metric keys of the leaderboards (those without any value are dropped).

    Raises:
        InputError: ``source`` is missing or holds no run folder.
        ConfigError: an unknown protocol.
    """
    root = Path(source)
    paths = find_runs(root)
    if not paths:
        raise InputError(root, "holds no run folders (no run.yaml found)")
    for name in protocols or []:
        get_protocol(name)
    chosen = list(dict.fromkeys(protocols)) if protocols else metrics_protocols(paths)
    boards: dict[str, Leaderboard] = {}
    for i, name in enumerate(chosen):
        results = collect_results(root, name, evaluate_missing=evaluate_missing and i == 0)
        boards[name] = build(results, metrics)
    first = boards[chosen[0]].results
    assert first is not None
    taken: set[str] = set()
    runs = [read_run_record(r, _page_name(r, taken), chosen[0]) for r in first.runs]
    return ReportData(root, source_kind(root), chosen, boards, runs)
