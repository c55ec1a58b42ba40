"""Small random scenes shared by the render tests (imported as a helper module)."""

from __future__ import annotations

import math
from typing import Any

import torch


def random_scene(n: int = 200, c: int = 3, width: int = 32, height: int = 24, seed: int = 0,
                 dtype: torch.dtype = torch.float64, opacity_scale: float = 1.0,
                 scale_range: tuple[float, float] = (0.02, 0.25)) -> dict:
    """N Gaussians in front of C cameras along a short arc; returns a dict of tensors and
    sizes ready for ``rasterize(**scene)`` (keys match its arguments)."""
    g = torch.Generator().manual_seed(seed)
    f = 0.9 * width
    z = 1.5 + 3.0 * torch.rand(n, generator=g, dtype=torch.float64)
    x = (torch.rand(n, generator=g, dtype=torch.float64) * 2 - 1) * 0.7 * z * width / (2 * f)
    y = (torch.rand(n, generator=g, dtype=torch.float64) * 2 - 1) * 0.7 * z * height / (2 * f)
    means = torch.stack([x, y, z], -1)
    quats = torch.randn(n, 4, generator=g, dtype=torch.float64)
    lo, hi = math.log(scale_range[0]), math.log(scale_range[1])
    scales = torch.exp(lo + (hi - lo) * torch.rand(n, 3, generator=g, dtype=torch.float64))
    opacities = torch.sigmoid(torch.randn(n, generator=g, dtype=torch.float64)) * opacity_scale
    colors = torch.rand(n, 3, generator=g, dtype=torch.float64)
    viewmats = torch.stack([small_pose(k - (c - 1) / 2) for k in range(c)])
    K = torch.tensor([[f, 0, width / 2 + 0.3], [0, f * 1.05, height / 2 - 0.2], [0, 0, 1]],
                     dtype=torch.float64)
    out = dict(means=means, quats=quats, scales=scales, opacities=opacities, colors=colors,
               viewmats=viewmats)
    scene: dict[str, Any] = {k: v.to(dtype) for k, v in out.items()}
    scene.update(Ks=K.expand(c, 3, 3).clone(), width=width, height=height)
    return scene


def small_pose(step: float) -> torch.Tensor:
    """A world-to-camera matrix a small rotation (2 deg/step) and translation away from I."""
    return se3_exp(torch.tensor([[0.02 * step, -0.01 * step, 0.015 * step,
                                  0.03 * step, -0.035 * step, 0.01 * step]],
                                dtype=torch.float64))[0]


def se3_exp(xi: torch.Tensor) -> torch.Tensor:
    """[C,6] twists (rho, theta) -> [C,4,4] via the matrix exponential (differentiable)."""
    c = xi.shape[0]
    m = torch.zeros(c, 4, 4, dtype=xi.dtype)
    th = xi[:, 3:]
    m[:, 0, 1], m[:, 0, 2], m[:, 1, 2] = -th[:, 2], th[:, 1], -th[:, 0]
    m = m - m.transpose(1, 2)
    m[:, :3, 3] = xi[:, :3]
    return torch.linalg.matrix_exp(m)


def leaf_copy(scene: dict, requires_grad: bool = True) -> dict:
    """Fresh leaf tensors (same values) for the differentiable inputs of ``scene``."""
    out = dict(scene)
    for k in ("means", "quats", "scales", "opacities", "colors", "viewmats"):
        out[k] = scene[k].detach().clone().requires_grad_(requires_grad)
    return out
