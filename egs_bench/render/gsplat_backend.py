"""CUDA backend: gsplat 1.5.3 (optional extra ``egs-bench[cuda]``).

``gsplat.rasterization`` is called with the settings that give our per-pixel rule as closely as
gsplat allows: ``eps2d=0.3``, ``rasterize_mode="classic"`` (no anti-aliasing opacity factor),
``render_mode="RGB+D"`` (accumulated depth ``sum w_i z_i`` as a fourth channel),
``packed=False``, ``tile_size=16`` and our near/far planes. Two differences are hard-coded in
gsplat's CUDA kernels and cannot be passed: the alpha clamp is 0.999 (ours 0.99) and the
compositing stops when ``T <= 1e-4`` (ours ``< 1e-4``). Backgrounds and the expected depth are
applied by :func:`egs_bench.render.rasterize`, identically for every backend.

Visibility (MonoGS's "touched", T after > 0.5): gsplat 1.5.3 has no such output.
``gsplat.rasterize_to_indices_in_range`` lists the (Gaussian, pixel) pairs that contribute
before the transmittance drops to 1e-4; starting it with ``T = 1e-4 / 0.5`` instead of 1 makes it
stop exactly where the true transmittance reaches 0.5, so the pairs it returns are the touched
ones.

Not run on a GPU yet (no GPU was available when this was written); see docs/notes/render.md.
"""

from __future__ import annotations

from types import ModuleType

import torch

from egs_bench.errors import ConfigError
from egs_bench.render import constants as RC
from egs_bench.render.work import active, book


def _import_gsplat() -> ModuleType:
    try:
        import gsplat
    except ImportError as exc:
        raise ConfigError(
            "backend 'gsplat' needs gsplat 1.5.3: pip install 'egs-bench[cuda]'"
        ) from exc
    return gsplat


def touched_visibility(meta: dict, C: int, N: int, width: int, height: int) -> torch.Tensor:
    """[C, N] bool: contributed to some pixel while the transmittance after it was > 0.5."""
    gsplat = _import_gsplat()
    offsets = meta["isect_offsets"]
    flatten_ids = meta["flatten_ids"]
    n_isects = flatten_ids.numel()
    vis = torch.zeros(C, N, dtype=torch.bool, device=offsets.device)
    if n_isects == 0:
        return vis
    starts = offsets.flatten().long()
    ends = torch.cat([starts[1:], torch.tensor([n_isects], device=starts.device)])
    longest = int((ends - starts).max())
    t0 = torch.full((C, height, width), RC.T_MIN / RC.TOUCH_T, device=offsets.device,
                    dtype=meta["means2d"].dtype)
    gs_ids, _pixel_ids, cam_ids = gsplat.rasterize_to_indices_in_range(
        0, longest, t0, meta["means2d"].detach(), meta["conics"].detach(),
        meta["opacities"].detach(), width, height, meta["tile_size"], offsets, flatten_ids,
    )
    # Unpacked mode: ids may be flattened over cameras (c * N + g); "% N" covers both cases.
    vis[cam_ids.long(), gs_ids.long() % N] = True
    return vis


def rasterize_gsplat(
    means: torch.Tensor,
    quats: torch.Tensor,
    scales: torch.Tensor,
    opacities: torch.Tensor,
    colors: torch.Tensor,
    viewmats: torch.Tensor,
    Ks: torch.Tensor,
    width: int,
    height: int,
    near_plane: float,
    far_plane: float,
    visibility: bool = True,
    eps2d: float = RC.EPS2D,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor | None, torch.Tensor,
           torch.Tensor, torch.Tensor]:
    """gsplat rendering; returns rgb [C,H,W,3], depth [C,H,W], alpha [C,H,W], visibility
    [C,N] (None unless ``visibility``), radii [C,N] int32, means2d [C,N,2], depths [C,N]
    (see :class:`RasterResult`)."""
    gsplat = _import_gsplat()
    if means.device.type != "cuda":
        raise ValueError("backend 'gsplat' needs CUDA tensors (use backend='numba' on the CPU)")
    C, N = viewmats.shape[0], means.shape[0]
    renders, alphas, meta = gsplat.rasterization(
        means, quats, scales, opacities, colors, viewmats, Ks.to(means.dtype), width, height,
        near_plane=near_plane, far_plane=far_plane, eps2d=eps2d, sh_degree=None,
        packed=False, tile_size=RC.TILE_SIZE, backgrounds=None, render_mode="RGB+D",
        rasterize_mode="classic",
    )
    radii = meta["radii"]
    if radii.dim() == 3:  # gsplat >= 1.5: per-axis radii [C,N,2]
        radii = radii.amax(-1)
    vis = touched_visibility(meta, C, N, width, height) if visibility else None
    flat = meta.get("flatten_ids")
    book(active(), isects=int(flat.numel()) if flat is not None else 0, blends_counted=False)
    return (renders[..., :3], renders[..., 3], alphas[..., 0], vis,
            radii.to(torch.int32), meta["means2d"], meta["depths"])
