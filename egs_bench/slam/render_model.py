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
from typing import NamedTuple

import numpy as np
import torch

from egs_bench.color import LUMA_BT601
from egs_bench.render import GaussianMap
from egs_bench.render.gaussian_map import FrozenGaussians
from egs_bench.slam.config import SlamConfig
from egs_bench.slam.frames import FrameObs
from egs_bench.slam.losses import isotropic_loss, rendered_event_maps


@dataclass
class LossTargets:
    """Observations of V frames, prepared for :func:`blur_loss` (device tensors, float).

    The loss weights and the 1 / (number of values) of each mean are folded into the masks
    (``*_scale``), so the loss is a few weighted sums.

    Attributes:
        rgb: observed LDR images [V, H, W, 3].
        photo_weight: [V, H, W] MonoGS boundary mask (channel sum > threshold), times the
            edge mask in tracking, times ``photo_scale``.
        depth: observed depth [V, H, W] (m; 0 = invalid).
        depth_mask: [V, H, W] ``depth_scale`` where the depth is valid, else 0.
        event_target: [V, K, H, W] ``theta E_k`` (theta by the sign of the polarity sum E_k),
            or None without event loss.
        event_weight: [V, K, H, W] ``event_scale`` where ``E_k != 0`` (``L_HE``) and
            ``lambda_NE event_scale`` where ``E_k = 0`` (``L_NE``, 0 without the no-event
            loss), or None.
        luma_weights: [3] BT.601 weights on the device (rendered luma = rgb @ weights).
        photo_scale, depth_scale, event_scale: ``lambda_ID lambda_I / (3 H W)``,
            ``lambda_ID lambda_D / (H W)``, ``lambda_E / (K H W)``.
    """

    rgb: torch.Tensor
    photo_weight: torch.Tensor
    depth: torch.Tensor
    depth_mask: torch.Tensor
    event_target: torch.Tensor | None
    event_weight: torch.Tensor | None
    luma_weights: torch.Tensor
    photo_scale: float
    depth_scale: float
    event_scale: float

    @property
    def n_views(self) -> int:
        return int(self.rgb.shape[0])


def prepare_targets(obs: FrameObs, cfg: SlamConfig, theta: tuple[float, float], *,
                    tracking: bool, use_events: bool) -> LossTargets:
    """:class:`LossTargets` of one frame (V = 1) for tracking or mapping."""
    dtype = obs.rgb.dtype
    h, w = obs.depth.shape
    photo_scale = cfg.loss.lambda_id * cfg.loss.lambda_i / (3 * h * w)
    depth_scale = cfg.loss.lambda_id * cfg.loss.lambda_d / (h * w)
    weight = obs.rgb_mask.to(dtype) * photo_scale
    if tracking and obs.edge_weight is not None:
        weight = weight * obs.edge_weight.to(dtype)
    target = event_weight = None
    event_scale = 0.0
    if use_events and obs.event_maps is not None and len(obs.fractions) > 1:
        e = obs.event_maps.to(dtype)
        event_scale = cfg.loss.lambda_e / e.numel()
        target = torch.where(e > 0, theta[0] * e, theta[1] * e)
        lam_ne = cfg.loss.lambda_ne if cfg.method.no_event_loss else 0.0
        event_weight = torch.where(e != 0, torch.full_like(e, event_scale),
                                   torch.full_like(e, lam_ne * event_scale))
        target, event_weight = target[None], event_weight[None]
    luma = torch.tensor(LUMA_BT601, dtype=dtype, device=obs.rgb.device)  # once per frame
    return LossTargets(obs.rgb[None], weight[None], obs.depth[None],
                       (obs.depth_mask.to(dtype) * depth_scale)[None], target, event_weight,
                       luma, photo_scale, depth_scale, event_scale)


