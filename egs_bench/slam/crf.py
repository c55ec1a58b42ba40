"""Camera response functions mapping rendered HDR (linear) intensity to LDR values.

``LeakyPiecewiseLinearCRF`` is the paper's learnable CRF (eq. after eq. 3): ``N`` control nodes
with fixed, evenly spaced LDR outputs ``y_j = j / (N - 1)`` and learnable HDR inputs ``x_j``;
inside [0, 1] the output is the linear interpolation through the nodes, below 0 it leaks with
slope ``alpha``, above 1 it saturates as ``1 + alpha - alpha / sqrt(I)`` (continuous at 1).
One instance is shared by all frames.

Monotonicity holds by construction: ``x_0 = 0``, ``x_{N-1} = 1`` and the gaps between nodes are
a softmax of free logits, hence positive and summing to one. Hand-written: no library offers a
differentiable monotone piecewise-linear curve with learnable knots.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from egs_bench.color import linear_to_srgb, srgb_to_linear
from egs_bench.errors import ConfigError


class CameraResponse(nn.Module):
    """Base class: ``forward(hdr [...]) -> ldr [...]`` and ``inverse(ldr) -> hdr`` (no grad)."""

    def inverse(self, ldr: torch.Tensor) -> torch.Tensor:  # pragma: no cover - interface
        raise NotImplementedError


class IdentityCRF(CameraResponse):
    """No response: the map's colours live directly in the LDR image space (MonoGS, no-CRF)."""

    def forward(self, hdr: torch.Tensor) -> torch.Tensor:
        return hdr

    def inverse(self, ldr: torch.Tensor) -> torch.Tensor:
        return ldr


class FixedSRGBCRF(CameraResponse):
    """Fixed sRGB encoding (a non-learnable, physically plausible response)."""

    def forward(self, hdr: torch.Tensor) -> torch.Tensor:
        return linear_to_srgb(hdr)

    def inverse(self, ldr: torch.Tensor) -> torch.Tensor:
        return srgb_to_linear(ldr)


class LeakyPiecewiseLinearCRF(CameraResponse):
    """The paper's learnable leaky piecewise-linear CRF.

    Args:
        n_nodes: number of control nodes N >= 2 (including the fixed end nodes).
        alpha: leak slope below 0 and saturation scale above 1 (paper: 0.01).
        init: ``"srgb"`` (nodes on the sRGB curve) or ``"linear"`` (identity on [0, 1]).
    """

    levels: torch.Tensor

    def __init__(self, n_nodes: int = 16, alpha: float = 0.01, init: str = "linear") -> None:
        super().__init__()
        if n_nodes < 2:
            raise ConfigError(f"CRF needs at least 2 control nodes, got {n_nodes}")
        self.alpha = float(alpha)
        levels = np.linspace(0.0, 1.0, n_nodes)
        if init == "srgb":
            hdr = srgb_to_linear(levels)
        elif init == "linear":
            hdr = levels
        else:
            raise ConfigError(f"unknown CRF init {init!r} (use 'srgb' or 'linear')")
        gaps = np.maximum(np.diff(hdr), 1e-6)
        gaps = gaps / gaps.sum()
        self.gap_logits = nn.Parameter(torch.tensor(np.log(gaps), dtype=torch.float32))
        self.register_buffer("levels", torch.tensor(levels, dtype=torch.float32))

    def nodes(self) -> torch.Tensor:
        """HDR inputs of the control nodes [N], strictly increasing from 0 to 1."""
        return nodes_from_logits(self.gap_logits)

    def forward(self, hdr: torch.Tensor) -> torch.Tensor:
        """LDR values, same shape as ``hdr``."""
        return leaky_piecewise_linear(hdr, self.nodes(), self.levels, self.alpha)

    @torch.no_grad()
    def inverse(self, ldr: torch.Tensor) -> torch.Tensor:
        """HDR values mapping to ``ldr`` (exact inverse of the curve; no gradient)."""
        x = self.nodes().to(ldr.dtype)
        y = self.levels.to(ldr.dtype)
        inside = ldr.clamp(0.0, 1.0)
        idx = (torch.searchsorted(y.contiguous(), inside.reshape(-1).contiguous(), right=True)
               .reshape(ldr.shape) - 1).clamp(0, len(y) - 2)
        mid = x[idx] + (inside - y[idx]) * (x[idx + 1] - x[idx]) / (y[idx + 1] - y[idx])
        low = ldr / self.alpha
        high_arg = (1 + self.alpha - ldr).clamp_min(1e-6)
        high = (self.alpha / high_arg) ** 2
        return torch.where(ldr < 0, low, torch.where(ldr > 1, high, mid))


def nodes_from_logits(gap_logits: torch.Tensor) -> torch.Tensor:
    """Strictly increasing node inputs [N] from 0 to 1, from free gap logits [N-1]."""
    gaps = torch.softmax(gap_logits, 0)
    return torch.cat([gaps.new_zeros(1), torch.cumsum(gaps, 0)[:-1], gaps.new_ones(1)])


def leaky_piecewise_linear(hdr: torch.Tensor, nodes: torch.Tensor, levels: torch.Tensor,
                           alpha: float) -> torch.Tensor:
    """The leaky CRF curve of ``hdr`` [...] through nodes ``(nodes[j], levels[j])`` [N].

    ``nodes`` must increase from 0 to 1 and ``levels`` from 0 to 1; differentiable w.r.t. both
    ``hdr`` and ``nodes``.
    """
    x = nodes.to(hdr.dtype)
    y = levels.to(hdr.dtype)
    inside = hdr.clamp(0.0, 1.0)
    idx = torch.searchsorted(x.detach().contiguous(), inside.detach().reshape(-1).contiguous(),
                             right=True).reshape(hdr.shape)
    idx = (idx - 1).clamp(0, len(x) - 2)
    x0, x1, y0, y1 = x[idx], x[idx + 1], y[idx], y[idx + 1]
    mid = y0 + (inside - x0) * (y1 - y0) / (x1 - x0)
    low = alpha * hdr
    safe_high = torch.where(hdr > 1, hdr, torch.ones_like(hdr))
    high = 1 + alpha - alpha / torch.sqrt(safe_high)
    return torch.where(hdr < 0, low, torch.where(hdr > 1, high, mid))


def make_crf(kind: str, n_nodes: int = 16, alpha: float = 0.01, init: str = "linear"
             ) -> CameraResponse:
    """Factory: ``"learnable"`` (initialised ``init``), ``"srgb"`` (fixed) or ``"identity"``."""
    if kind == "learnable":
        return LeakyPiecewiseLinearCRF(n_nodes, alpha, init)
    if kind == "srgb":
        return FixedSRGBCRF()
    if kind == "identity":
        return IdentityCRF()
    raise ConfigError(f"unknown CRF kind {kind!r} (use learnable, srgb or identity)")
