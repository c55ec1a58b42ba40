#!/usr/bin/env bash
# One-command GPU check: builds gsplat if needed, runs the CUDA tests, times egs and monogs with
# the paper preset on a built-in 448x256 sequence and writes gpu_check.json (see gpu_check.py).
# Needs the project installed with its CUDA extra: pip install -e ".[cuda]" (or PYTHON=...).
# Arguments go to gpu_check.py, e.g. --frames 100 --json out.json.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
# gsplat compiles its CUDA kernels on first use (about a minute); keep them between checks.
export TORCH_EXTENSIONS_DIR=${TORCH_EXTENSIONS_DIR:-$PWD/.cache/torch_extensions}
export TORCH_CUDA_ARCH_LIST=${TORCH_CUDA_ARCH_LIST:-$("$PY" -c \
  "import torch; m, n = torch.cuda.get_device_capability(); print(f'{m}.{n}')")}
export MAX_JOBS=${MAX_JOBS:-$(nproc)}
export NUMBA_CACHE_DIR=${NUMBA_CACHE_DIR:-$PWD/.cache/numba}
export EGS_BENCH_DATA=${EGS_BENCH_DATA:-$PWD/data}
export OMP_WAIT_POLICY=PASSIVE MPLBACKEND=Agg
exec "$PY" benchmarks/gpu_check.py "$@"
