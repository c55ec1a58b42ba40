"""The engine's benchmark scripts answer ``--help`` (argparse formats every help string; a
stray ``%`` made one of them crash instead)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"


@pytest.mark.parametrize("script", ["gpu_cost_model", "gpu_accuracy", "gpu_check",
                                    "tracking_convergence", "oracle_tracking"])
def test_help(script: str) -> None:
    proc = subprocess.run([sys.executable, str(BENCHMARKS / f"{script}.py"), "--help"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("usage:")
