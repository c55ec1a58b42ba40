"""SLAM settings that depend on the kind of sequence: the paper's real-data parameters.

EGS-SLAM §V.B uses theta 0.25, lambda_E 0.05, lambda_ID 0.95 on synthetic data and theta 0.3,
lambda_E 0.15, lambda_ID 0.85 on its real recordings (DEVD). A sequence imported from a real
recording (:mod:`egs_bench.recordings`) says ``source: real`` in its ``meta.yaml``; runs on it
start from the real-data values (a method's own settings and ``--set`` still override them),
and the run's ``config.yaml`` records the values used. The SLAM configuration reads them here,
so that it depends on the sequence's metadata only, not on the importer.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

#: EGS-SLAM §V.B, real data (``SlamConfig`` field names)
REAL_DATA_SLAM: dict[str, float] = {"theta": 0.3, "lambda_e": 0.15, "lambda_id": 0.85}


def sequence_slam_defaults(meta: Mapping[str, Any]) -> dict[str, Any]:
    """SLAM configuration fields implied by a sequence's ``meta.yaml``: the paper's real-data
    values for ``source: real``, nothing otherwise."""
    return dict(REAL_DATA_SLAM) if meta.get("source") == "real" else {}
