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

from collections.abc import Callable
from typing import Any

import numpy as np
import torch
from torch import nn

from egs_bench.color import linear_to_srgb, srgb_to_linear
from egs_bench.errors import ConfigError


class CameraResponse(nn.Module):
    """Base class: ``forward(hdr [...]) -> ldr [...]`` and ``inverse(ldr) -> hdr`` (no grad)."""

    def inverse(self, ldr: torch.Tensor) -> torch.Tensor:  # pragma: no cover - interface
        raise NotImplementedError

    def frozen(self) -> Callable[[torch.Tensor], torch.Tensor]:
        """The response with its parameters fixed (differentiable in the input only), for
        loops that do not optimise it (tracking). Parameter-free responses return themselves."""
        return self


class IdentityCRF(CameraResponse):
    """No response: the map's colours live directly in the LDR image space (MonoGS, no-CRF)."""

    def forward(self, hdr: torch.Tensor) -> torch.Tensor:
        return hdr

    def inverse(self, ldr: torch.Tensor) -> torch.Tensor:
        return ldr

    def value_and_slope(self, hdr: torch.Tensor) -> tuple[torch.Tensor, None]:
        """The response and its derivative (None: 1 everywhere), without autograd."""
        return hdr, None


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

    def __init__(self, n_nodes: int = 16, alpha: float = 0.01, init: str = "linear",
                 device: str | torch.device = "cpu") -> None:
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
        self.gap_logits = nn.Parameter(torch.tensor(np.log(gaps), dtype=torch.float32,
                                                    device=device))
        self.register_buffer("levels", torch.tensor(levels, dtype=torch.float32, device=device))

    def nodes(self) -> torch.Tensor:
        """HDR inputs of the control nodes [N], strictly increasing from 0 to 1."""
        return nodes_from_logits(self.gap_logits)

    def forward(self, hdr: torch.Tensor) -> torch.Tensor:
        """LDR values, same shape as ``hdr``."""
        return leaky_piecewise_linear(hdr, self.nodes(), self.levels, self.alpha)

    def frozen(self) -> FrozenLeakyCurve:
        return FrozenLeakyCurve(self.nodes().detach(), self.levels, self.alpha)

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


