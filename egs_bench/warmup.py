"""Compile the numba kernels ahead of their first use (``egs-bench warm-up``, run by
``make setup``).

numba compiles a kernel the first time it is called with new argument types and, as every
kernel here has ``cache=True``, stores the machine code under ``NUMBA_CACHE_DIR`` for later
processes. On a cold cache the first ``make demo`` spends minutes compiling inside its sequence
generation and its first SLAM frame. Warming runs, on tiny inputs, the library code the demo and
the generators run (a synthetic sequence with events, a SLAM run of each demo method, an
EventReplica view synthesis), so each kernel compiles with the argument types those paths give
it, not with types guessed here.
"""

from __future__ import annotations

import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from egs_bench.kernel_cache import cached_kernels

# Tiny but legal inputs: the synthetic generator's smallest image, two frames (a first frame
# that initialises the map and one tracked frame), the demo's motion and exposure.
_SIZE_PX = 16
_FRAMES = 2


@dataclass(frozen=True)
class WarmupReport:
    """What a warm-up did.

    Attributes:
        compiled: kernels compiled now (their machine code was not in the cache).
        loaded: kernels whose machine code came from the cache.
        missing: cached kernels none of the warm-up's paths called (a gap in :func:`warm_up`).
        seconds: wall-clock time of the warm-up.
    """

    compiled: tuple[str, ...]
    loaded: tuple[str, ...]
    missing: tuple[str, ...]
    seconds: float


def warm_up(say: Callable[[str], None] = print) -> WarmupReport:
    """Compile (or load from the cache) every cached kernel with the argument types the demo,
    the sequence generators and the CPU rasteriser use.

    Args:
        say: where the one-line progress messages go.

    Returns:
        What was compiled, loaded and missed; the temporary data it made is deleted.
    """
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="egs_bench_warmup_") as tmp:
        say("warming the numba kernels: synthetic sequence with events")
        seq = _tiny_synthetic(Path(tmp) / "seq")
        say("warming the numba kernels: SLAM runs (CPU rasteriser, forward and backward)")
        _tiny_slam_runs(seq, Path(tmp) / "runs")
        say("warming the numba kernels: EventReplica view synthesis")
        _tiny_view_synthesis()
    compiled, loaded, missing = [], [], []
    for name, kernel in cached_kernels().items():
        stats = kernel.stats
        if stats.cache_misses:
            compiled.append(name)
        elif stats.cache_hits:
            loaded.append(name)
        else:
            missing.append(name)
    return WarmupReport(tuple(compiled), tuple(loaded), tuple(missing),
                        time.perf_counter() - start)


def _tiny_synthetic(out: Path) -> Path:
    """A 16x16 two-frame sequence of the demo's room and motion: ray caster and ESIM."""
    from egs_bench.datasets.registry import BUILTIN_SEQUENCES
    from egs_bench.datasets.synthetic import make_synthetic
    from egs_bench.demo import DEMO_SEQUENCE

    demo = BUILTIN_SEQUENCES[DEMO_SEQUENCE]
    return make_synthetic(demo.scene, out, frames=_FRAMES, width=_SIZE_PX, height=_SIZE_PX,
                          fps=demo.fps, exposure_ms=demo.exposure_ms, speed=demo.speed,
                          seed=demo.seed, progress=False)


def _tiny_slam_runs(seq_path: Path, out: Path) -> None:
    """Each demo method on ``seq_path`` with the demo's preset and options: the projection and
    compositing kernels in the SLAM's dtype, forward and backward."""
    from egs_bench.datasets.sequence import Sequence
    from egs_bench.demo import DEMO_METHODS, DEMO_OPTIONS, DEMO_PRESET
    from egs_bench.runs.registry import get_method
    from egs_bench.slam.methods import ConfiguredSlamMethod

    seq = Sequence.open(seq_path)
    for name in DEMO_METHODS:
        method = get_method(name)
        if isinstance(method, ConfiguredSlamMethod):
            method = method.with_options(DEMO_OPTIONS)
        method.run(seq, out / name, preset=DEMO_PRESET, device="cpu", max_frames=_FRAMES,
                   progress=False)


def _tiny_view_synthesis() -> None:
    """One interpolated view between two 16x16 key frames: the point-splatting kernel."""
    from egs_bench.datasets.eventreplica.interpolate import DepthWarpInterpolator, KeyFrame
    from egs_bench.geometry import Intrinsics

    rgb = np.full((_SIZE_PX, _SIZE_PX, 3), 0.5, np.float32)
    depth = np.ones((_SIZE_PX, _SIZE_PX), np.float32)
    a = KeyFrame(rgb, depth, np.eye(4))
    pose_b = np.eye(4)
    pose_b[0, 3] = 0.01
    b = KeyFrame(rgb, depth, pose_b)
    f = float(_SIZE_PX)
    camera = Intrinsics(width=_SIZE_PX, height=_SIZE_PX, fx=f, fy=f, cx=f / 2, cy=f / 2)
    DepthWarpInterpolator().prepare(a, b, camera)(0.5)

