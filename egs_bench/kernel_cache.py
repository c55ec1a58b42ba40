"""Which numba kernels egs-bench caches, and whether numba's cache holds their machine code.

Every kernel here has ``cache=True``: numba stores its machine code under ``NUMBA_CACHE_DIR``
(the rule of :mod:`egs_bench.caches`). A process about to call a kernel asks
:func:`uncached_kernels` whether that call will compile, to say so before a long silence; the
warm-up (:mod:`egs_bench.warmup`) fills the cache.

The kernel modules are named as strings and imported only when asked about, so that this base
module depends on no package of the library at import time.
"""

from __future__ import annotations

import importlib
from typing import Any

#: modules that define ``cache=True`` numba kernels
KERNEL_MODULES = (
    "egs_bench.render.numba_kernels",
    "egs_bench.render.numba_projection",
    "egs_bench.datasets.esim_kernels",
    "egs_bench.datasets.synthetic.raycast",
    "egs_bench.datasets.eventreplica.splat_kernels",
)


def cached_kernels() -> dict[str, Any]:
    """The entry kernels of :data:`KERNEL_MODULES`: their ``cache=True`` numba dispatchers that
    Python code calls, by ``module.name``.

    Left out: helpers with ``inline="always"``, which numba compiles into their callers, and
    private helpers (``_name``) that only other kernels call: they are compiled with their
    callers, and a caller loaded from the cache never asks them for code.
    """
    from numba.core.caching import NullCache
    from numba.core.dispatcher import Dispatcher

    kernels: dict[str, Any] = {}
    for module_name in KERNEL_MODULES:
        module = importlib.import_module(module_name)
        for name, obj in vars(module).items():
            if (isinstance(obj, Dispatcher) and obj.__module__ == module_name
                    and not name.startswith("_")
                    and not isinstance(getattr(obj, "_cache", None), NullCache)
                    and obj.targetoptions.get("inline") != "always"):
                kernels[f"{module_name}.{name}"] = obj
    return kernels


def uncached_kernels(prefix: str = "egs_bench") -> list[str]:
    """The kernels of :func:`cached_kernels` under the module ``prefix`` that numba's cache
    holds no machine code for (for the current source): their first call compiles, which takes
    seconds to minutes.

    Reads numba's cache index (a private numba API, pinned in constraints.txt); when that
    fails, the kernel counts as uncached, so a caller's "compiling…" line errs on saying it.
    """
    missing = []
    for name, kernel in cached_kernels().items():
        if not name.startswith(prefix):
            continue
        try:
            cached = bool(kernel._cache._cache_file._load_index())  # {} on a stale source stamp
        except Exception:  # numba moved its internals: assume the worst
            cached = False
        if not cached:
            missing.append(name)
    return missing
