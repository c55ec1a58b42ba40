"""Run every benchmark script in this folder (``make bench``), one process each.

Each script prints its own table; numbers go to BENCHMARKS.md by hand with machine and date.
Pass script names to run a subset: ``python benchmarks/run_all.py bench_esim``.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from egs_bench.caches import numba_cache_dir


def main(names: list[str]) -> int:
    here = Path(__file__).resolve().parent
    scripts = sorted(here.glob("bench_*.py"))
    if names:
        scripts = [s for s in scripts if s.stem in names]
    # the kernels `make setup` compiled: the scripts time the code, not numba's compiler
    env = {**os.environ, "NUMBA_CACHE_DIR": str(numba_cache_dir())}
    failed = 0
    for script in scripts:
        print(f"\n=== {script.name} ===", flush=True)
        failed += subprocess.call([sys.executable, str(script)], env=env) != 0
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