def stack_targets(targets: list[LossTargets]) -> LossTargets:
    """Concatenate the views of several :class:`LossTargets` (events only if all have them)."""
    def cat(parts: list[torch.Tensor | None]) -> torch.Tensor | None:
        present = [p for p in parts if p is not None]
        return torch.cat(present) if len(present) == len(parts) else None
    first = targets[0]
    return LossTargets(torch.cat([t.rgb for t in targets]),
                       torch.cat([t.photo_weight for t in targets]),
                       torch.cat([t.depth for t in targets]),
                       torch.cat([t.depth_mask for t in targets]),
                       cat([t.event_target for t in targets]),
                       cat([t.event_weight for t in targets]),
                       first.luma_weights, first.photo_scale, first.depth_scale,
                       first.event_scale)


def render_views(gmap: GaussianMap | FrozenGaussians, viewmats: torch.Tensor | np.ndarray,
                 K: torch.Tensor, width: int, height: int, cfg: SlamConfig, *,
                 visibility: bool = False):
    """Render world-to-camera ``viewmats`` [C, 4, 4] (any float dtype, tensor or array) with the
    map's dtype and device; returns the RasterResult (``visibility`` only when asked)."""
    if isinstance(viewmats, np.ndarray):
        viewmats = torch.from_numpy(viewmats)
    vm = viewmats.to(device=gmap.device, dtype=gmap.dtype)
    ks = K.to(gmap.dtype).expand(vm.shape[0], 3, 3)
    return gmap.render(vm, ks, width, height, near_plane=cfg.mapping.near_plane,
                       backend=cfg.runtime.backend, visibility=visibility)


class _LossParts(NamedTuple):
    """What :func:`blur_loss` and :func:`blur_loss_terms` share: the weighted total (scalar),
    the per-frame photometric and depth sums ``l_i``, ``l_d`` [V] and the event residual
    ``|theta E - predicted|`` [V, K, H, W] (None without events)."""

    total: torch.Tensor
    l_i: torch.Tensor
    l_d: torch.Tensor
    event_resid: torch.Tensor | None


