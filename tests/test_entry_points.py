"""``python -m egs_bench`` is the same command as the ``egs-bench`` console script (for
``python -m cProfile -m egs_bench ...`` and environments without the script on PATH)."""

import subprocess
import sys


def test_python_dash_m_runs_the_command() -> None:
    proc = subprocess.run([sys.executable, "-m", "egs_bench", "list-scenes"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "office" in proc.stdout
