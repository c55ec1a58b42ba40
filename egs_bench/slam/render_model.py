"""Blur-aware rendering of frames and their loss (paper §III.B–D, MonoGS masks), batched.

One rasteriser call renders the M sub-poses of each of V frames (tracking: V = 1; mapping: the
keyframes of the iteration). Per frame, the HDR sub-images are averaged, go through the CRF
(and MonoGS's exposure compensation ``exp(a) I + b``) to the LDR prediction; event maps are
log-luma differences between consecutive sub-images.

Everything that depends on the observations alone (masks, ``theta E`` targets, weights) is
prepared once per frame in :class:`LossTargets`, so an iteration issues few, large tensor
operations (each one is a kernel launch on a GPU; see ``benchmarks/bench_slam_overhead.py``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
import torch

from egs_bench.color import LUMA_BT601
from egs_bench.render import GaussianMap
from egs_bench.render import constants as RC
from egs_bench.render.gaussian_map import FrozenGaussians
from egs_bench.render.rasterize import RasterResult
from egs_bench.slam.config import SlamConfig
from egs_bench.slam.frames import FrameObs
from egs_bench.slam.loss_terms import (
    EVENTS,
    LOSS_TERMS,
    LossTerm,
    Prepared,
    RenderedViews,
    TermSetup,
    event_residual,
)
from egs_bench.slam.losses import isotropic_loss


@dataclass
class LossTargets:
    """Observations of V frames, prepared for :func:`blur_loss` by each loss term.

    Attributes:
        n_views: V.
        terms: the loss terms (:mod:`egs_bench.slam.loss_terms`), in order.
        prepared: by term name, the term's tensors for the V frames (first axis V); a term
            that does not apply to these frames (events without events) is absent.
        weights: by term name, its weight (for unweighted diagnostics).
        luma_weights: [3] BT.601 weights on the device (rendered luma = rgb @ weights).
    """

    n_views: int
    terms: tuple[LossTerm, ...]
    prepared: dict[str, Prepared]
    weights: dict[str, float]
    luma_weights: torch.Tensor


def prepare_targets(obs: FrameObs, cfg: SlamConfig, theta: tuple[float, float], *,
                    tracking: bool, use_events: bool,
                    terms: tuple[LossTerm, ...] = LOSS_TERMS) -> LossTargets:
    """:class:`LossTargets` of one frame (V = 1) for tracking or mapping."""
    setup = TermSetup(cfg, theta, tracking, use_events)
    weights = {t.name: float(t.weight(cfg)) for t in terms}
    prepared = {}
    for term in terms:
        p = term.prepare(obs, setup, weights[term.name])
        if p is not None:
            prepared[term.name] = p
    luma = torch.tensor(LUMA_BT601, dtype=obs.rgb.dtype, device=obs.rgb.device)  # once per frame
    return LossTargets(1, terms, prepared, weights, luma)


def stack_targets(targets: list[LossTargets]) -> LossTargets:
    """Concatenate the views of several :class:`LossTargets` (a term only where every one of
    them has it)."""
    first = targets[0]
    common = [name for name in first.prepared if all(name in t.prepared for t in targets)]
    prepared = {name: {key: torch.cat([t.prepared[name][key] for t in targets])
                       for key in first.prepared[name]} for name in common}
    return LossTargets(sum(t.n_views for t in targets), first.terms, prepared, first.weights,
                       first.luma_weights)


def render_views(gmap: GaussianMap | FrozenGaussians, viewmats: torch.Tensor | np.ndarray,
                 K: torch.Tensor, width: int, height: int, cfg: SlamConfig, *,
                 visibility: bool = False, eps2d: float = RC.EPS2D) -> RasterResult:
    """Render world-to-camera ``viewmats`` [C, 4, 4] (any float dtype, tensor or array) with the
    map's dtype and device; returns the RasterResult (``visibility`` only when asked;
    ``eps2d``: the rasteriser's 2-D dilation, pixels^2)."""
    if isinstance(viewmats, np.ndarray):
        viewmats = torch.from_numpy(viewmats)
    vm = viewmats.to(device=gmap.device, dtype=gmap.dtype)
    ks = K.to(gmap.dtype).expand(vm.shape[0], 3, 3)
    return gmap.render(vm, ks, width, height, near_plane=cfg.mapping.near_plane,
                       backend=cfg.runtime.backend, visibility=visibility, eps2d=eps2d)


def _rendered(res: RasterResult, targets: LossTargets, crf: Callable[[torch.Tensor], torch.Tensor],
              exp_ab: torch.Tensor | None, cfg: SlamConfig, *, tracking: bool,
              eps: float) -> RenderedViews:
    v = targets.n_views
    c, h, w = res.rgb.shape[:3]
    m = c // v
    hdr = res.rgb.view(v, m, h, w, 3)
    depth = (res.expected_depth if cfg.loss.expected_depth else res.depth).view(v, m, h, w)
    return RenderedViews(hdr, respond(crf, hdr.mean(1), exp_ab),
                         res.alpha.detach().view(v, m, h, w), depth, tracking, eps,
                         targets.luma_weights)