def blur_loss(res, targets: LossTargets, crf: Callable[[torch.Tensor], torch.Tensor],
              exp_ab: torch.Tensor | None, cfg: SlamConfig, *, tracking: bool,
              eps: float) -> torch.Tensor:
    """Sum over the V frames of ``lambda_E L_E + lambda_ID (lambda_I L_I + lambda_D L_D)``
    (a scalar tensor).

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
    return _loss_parts(res, targets, crf, exp_ab, cfg, tracking=tracking, eps=eps).total


def blur_loss_terms(res, targets: LossTargets, crf: Callable[[torch.Tensor], torch.Tensor],
                    exp_ab: torch.Tensor | None, cfg: SlamConfig, *, tracking: bool,
                    eps: float) -> dict[str, torch.Tensor]:
    """The terms of :func:`blur_loss` (same arguments), summed over frames, for diagnostics:
    ``photometric`` L_I, ``depth`` L_D, ``event_he``, ``event_ne`` (unweighted; a term whose
    weight is 0 is NaN) and the weighted ``total``. Costs a few more operations."""
    parts = _loss_parts(res, targets, crf, exp_ab, cfg, tracking=tracking, eps=eps)
    h, w = res.rgb.shape[1:3]
    total = parts.total

    def unscaled(value: torch.Tensor, weight: float) -> torch.Tensor:
        return value / weight if weight else torch.full_like(value, float("nan"))
    out = {"photometric": unscaled(parts.l_i.sum(), targets.photo_scale * 3 * h * w),
           "depth": unscaled(parts.l_d.sum(), targets.depth_scale * h * w),
           "event_he": total.new_zeros(()), "event_ne": total.new_zeros(()), "total": total}
    if parts.event_resid is not None and targets.event_target is not None:
        resid = parts.event_resid
        has = (targets.event_target != 0).to(resid.dtype)
        out["event_he"] = (has * resid).mean((1, 2, 3)).sum()
        out["event_ne"] = ((1 - has) * resid).mean((1, 2, 3)).sum()
    return out


def _loss_parts(res, targets: LossTargets, crf: Callable[[torch.Tensor], torch.Tensor],
                exp_ab: torch.Tensor | None, cfg: SlamConfig, *, tracking: bool,
                eps: float) -> _LossParts:
    v = targets.n_views
    c, h, w = res.rgb.shape[:3]
    m = c // v
    hdr = res.rgb.view(v, m, h, w, 3)
    ldr = respond(crf, hdr.mean(1), exp_ab)
    alpha = res.alpha.detach().view(v, m, h, w)
    weight = targets.photo_weight
    depth_mask = targets.depth_mask[:, None]
    if tracking:
        weight = weight * alpha.mean(1)
        depth_mask = depth_mask * (alpha > 0.95)
    l_i = (weight[..., None] * (ldr - targets.rgb).abs()).sum((1, 2, 3))  # [V]
    depth = (res.expected_depth if cfg.loss.expected_depth else res.depth).view(v, m, h, w)
    l_d = (depth_mask * (depth - targets.depth[:, None]).abs()).sum((2, 3)).amin(1)  # [V]
    total = (l_i + l_d).sum()
    resid = None
    event_target, event_weight = targets.event_target, targets.event_weight
    if event_target is not None and event_weight is not None and m > 1:
        pred = rendered_event_maps(hdr, eps, targets.luma_weights)  # [V, K, H, W]
        resid = (event_target - pred).abs()
        if tracking:
            resid = resid * (alpha > 0.5).all(1, keepdim=True)
        total = total + (event_weight * resid).sum()
    return _LossParts(total, l_i, l_d, resid)


def respond(crf: Callable[[torch.Tensor], torch.Tensor], hdr: torch.Tensor,
            exp_ab: torch.Tensor | None) -> torch.Tensor:
    """LDR prediction ``exp(a) CRF(hdr) + b`` [V, H, W, 3] of mean HDR images [V, H, W, 3]
    with per-frame exposure ``exp_ab`` [V, 2] (None: ``CRF(hdr)``).

    A response with fixed parameters (``value_and_slope``: tracking's frozen curve, the
    identity) goes through one autograd node with a hand-written backward; a learnable one
    through autograd, so its parameters get gradients."""
    if exp_ab is None:
        return crf(hdr)
    if hasattr(crf, "value_and_slope"):
        return _FixedResponseWithExposure.apply(hdr, exp_ab, crf)
    ab = exp_ab.view(-1, 1, 1, 2)
    return torch.addcmul(ab[..., 1:], crf(hdr), ab[..., :1].exp())


class _FixedResponseWithExposure(torch.autograd.Function):
    """``exp(a) f(h) + b`` for a response ``f`` without parameters; gradients for ``h`` and
    ``(a, b)`` from ``f``'s precomputed derivative (a handful of operations instead of the
    autograd graph of the curve's branches)."""

    @staticmethod
    def forward(ctx, hdr: torch.Tensor, exp_ab: torch.Tensor, crf) -> torch.Tensor:
        value, slope = crf.value_and_slope(hdr)
        gain = exp_ab[:, 0].exp().view(-1, 1, 1, 1)
        out = torch.addcmul(exp_ab[:, 1].view(-1, 1, 1, 1), value, gain)
        ctx.save_for_backward(out, gain if slope is None else gain * slope, exp_ab[:, 1])
        return out

    @staticmethod
    def backward(ctx, grad: torch.Tensor):
        out, d_hdr, b = ctx.saved_tensors
        # d/da = exp(a) f(h) = out - b; d/db = 1
        g_a = (grad * (out - b.view(-1, 1, 1, 1))).sum((1, 2, 3))
        g_b = grad.sum((1, 2, 3))
        return grad * d_hdr, torch.stack([g_a, g_b], -1), None


def mapping_regulariser(gmap: GaussianMap, cfg: SlamConfig) -> torch.Tensor:
    """``lambda_iso`` x the isotropic term on the map's scales (paper eq. 15, MonoGS)."""
    return cfg.loss.lambda_iso * isotropic_loss(gmap.scales)
