"""The run folder: the contract between a method run (ours, a baseline, an import) and
evaluation, in two parts.

* :mod:`egs_bench.runs.contract`, the file contract: what files a run folder has
  (``run.yaml``, ``config.yaml``, ``status.json``, ``trajectory.txt``, renders, timing, log,
  metrics, plots), what they hold and reading and writing them (:class:`RunFiles`);
* :mod:`egs_bench.runs.coordination`, who writes a folder: the lock a writing process holds,
  its heartbeat, and whether a ``running`` status still has a live writer (:class:`RunFolder`,
  the :class:`RunFiles` a method run creates).

This module is the one place callers import both from.
"""

from egs_bench.runs.contract import (
    CONFIG_FILE,
    ESTIMATE_COVERAGE,
    ESTIMATE_DEFAULTS,
    KEYFRAMES_FILE,
    LOCK_FILE,
    LOG_FILE,
    METRICS_FILE,
    PLOT_FILES,
    PLOTS_DIR,
    RENDERS_DIR,
    RUN_FILE,
    STATES,
    STATUS_FILE,
    TIMING_FILE,
    TRAJECTORY_FILE,
    RunFiles,
    RunStatus,
    RunTiming,
    find_runs,
    read_json_object,
    run_identity,
)
from egs_bench.runs.coordination import HEARTBEAT_S, STALE_AFTER_S, RunFolder

__all__ = [
    "CONFIG_FILE",
    "ESTIMATE_COVERAGE",
    "ESTIMATE_DEFAULTS",
    "HEARTBEAT_S",
    "KEYFRAMES_FILE",
    "LOCK_FILE",
    "LOG_FILE",
    "METRICS_FILE",
    "PLOTS_DIR",
    "PLOT_FILES",
    "RENDERS_DIR",
    "RUN_FILE",
    "STALE_AFTER_S",
    "STATES",
    "STATUS_FILE",
    "TIMING_FILE",
    "TRAJECTORY_FILE",
    "RunFiles",
    "RunFolder",
    "RunStatus",
    "RunTiming",
    "find_runs",
    "read_json_object",
    "run_identity",
]
