"""The terms of the EGS-SLAM loss (paper §III.C-D, MonoGS masks), each named and weighted, in
one place.

A :class:`LossTerm` is

* a ``weight(cfg)``: its configuration field(s), e.g. ``lambda_e``;
* a ``prepare(obs, setup, weight)``: what it needs from one frame's observations, computed
  once per frame (tensors with a leading view axis of 1), or None when the term does not
  apply to the frame (the event term without events);
* a ``value(views, prepared)``: its weighted contribution per view [V] for a batch of V
  rendered frames, from the ``prepared`` tensors of the V frames stacked along the first axis.

The loss of a batch is the sum of every term's values (:func:`~egs_bench.slam.render_model.
blur_loss`). The built-in terms fold their weight and the ``1 / (number of values)`` of their
mean into the prepared masks, so an iteration costs a few weighted sums. Adding a term is one
function pair here (or in a user's module) plus the configuration field that weights it (a
user's term declares it in its ``config``, an extension of the ``loss`` group); pass
the extended tuple as :attr:`~egs_bench.slam.components.SlamComponents.loss_terms`.
``docs/guide/extending.md`` has a worked example.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import torch

from egs_bench.slam.config import SlamConfig
from egs_bench.slam.frames import FrameObs
from egs_bench.slam.losses import rendered_event_maps

Prepared = dict[str, torch.Tensor]


@dataclass(frozen=True)
class RenderedViews:
    """What the loss terms see of V frames rendered at M sub-poses each (channels last).

    Attributes:
        hdr: linear renders [V, M, H, W, 3].
        ldr: predicted observation [V, H, W, 3]: the sub-poses' mean through the response
            and exposure compensation.
        alpha: rendered opacity [V, M, H, W], detached (masks only).
        depth: rendered depth [V, M, H, W] in metres (alpha-normalised when
            ``loss.expected_depth``, else MonoGS's ``sum w z``).
        tracking: MonoGS's tracking masks instead of the mapping ones.
        eps: the log offset of the event model.
        luma_weights: BT.601 weights [3] on the renders' device.
    """

    hdr: torch.Tensor
    ldr: torch.Tensor
    alpha: torch.Tensor
    depth: torch.Tensor
    tracking: bool
    eps: float
    luma_weights: torch.Tensor


@dataclass(frozen=True)
class TermSetup:
    """What a term's ``prepare`` may depend on besides the frame: the configuration, the event
    thresholds ``(C+, C-)``, whether this is tracking, and whether the event loss is used."""

    cfg: SlamConfig
    theta: tuple[float, float]
    tracking: bool
    use_events: bool


@dataclass(frozen=True)
class LossTerm:
    """One named, weighted term; see the module docstring.

    Attributes:
        config: the class of the ``loss`` group that holds this term's settings (its weight):
            a frozen dataclass extending :class:`~egs_bench.slam.config.LossConfig`, with
            ``RANGES`` for its own fields; None: the built-in ``LossConfig``.
    """

    name: str
    weight: Callable[[SlamConfig], float]
    prepare: Callable[[FrameObs, TermSetup, float], Prepared | None]
    value: Callable[[RenderedViews, Prepared], torch.Tensor]
    config: type | None = None


# ---------------------------------------------------------------------- photometric (L_I)
def _prepare_photometric(obs: FrameObs, setup: TermSetup, weight: float) -> Prepared:
    h, w = obs.depth.shape
    mask = obs.rgb_mask.to(obs.rgb.dtype) * (weight / (3 * h * w))
    if setup.tracking and obs.edge_weight is not None:
        mask = mask * obs.edge_weight.to(obs.rgb.dtype)
    return {"rgb": obs.rgb[None], "weight": mask[None]}


def _photometric(views: RenderedViews, p: Prepared) -> torch.Tensor:
    """Mean over pixels and channels of ``|predicted - observed|`` under MonoGS's boundary mask
    (times the edge mask and the mean rendered opacity in tracking) [V]."""
    weight = p["weight"]
    if views.tracking:
        weight = weight * views.alpha.mean(1)
    return (weight[..., None] * (views.ldr - p["rgb"]).abs()).sum((1, 2, 3))


# ---------------------------------------------------------------------- depth (L_D)
def _prepare_depth(obs: FrameObs, setup: TermSetup, weight: float) -> Prepared:
    h, w = obs.depth.shape
    mask = obs.depth_mask.to(obs.rgb.dtype) * (weight / (h * w))
    return {"depth": obs.depth[None], "mask": mask[None]}


def _depth(views: RenderedViews, p: Prepared) -> torch.Tensor:
    """Per sub-pose mean over valid pixels of ``|rendered - observed depth|``, the smallest
    over the sub-poses (the observed depth is at one instant of the exposure) [V]; tracking
    keeps pixels whose rendered opacity exceeds 0.95."""
    mask = p["mask"][:, None]
    if views.tracking:
        mask = mask * (views.alpha > 0.95)
    return (mask * (views.depth - p["depth"][:, None]).abs()).sum((2, 3)).amin(1)


# ---------------------------------------------------------------------- events (L_HE, L_NE)
def _prepare_events(obs: FrameObs, setup: TermSetup, weight: float) -> Prepared | None:
    if not setup.use_events or obs.event_maps is None or len(obs.fractions) <= 1:
        return None
    cfg = setup.cfg
    e = obs.event_maps.to(obs.rgb.dtype)
    scale = weight / e.numel()
    target = torch.where(e > 0, setup.theta[0] * e, setup.theta[1] * e)
    lam_ne = cfg.loss.lambda_ne if cfg.method.no_event_loss else 0.0
    event_weight = torch.where(e != 0, torch.full_like(e, scale),
                               torch.full_like(e, lam_ne * scale))
    return {"target": target[None], "weight": event_weight[None]}


def event_residual(views: RenderedViews, p: Prepared) -> torch.Tensor:
    """``|theta E_k - (log B(k) - log B(k-1))|`` per segment [V, K, H, W]; in tracking only
    where every sub-image's rendered opacity exceeds 0.5."""
    pred = rendered_event_maps(views.hdr, views.eps, views.luma_weights)
    resid = (p["target"] - pred).abs()
    if views.tracking:
        resid = resid * (views.alpha > 0.5).all(1, keepdim=True)
    return resid


def _events(views: RenderedViews, p: Prepared) -> torch.Tensor:
    """``L_HE`` on pixels with events plus ``lambda_NE L_NE`` on silent ones (means) [V]."""
    return (p["weight"] * event_residual(views, p)).sum((1, 2, 3))


PHOTOMETRIC = LossTerm("photometric", lambda c: c.loss.lambda_id * c.loss.lambda_i,
                       _prepare_photometric, _photometric)
DEPTH = LossTerm("depth", lambda c: c.loss.lambda_id * c.loss.lambda_d, _prepare_depth, _depth)
EVENTS = LossTerm("events", lambda c: c.loss.lambda_e, _prepare_events, _events)

#: The EGS-SLAM loss ``lambda_ID (lambda_I L_I + lambda_D L_D) + lambda_E L_E``; the MonoGS
#: baseline is the same terms with its own weights and no events.
LOSS_TERMS: tuple[LossTerm, ...] = (PHOTOMETRIC, DEPTH, EVENTS)