class FrozenLeakyCurve:
    """:func:`leaky_piecewise_linear` with fixed nodes: per-segment slopes and intercepts are
    computed once, so a call is a bucket search, two gathers and the two leaky ends."""

    def __init__(self, nodes: torch.Tensor, levels: torch.Tensor, alpha: float) -> None:
        x, y = nodes.detach(), levels.to(nodes.dtype)
        self.inner = x[1:-1].contiguous()  # segment j covers [x_j, x_{j+1})
        self.slope = (y[1:] - y[:-1]) / (x[1:] - x[:-1])
        self.intercept = y[:-1] - x[:-1] * self.slope
        self.alpha = float(alpha)

    @torch.no_grad()
    def value_and_slope(self, hdr: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """LDR values [...] of HDR values [...] and the curve's derivative there, without
        autograd (tracking differentiates through them by hand: one multiplication)."""
        inside = hdr.clamp(0.0, 1.0)
        idx = torch.bucketize(inside, self.inner.to(hdr.dtype), right=True)
        seg_slope = self.slope.to(hdr.dtype)[idx]
        mid = inside * seg_slope + self.intercept.to(hdr.dtype)[idx]
        root = torch.rsqrt(hdr.clamp_min(1.0))
        high = (1 + self.alpha) - self.alpha * root
        low, high_slope = hdr < 0, hdr > 1
        value = torch.where(low, self.alpha * hdr, torch.where(high_slope, high, mid))
        # d/dh (1 + a - a h^-1/2) = (a / 2) h^-3/2
        slope = torch.where(low, self.alpha, torch.where(high_slope,
                                                         (0.5 * self.alpha) * root ** 3,
                                                         seg_slope))
        return value, slope

    def __call__(self, hdr: torch.Tensor) -> torch.Tensor:
        """LDR values [...] of HDR values [...] (differentiable in ``hdr``)."""
        return _CurveFunction.apply(hdr, self)


class _CurveFunction(torch.autograd.Function):
    """A response with a hand-written backward from its precomputed derivative."""

    @staticmethod
    def forward(ctx: Any, hdr: torch.Tensor, curve: FrozenLeakyCurve) -> torch.Tensor:
        value, slope = curve.value_and_slope(hdr)
        ctx.save_for_backward(slope)
        return value

    @staticmethod
    def backward(ctx: Any, grad: torch.Tensor) -> tuple[torch.Tensor, None]:
        (slope,) = ctx.saved_tensors
        return grad * slope, None


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


def make_crf(kind: str, n_nodes: int = 16, alpha: float = 0.01, init: str = "linear",
             device: str | torch.device = "cpu"
             ) -> CameraResponse:
    """Factory: ``"learnable"`` (initialised ``init``), ``"srgb"`` (fixed) or ``"identity"``."""
    if kind == "learnable":
        return LeakyPiecewiseLinearCRF(n_nodes, alpha, init, device)
    if kind == "srgb":
        return FixedSRGBCRF()
    if kind == "identity":
        return IdentityCRF()
    raise ConfigError(f"unknown CRF kind {kind!r} (use learnable, srgb or identity)")


def crf_to_dict(crf: CameraResponse) -> dict:
    """Plain-data description of ``crf`` (JSON-ready) from which :func:`crf_from_dict` rebuilds
    the same curve bit for bit.

    ``{"kind": "identity" | "srgb"}``, or for the learnable curve ``{"kind": "learnable",
    "alpha", "gap_logits" [N-1] (the raw parameters), "nodes_hdr" [N] and "levels_ldr" [N]}``:
    ``nodes_hdr``/``levels_ldr`` are the control points (HDR input, LDR output) for readers
    outside egs-bench; inside [0, 1] the curve interpolates them linearly, below 0 it is
    ``alpha * x``, above 1 ``1 + alpha - alpha / sqrt(x)``.
    """
    if isinstance(crf, LeakyPiecewiseLinearCRF):
        with torch.no_grad():
            return {"kind": "learnable", "alpha": crf.alpha,
                    "gap_logits": [float(v) for v in crf.gap_logits.detach().cpu()],
                    "nodes_hdr": [float(v) for v in crf.nodes().detach().cpu()],
                    "levels_ldr": [float(v) for v in crf.levels.detach().cpu()]}
    if isinstance(crf, FixedSRGBCRF):
        return {"kind": "srgb"}
    if isinstance(crf, IdentityCRF):
        return {"kind": "identity"}
    raise ConfigError(f"cannot describe a CRF of type {type(crf).__name__}")


def crf_from_dict(data: dict) -> CameraResponse:
    """The CRF described by :func:`crf_to_dict` (float32 parameters, as during the run).

    Raises:
        ConfigError: unknown kind or malformed parameters.
    """
    kind = data.get("kind") if isinstance(data, dict) else None
    if kind in ("identity", "srgb"):
        return make_crf(kind)
    if kind != "learnable":
        raise ConfigError(f"unknown CRF kind {kind!r} (use learnable, srgb or identity)")
    try:
        logits = np.asarray(data["gap_logits"], dtype=np.float32)
        alpha = float(data["alpha"])
    except (KeyError, TypeError, ValueError) as exc:
        raise ConfigError(f"learnable CRF needs 'alpha' and 'gap_logits' ({exc})") from None
    if logits.ndim != 1 or len(logits) < 1 or not np.isfinite(logits).all():
        raise ConfigError("learnable CRF 'gap_logits' must be a non-empty list of numbers")
    crf = LeakyPiecewiseLinearCRF(len(logits) + 1, alpha)
    with torch.no_grad():
        crf.gap_logits.copy_(torch.from_numpy(logits))
    return crf
