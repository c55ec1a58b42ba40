"""Whether the CPU rasteriser's numba kernels are ready in this process, and readying them.

A SLAM run readies the kernels before its clock starts, so that a cold cache shows as compile
time, not as a lower frame rate. Readying renders through :func:`egs_bench.render.rasterize`,
so it sits above both the dispatcher and the numba backend.
"""

from __future__ import annotations

import torch

from egs_bench.render import numba_kernels as nk
from egs_bench.render import numba_projection as npj
from egs_bench.render.rasterize import rasterize


def kernels_ready() -> bool:
    """Whether this process has the machine code of every CPU rasteriser kernel (compiled, or
    loaded from the cache); until then the next render compiles, which takes minutes on a
    cold cache (``egs-bench warm-up`` fills it)."""
    kernels = (nk.bin_tiles, nk.raster_fwd, nk.raster_bwd, nk.reduce_rows, nk.reduce_touch,
               npj.project_fwd, npj.project_bwd)
    return all(kernel.signatures for kernel in kernels)


def prepare_kernels(dtype: torch.dtype = torch.float32) -> None:
    """Compile, or load from the cache, every CPU rasteriser kernel for ``dtype`` now, by
    rendering one Gaussian forward and backward: a run times this apart from its frames, so
    a cold cache does not change its frame rate."""
    means = torch.tensor([[0.0, 0.0, 2.0]], dtype=dtype, requires_grad=True)
    quats = torch.tensor([[1.0, 0.0, 0.0, 0.0]], dtype=dtype)
    K = torch.tensor([[[20.0, 0.0, 8.0], [0.0, 20.0, 8.0], [0.0, 0.0, 1.0]]], dtype=dtype)
    out = rasterize(means, quats, torch.full((1, 3), 0.1, dtype=dtype),
                    torch.tensor([0.5], dtype=dtype), torch.ones((1, 3), dtype=dtype),
                    torch.eye(4, dtype=dtype)[None], K, 16, 16, backend="numba")
    (out.rgb.sum() + out.depth.sum()).backward()
