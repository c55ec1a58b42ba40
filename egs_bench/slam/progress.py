"""The text a SLAM run's progress bar shows during a long phase (map initialisation, a
keyframe's mapping round): iterations done and the time left, or that kernels are compiling.

The time left is extrapolated only from iterations run with compiled kernels: on a cold numba
cache the first iteration is minutes of compilation, and an ETA taken from it was off by hours.
"Compiling" is said only when numba's cache lacks the kernels; kernels that are merely not
loaded yet come from the cache in about a second.
"""

from __future__ import annotations

import time
from collections.abc import Callable

COMPILING = "compiling kernels…"


class PhaseProgress:
    """Formats ``on_phase(name, done, total)`` calls (see :meth:`SlamSystem.run`) as one line.

    Args:
        kernels_ready: whether the renderer's compiled kernels are in this process (e.g.
            :func:`egs_bench.render.cpu_kernels.kernels_ready`; None: nothing compiles).
        clock: seconds of a monotonic clock.
        cold_cache: whether numba's cache lacks renderer kernels, asked once, when kernels
            are first found missing (default: :func:`egs_bench.kernel_cache.uncached_kernels`).
    """

    def __init__(self, kernels_ready: Callable[[], bool] | None = None,
                 clock: Callable[[], float] = time.perf_counter,
                 cold_cache: Callable[[], bool] | None = None) -> None:
        self._kernels_ready = kernels_ready or (lambda: True)
        self._clock = clock
        self._cold_cache = cold_cache or _render_kernels_uncached
        self._cold: bool | None = None  # the answer of cold_cache, once asked
        self._since: tuple[float, int] | None = None  # (time, done) from which speed is measured

    def text(self, name: str, done: int, total: int) -> str:
        """``"map init 12/150 iterations, ETA 40 s"``; ``"..., compiling kernels…"`` while the
        kernels are not compiled; no ETA until an iteration has run with compiled kernels."""
        now = self._clock()
        head = f"{name} {done}/{total} iterations"
        if done == 0:
            self._since = None  # a new phase
        if not self._kernels_ready():
            self._since = None
            if self._cold is None:
                self._cold = self._cold_cache()
            return f"{head}, {COMPILING}" if self._cold else head
        if self._since is None or done < self._since[1]:
            self._since = (now, done)
        t0, done0 = self._since
        if done <= done0:
            return head
        eta = (now - t0) / (done - done0) * (total - done)
        return f"{head}, ETA {eta:.0f} s"


def _render_kernels_uncached() -> bool:
    from egs_bench.kernel_cache import uncached_kernels

    return bool(uncached_kernels("egs_bench.render"))
