"""Shared test fixtures: the optional ``../shared`` folder, a writable numba cache, and a tiny
generated sequence (a textured plane seen by a translating camera)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from egs_bench.caches import numba_cache_dir
from tests.helpers.plane_scene import make_plane_sequence

REPO_ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("EGS_BENCH_SHARED", REPO_ROOT.parent / "shared"))
# the kernel cache `make setup`'s warm-up filled (the CLI's rule, egs_bench/caches.py)
os.environ["NUMBA_CACHE_DIR"] = str(numba_cache_dir())
os.environ.setdefault("MPLBACKEND", "Agg")
# torch's and numba's OpenMP pools otherwise spin-wait and steal each other's 2 cores
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """``../shared/data``; tests that use it skip when it is absent (a user's fresh clone)."""
    path = SHARED / "data"
    if not path.is_dir():
        pytest.skip("../shared/data is not available")
    return path



@pytest.fixture(scope="session")
def tiny_sequence(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 4-frame 64x48 blurred sequence with events (read-only: copy before modifying)."""
    return make_plane_sequence(tmp_path_factory.mktemp("seq") / "plane")
