"""``python -m egs_bench`` is the same command as the ``egs-bench`` console script (for
``python -m cProfile -m egs_bench ...`` and environments without the script on PATH); both
set the process environment torch and numba read, and importing the CLI sets none."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from egs_bench.caches import ENV_CACHE, ENV_NUMBA, numba_cache_dir


def test_python_dash_m_runs_the_command() -> None:
    proc = subprocess.run([sys.executable, "-m", "egs_bench", "list-scenes"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "office" in proc.stdout


# Prints, at import of the CLI and at the process's exit, the variables the entry point sets,
# then starts the command the way ``{start}`` does.
_PROBE = """
import atexit, os, sys
def report() -> None:
    print("exit", os.environ.get("OMP_WAIT_POLICY"), os.environ.get("NUMBA_CACHE_DIR"))
atexit.register(report)
import egs_bench.cli
print("import", os.environ.get("OMP_WAIT_POLICY"), os.environ.get("NUMBA_CACHE_DIR"))
sys.argv = ["egs-bench", "list-scenes"]
{start}
"""
_STARTS = {
    "python -m egs_bench": 'import runpy; runpy.run_module("egs_bench", run_name="__main__")',
    "console script": ('from importlib.metadata import entry_points; '
                       '(script,) = entry_points(group="console_scripts", name="egs-bench"); '
                       'script.load()()'),
}


@pytest.mark.parametrize("start", sorted(_STARTS))
def test_the_entry_points_set_the_environment_and_importing_the_cli_does_not(
        start: str, tmp_path: Path) -> None:
    env = {k: v for k, v in os.environ.items() if k not in ("OMP_WAIT_POLICY", ENV_NUMBA)}
    env[ENV_CACHE] = str(tmp_path / "cache")
    proc = subprocess.run([sys.executable, "-c", _PROBE.format(start=_STARTS[start])],
                          env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0] == "import None None"
    assert "office" in proc.stdout
    expected = numba_cache_dir({ENV_CACHE: str(tmp_path / "cache")})
    assert lines[-1] == f"exit PASSIVE {expected}"
