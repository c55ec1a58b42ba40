"""How much each Gaussian contributes to a set of views: the pruning rule of
``budget.prune_contribution``.

A Gaussian's contribution to a view is its total blending weight there, ``sum_p alpha T`` over
the pixels ``p`` it is composited into: the number of pixels' worth of colour it supplies. It is
the gradient of the rendered image's colour sum with respect to that Gaussian's colour, so both
rasteriser backends give it through their own backward pass (gsplat has no such output).

Keyframe insertion adds Gaussians on every keyframe's depth, also where earlier ones already
cover the surface; many of the new ones end up behind the old and supply almost nothing, yet
every render projects, bins and sorts them (docs/notes/contribution_pruning_2026-12-07.md).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import torch

from egs_bench.render import GaussianMap
from egs_bench.slam.context import SlamContext


def blend_weights(ctx: SlamContext, gmap: GaussianMap, viewmats: torch.Tensor,
                  scale: float) -> torch.Tensor:
    """Each Gaussian's blending weight summed over the views, in pixels of the internal
    resolution.

    Args:
        ctx: the run's context (the render is booked as mapping work).
        gmap: the map (its tensors are not modified and need no gradients).
        viewmats: world-to-camera poses [C, 4, 4].
        scale: render at this factor of the internal resolution; the weights are divided by
            the level's pixel-area ratio so that they count internal-resolution pixels.

    Returns:
        [N] float tensor on the map's device, >= 0.
    """
    frozen = gmap.frozen()
    unit = torch.ones_like(frozen.colors).requires_grad_(True)
    probe = replace(frozen, colors=unit)
    res = ctx.render(probe, viewmats, phase="mapping", scale=scale)
    (grad,) = torch.autograd.grad(res.rgb[..., 0].sum(), unit)
    cam = ctx.level(scale).cam
    return grad[:, 0] * (ctx.width * ctx.height / (cam.width * cam.height))


def in_view(ctx: SlamContext, means: torch.Tensor, viewmats: torch.Tensor) -> torch.Tensor:
    """Which Gaussians' centres project inside the image of at least one view, in front of
    its near plane.

    Args:
        means: world positions [N, 3].
        viewmats: world-to-camera poses [C, 4, 4].

    Returns:
        [N] bool tensor on ``means``'s device.
    """
    points = means.detach().cpu().double().numpy()
    seen = np.zeros(len(points), dtype=bool)
    for view in viewmats.detach().cpu().double().numpy():
        cam = points @ view[:3, :3].T + view[:3, 3]
        front = cam[:, 2] > ctx.cfg.mapping.near_plane
        uv = ctx.cam.project(cam[front])
        inside = ((uv[:, 0] >= 0) & (uv[:, 0] < ctx.width) & (uv[:, 1] >= 0)
                  & (uv[:, 1] < ctx.height))
        seen[np.flatnonzero(front)[inside]] = True
    return torch.from_numpy(seen).to(means.device)


def low_contribution(ctx: SlamContext, gmap: GaussianMap, viewmats: torch.Tensor, scale: float,
                     min_pixels: float) -> torch.Tensor:
    """The Gaussians to prune: in view of at least one of ``viewmats`` [C, 4, 4], and blending
    less than ``min_pixels`` internal-resolution pixels summed over them (rendered at
    ``scale``). Those out of every view are kept: nothing here says whether they matter.

    Returns:
        [N] bool tensor.
    """
    weights = blend_weights(ctx, gmap, viewmats, scale)
    return in_view(ctx, gmap.means, viewmats) & (weights < min_pixels)
