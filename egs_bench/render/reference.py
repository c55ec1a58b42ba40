"""Dense pure-PyTorch compositing: every pixel against every Gaussian (the test oracle).

Autograd gives the backward. Memory is O(C N H W), so this is for tiny images and a few
hundred Gaussians only (float64 works). It implements the rule in
:mod:`egs_bench.render.constants` literally, with no tiles and no culling boxes, so that it is
structured independently of the tile kernels it checks.
"""

from __future__ import annotations

import torch

from egs_bench.render import constants as RC
from egs_bench.render.projection import Projected


def composite_dense(
    proj: Projected,
    opacities: torch.Tensor,
    colors: torch.Tensor,
    width: int,
    height: int,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Composite projected Gaussians front to back for every pixel.

    Args:
        proj: projection of N Gaussians into C cameras.
        opacities: [N] activated opacities.
        colors: [N, 3] linear RGB.
        width, height: image size (pixels).

    Returns:
        rgb [C, H, W, 3], depth [C, H, W] (sum of w_i z_i), alpha [C, H, W] (1 - T), and
        visibility [C, N] bool (contributed to a pixel with transmittance after it > TOUCH_T).
    """
    C, N = proj.depths.shape
    dtype = proj.means2d.dtype
    order = torch.argsort(proj.depths.detach(), dim=1, stable=True)  # [C,N]

    def sort(x: torch.Tensor) -> torch.Tensor:
        idx = order if x.dim() == 2 else order[..., None].expand(-1, -1, x.shape[-1])
        return torch.gather(x, 1, idx)

    m, con, z, ok = sort(proj.means2d), sort(proj.conics), sort(proj.depths), sort(proj.valid)
    o = opacities[order]  # [C,N]
    col = colors[order]  # [C,N,3]
    v, u = torch.meshgrid(
        torch.arange(height, dtype=dtype), torch.arange(width, dtype=dtype), indexing="ij"
    )
    pu = (u.reshape(-1) + 0.5)[None, None]  # [1,1,P]
    pv = (v.reshape(-1) + 0.5)[None, None]
    dx = pu - m[..., 0:1]
    dy = pv - m[..., 1:2]
    power = -0.5 * (con[..., 0:1] * dx * dx + con[..., 2:3] * dy * dy) - con[..., 1:2] * dx * dy
    alpha = torch.clamp_max(o[..., None] * torch.exp(power), RC.ALPHA_MAX)  # [C,N,P]
    with torch.no_grad():
        use = ok[..., None] & (power <= 0) & (alpha >= RC.ALPHA_MIN)
    alpha = torch.where(use, alpha, torch.zeros_like(alpha))
    t_after = torch.cumprod(1 - alpha, dim=1)
    t_before = torch.cat([torch.ones_like(t_after[:, :1]), t_after[:, :-1]], 1)
    with torch.no_grad():
        # The stop rule: once T would drop below T_MIN the pixel is finished, so this Gaussian
        # and every later one are excluded (cumprod is monotone, so ">= T_MIN" says it all).
        keep = t_after >= RC.T_MIN
    w = alpha * t_before * keep
    rgb = torch.einsum("cnp,cnk->cpk", w, col)
    depth = (w * z[..., None]).sum(1)
    alpha_img = 1 - torch.prod(torch.where(keep, 1 - alpha, torch.ones_like(alpha)), dim=1)
    with torch.no_grad():
        touched_sorted = (use & keep & (t_after > RC.TOUCH_T)).any(-1)  # [C,N]
        visibility = torch.zeros_like(touched_sorted).scatter_(1, order, touched_sorted)
    return (
        rgb.reshape(C, height, width, 3),
        depth.reshape(C, height, width),
        alpha_img.reshape(C, height, width),
        visibility,
    )
