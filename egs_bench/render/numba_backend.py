"""CPU backend: the numba tile kernels wrapped as a ``torch.autograd.Function``.

The projection is :mod:`egs_bench.render.numba_projection`'s fused kernel pair; this module
composites the projected Gaussians and back-propagates to the 2-D means, conics, depths,
opacities and colours.
Compiled kernels are cached on disk (``NUMBA_CACHE_DIR``); float32 and float64 each compile once.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from egs_bench.render import constants as RC
from egs_bench.render import numba_kernels as nk
from egs_bench.render.projection import Projected, log_opacity_margin
from egs_bench.render.work import active, book

assert nk.TILE == RC.TILE_SIZE


def _np(x: torch.Tensor) -> np.ndarray:
    return x.detach().contiguous().numpy()


def _n_tiles(width: int, height: int) -> int:
    return ((width + nk.TILE - 1) // nk.TILE) * ((height + nk.TILE - 1) // nk.TILE)


class _CompositeTiles(torch.autograd.Function):
    @staticmethod
    def forward(
        ctx: Any,
        means2d: torch.Tensor,
        conics: torch.Tensor,
        depths: torch.Tensor,
        opacities: torch.Tensor,
        colors: torch.Tensor,
        extents: torch.Tensor,
        width: int,
        height: int,
    ) -> tuple[torch.Tensor, ...]:
        C, N = depths.shape
        # The row spans use the same margin as the boxes (extents carry a 1e-3 relative pad).
        m2s = _np(log_opacity_margin(opacities.detach()) * (1.0 + 2e-3) + 1e-6)
        arrs = (_np(means2d), _np(conics), _np(depths), _np(opacities), m2s.astype(
            _np(means2d).dtype), _np(colors), _np(extents))
        isect, offsets = nk.bin_tiles(arrs[0], arrs[6], nk.depth_order_keys(arrs[2]), width,
                                      height)
        dt = arrs[0].dtype
        rgb = np.empty((C, height, width, 3), dt)
        dep = np.empty((C, height, width), dt)
        t_final = np.empty((C, height, width), np.float64)
        last = np.empty((C, height, width), np.int64)
        touch = np.zeros(isect.shape[0], np.int32)
        blends = np.zeros(C * _n_tiles(width, height), np.int64)
        consts, centre = nk.tables(RC.ALPHA_MAX, RC.ALPHA_MIN, RC.T_MIN, RC.TOUCH_T,
                                   max(width, height))
        nk.raster_fwd(*arrs, isect, offsets, width, height, rgb, dep, t_final, last, touch,
                      blends, consts, centre)
        ctx.work = active()  # the backward books into the record open now
        book(ctx.work, isects=int(isect.shape[0]), blends_fwd=int(blends.sum()))
        vis = np.zeros((C, N), np.bool_)
        nk.reduce_touch(isect, offsets, touch, _n_tiles(width, height), vis)
        ctx.saved = (arrs, isect, offsets, t_final, last, width, height)
        visibility = torch.from_numpy(vis)
        ctx.mark_non_differentiable(visibility)
        alpha = torch.from_numpy((1.0 - t_final).astype(dt))
        return torch.from_numpy(rgb), torch.from_numpy(dep), alpha, visibility

    @staticmethod
    def backward(
        ctx: Any,
        g_rgb: torch.Tensor | None,
        g_dep: torch.Tensor | None,
        g_alpha: torch.Tensor | None,
        _g_vis: torch.Tensor | None,
    ) -> tuple[torch.Tensor | None, ...]:
        arrs, isect, offsets, t_final, last, width, height = ctx.saved
        C, N = arrs[2].shape
        dt = arrs[0].dtype
        zeros = np.zeros((C, height, width), dt)
        g_rgb_np = _np(g_rgb) if g_rgb is not None else np.zeros((C, height, width, 3), dt)
        g_dep_np = _np(g_dep) if g_dep is not None else zeros
        g_alpha_np = _np(g_alpha) if g_alpha is not None else zeros
        rows = np.zeros((isect.shape[0], nk.NGRAD), dt)
        blends = np.zeros(C * _n_tiles(width, height), np.int64)
        consts, centre = nk.tables(RC.ALPHA_MAX, RC.ALPHA_MIN, RC.T_MIN, RC.TOUCH_T,
                                   max(width, height))
        nk.raster_bwd(*arrs, isect, offsets, width, height, t_final, last, g_rgb_np, g_dep_np,
                      g_alpha_np, rows, blends, consts, centre)
        book(ctx.work, blends_bwd=int(blends.sum()))
        out = np.zeros((C, N, nk.NGRAD), dt)
        nk.reduce_rows(isect, offsets, rows, _n_tiles(width, height), out)
        grads = torch.from_numpy(out)
        need = ctx.needs_input_grad  # tracking differentiates the poses only: no map sums
        return (grads[..., 0:2], grads[..., 2:5], grads[..., 9],
                grads[..., 8].sum(0) if need[3] else None,
                grads[..., 5:8].sum(0) if need[4] else None, None, None, None)


def composite_tiles(
    proj: Projected,
    opacities: torch.Tensor,
    colors: torch.Tensor,
    width: int,
    height: int,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Tile compositing on the CPU; same signature and outputs as
    :func:`egs_bench.render.reference.composite_dense` (rgb [C,H,W,3], depth [C,H,W],
    alpha [C,H,W], visibility [C,N] bool)."""
    if proj.means2d.device.type != "cpu":
        raise ValueError("the numba backend needs CPU tensors (use backend='gsplat' on CUDA)")
    colors = colors.to(proj.means2d.dtype)
    rgb, depth, alpha, vis = _CompositeTiles.apply(
        proj.means2d, proj.conics, proj.depths, opacities, colors, proj.extents, width, height,
    )
    return rgb, depth, alpha, vis
