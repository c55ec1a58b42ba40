"""Where runs go: the one rule for a run folder's location, and the names inside a sweep's
output folder.

Every command that picks a run folder itself (``egs-bench run`` without ``--out``, the demo,
a sweep) puts it at ``<root>/runs/<sequence>/<method>[__<variant>][/seed<k>]``
(:func:`run_location`): the runs of one sequence sit together, as the leaderboard's columns
do. ``variant`` tells apart settings of one method (a sweep's named settings, presets,
devices); ``seed`` is a level of its own when runs are repeated. Names are made safe for one
folder level by :func:`folder_name`.

A sweep's output folder holds its runs under :data:`RUNS_DIR`, its coordination state under
:data:`STATE_DIR` and its summary tables :data:`SUMMARY_CSV` and :data:`SUMMARY_MD`. The sweep
writes them (:mod:`egs_bench.experiments`); the report recognises a sweep folder by them.
"""

from __future__ import annotations

import re
from pathlib import Path

#: the folder of the run folders under a root (a sweep's or demo's output folder, or ".")
RUNS_DIR = "runs"
#: locks, worker specs and launcher logs of a sweep
STATE_DIR = ".sweep"
#: one row per run of a sweep: its state and metrics
SUMMARY_CSV = "sweep_summary.csv"
#: the same summary as a markdown table
SUMMARY_MD = "sweep_summary.md"

# what a folder name keeps; a path separator or a method's "name:variant" colon does not
_UNSAFE = re.compile(r"[^A-Za-z0-9._=+-]+")


def folder_name(text: str) -> str:
    """``text`` as one folder level: each run of characters other than letters, digits and
    ``._=+-`` becomes ``_`` (``"egs:depth tv"`` -> ``"egs_depth_tv"``)."""
    return _UNSAFE.sub("_", text)


def relative_run_path(sequence: str, method: str, *, variant: str = "",
                      seed: int | None = None) -> str:
    """``<sequence>/<method>[__<variant>][/seed<k>]``, each part a :func:`folder_name`: the
    run's place under :data:`RUNS_DIR` (a sweep's run id)."""
    leaf = folder_name(method) + (f"__{folder_name(variant)}" if variant else "")
    parts = [folder_name(sequence), leaf] + ([] if seed is None else [f"seed{seed}"])
    return "/".join(parts)


def run_location(root: str | Path, sequence: str, method: str, *, variant: str = "",
                 seed: int | None = None) -> Path:
    """The run folder of ``method`` on ``sequence`` under ``root``:
    ``<root>/runs/`` + :func:`relative_run_path`."""
    return Path(root) / RUNS_DIR / relative_run_path(sequence, method, variant=variant,
                                                     seed=seed)
