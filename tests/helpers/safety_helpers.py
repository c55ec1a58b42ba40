"""Helpers of the regression suite (a uniquely named module: ``from conftest import`` is
ambiguous when several conftest.py files are collected)."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[2]

# The cheapest real SLAM run: every stage once on the 4-frame plane sequence.
QUICK_RUN = ["--preset", "cpu", "--quiet", "--set", "init_iters=2", "--set", "tracking_iters=2",
             "--set", "mapping_iters=1", "--set", "resolution_scale=1.0"]


def python_subprocess(code: str, cwd: Path) -> subprocess.Popen:
    """Start ``python -c code`` with this checkout first on the path (a separate process, so
    signals and locks behave as for a second user of the same folders)."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(REPO_ROOT), os.environ.get("PYTHONPATH", "")]))
    return subprocess.Popen([sys.executable, "-c", code], cwd=cwd, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def wait_for(condition: Callable[[], bool], proc: subprocess.Popen, timeout: float = 90.0
             ) -> None:
    """Poll ``condition`` until true; fail with the subprocess's output if it ends first."""
    deadline = time.monotonic() + timeout
    while not condition():
        if proc.poll() is not None:
            out, err = proc.communicate()
            pytest.fail(f"subprocess ended early (rc {proc.returncode}): {out}\n{err}")
        if time.monotonic() > deadline:
            proc.kill()
            pytest.fail("timed out waiting for the subprocess")
        time.sleep(0.05)
