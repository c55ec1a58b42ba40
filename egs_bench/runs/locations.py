"""Where runs go: the names inside a sweep's output folder.

A sweep's output folder holds its runs under :data:`RUNS_DIR`, its coordination state under
:data:`STATE_DIR` and its summary tables :data:`SUMMARY_CSV` and :data:`SUMMARY_MD`. The sweep
writes them (:mod:`egs_bench.experiments`); the report recognises a sweep folder by them.
"""

from __future__ import annotations

#: the folder of a sweep's run folders
RUNS_DIR = "runs"
#: locks, worker specs and launcher logs of a sweep
STATE_DIR = ".sweep"
#: one row per run of a sweep: its state and metrics
SUMMARY_CSV = "sweep_summary.csv"
#: the same summary as a markdown table
SUMMARY_MD = "sweep_summary.md"