def blur_loss(res: RasterResult, targets: LossTargets, crf: Callable[[torch.Tensor], torch.Tensor],
              exp_ab: torch.Tensor | None, cfg: SlamConfig, *, tracking: bool,
              eps: float) -> torch.Tensor:
    """Sum over the V frames and the loss terms (default: ``lambda_E L_E + lambda_ID
    (lambda_I L_I + lambda_D L_D)``) (a scalar tensor).

    Args:
        res: RasterResult of V x M cameras, frame-major (M sub-poses of frame 0, then frame 1...).
        targets: the V frames' observations.
        crf: HDR -> LDR response (a :class:`~egs_bench.slam.crf.CameraResponse` or its frozen
            curve).
        exp_ab: [V, 2] exposure compensation ``(a, b)`` per frame, or None (disabled).
        tracking: MonoGS tracking masks (photometric weight x mean rendered opacity, depth
            where the rendered opacity > 0.95, events where it is > 0.5 in every sub-image)
            instead of the mapping masks.
        eps: log offset of the event model (the sequence's).

    Every mean runs over all pixels with masked pixels counting zero (MonoGS), per frame.
    """
    views = _rendered(res, targets, crf, exp_ab, cfg, tracking=tracking, eps=eps)
    values = [term.value(views, targets.prepared[term.name]).sum() for term in targets.terms
              if term.name in targets.prepared]
    return torch.stack(values).sum() if len(values) != 1 else values[0]


def blur_loss_terms(res: RasterResult, targets: LossTargets,
                    crf: Callable[[torch.Tensor], torch.Tensor], exp_ab: torch.Tensor | None,
                    cfg: SlamConfig, *, tracking: bool, eps: float) -> dict[str, torch.Tensor]:
    """The terms of :func:`blur_loss` (same arguments), summed over frames, for diagnostics:
    each term unweighted by its name (``photometric`` L_I, ``depth`` L_D, ``events``; a term
    whose weight is 0 is NaN), the event term's parts ``event_he`` and ``event_ne`` (means over
    pixels with and without events; 0 without events) and the weighted ``total``."""
    views = _rendered(res, targets, crf, exp_ab, cfg, tracking=tracking, eps=eps)
    total = blur_loss(res, targets, crf, exp_ab, cfg, tracking=tracking, eps=eps)
    out = {"event_he": total.new_zeros(()), "event_ne": total.new_zeros(()), "total": total}
    for term in targets.terms:
        weight = targets.weights[term.name]
        if term.name not in targets.prepared:
            out[term.name] = total.new_zeros(())
            continue
        value = term.value(views, targets.prepared[term.name]).sum()
        out[term.name] = value / weight if weight else torch.full_like(value, float("nan"))
    events = targets.prepared.get(EVENTS.name)
    if events is not None:
        resid = event_residual(views, events)
        has = (events["target"] != 0).to(resid.dtype)
        out["event_he"] = (has * resid).mean((1, 2, 3)).sum()
        out["event_ne"] = ((1 - has) * resid).mean((1, 2, 3)).sum()
    return out


def respond(crf: Callable[[torch.Tensor], torch.Tensor], hdr: torch.Tensor,
            exp_ab: torch.Tensor | None) -> torch.Tensor:
    """LDR prediction ``exp(a) CRF(hdr) + b`` [V, H, W, 3] of mean HDR images [V, H, W, 3]
    with per-frame exposure ``exp_ab`` [V, 2] (None: ``CRF(hdr)``).

    A response with fixed parameters (``value_and_slope``: tracking's frozen curve, the
    identity) goes through one autograd node with a hand-written backward; a learnable one
    through autograd, so its parameters get gradients."""
    if exp_ab is None:
        return crf(hdr)
    if isinstance(crf, FixedResponse):
        out: torch.Tensor = _FixedResponseWithExposure.apply(hdr, exp_ab, crf)
        return out
    ab = exp_ab.view(-1, 1, 1, 2)
    return torch.addcmul(ab[..., 1:], crf(hdr), ab[..., :1].exp())


@runtime_checkable
class FixedResponse(Protocol):
    """A response without parameters that gives its derivative directly (tracking's frozen
    curve, the identity)."""

    def __call__(self, hdr: torch.Tensor) -> torch.Tensor:
        ...

    def value_and_slope(self, hdr: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor | None]:
        """The response of ``hdr`` [...] and its slope [...] (None: 1 everywhere)."""
        ...


class _FixedResponseWithExposure(torch.autograd.Function):
    """``exp(a) f(h) + b`` for a response ``f`` without parameters; gradients for ``h`` and
    ``(a, b)`` from ``f``'s precomputed derivative (a handful of operations instead of the
    autograd graph of the curve's branches)."""

    @staticmethod
    def forward(ctx: Any, hdr: torch.Tensor, exp_ab: torch.Tensor, crf: FixedResponse
                ) -> torch.Tensor:
        value, slope = crf.value_and_slope(hdr)
        gain = exp_ab[:, 0].exp().view(-1, 1, 1, 1)
        out = torch.addcmul(exp_ab[:, 1].view(-1, 1, 1, 1), value, gain)
        ctx.save_for_backward(out, gain if slope is None else gain * slope, exp_ab[:, 1])
        return out

    @staticmethod
    def backward(ctx: Any, grad: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, None]:
        out, d_hdr, b = ctx.saved_tensors
        # d/da = exp(a) f(h) = out - b; d/db = 1
        g_a = (grad * (out - b.view(-1, 1, 1, 1))).sum((1, 2, 3))
        g_b = grad.sum((1, 2, 3))
        return grad * d_hdr, torch.stack([g_a, g_b], -1), None


def mapping_regulariser(gmap: GaussianMap, cfg: SlamConfig) -> torch.Tensor:
    """``lambda_iso`` x the isotropic term on the map's scales (paper eq. 15, MonoGS)."""
    return cfg.loss.lambda_iso * isotropic_loss(gmap.scales)
