"""Blur-aware rendering of one frame and its loss (paper §III.B–C, MonoGS masks).

One rasteriser call renders the M sub-poses of the exposure; the HDR average goes through the
CRF (and MonoGS's exposure compensation) to the LDR prediction; event maps are log-luma
differences between consecutive sub-frames.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from egs_bench.render import GaussianMap
from egs_bench.slam.config import SlamConfig
from egs_bench.slam.crf import CameraResponse
from egs_bench.slam.exposure import interpolate_w2c
from egs_bench.slam.frames import FrameObs
from egs_bench.slam.losses import (
    event_loss,
    min_depth_loss,
    photometric_l1,
    rendered_event_maps,
)


@dataclass
class LossParts:
    total: torch.Tensor
    photometric: float
    depth: float
    event_he: float
    event_ne: float


def subposes(pose0_cw: torch.Tensor, pose1_cw: torch.Tensor, fractions: torch.Tensor
             ) -> torch.Tensor:
    """World-to-camera sub-poses [M, 4, 4]; with a single fraction 1.0 just ``pose1_cw``."""
    if fractions.numel() == 1:
        return pose1_cw[None]
    return interpolate_w2c(pose0_cw, pose1_cw, fractions)


def render_views(gmap: GaussianMap, viewmats: torch.Tensor, K: torch.Tensor, width: int,
                 height: int, cfg: SlamConfig):
    """Render ``viewmats`` [C, 4, 4] (any float dtype) with the map's dtype; RasterResult."""
    vm = viewmats.to(gmap.dtype)
    ks = K.to(gmap.dtype).expand(vm.shape[0], 3, 3)
    return gmap.render(vm, ks, width, height, near_plane=cfg.near_plane, backend=cfg.backend)


def frame_loss(res, obs: FrameObs, crf: CameraResponse, exp_a: torch.Tensor,
               exp_b: torch.Tensor, cfg: SlamConfig, *, tracking: bool, use_events: bool,
               theta: tuple[float, float], eps: float) -> LossParts:
    """``lambda_E L_E + lambda_ID (lambda_I L_I + lambda_D L_D)`` for one frame.

    Args:
        res: RasterResult of the frame's M sub-poses.
        exp_a, exp_b: exposure compensation scalars (tensors; zero when disabled).
        tracking: MonoGS tracking masks (edge x opacity weight, opacity > 0.95 for depth)
            instead of the mapping masks.
        theta: (positive, negative) contrast thresholds.
    """
    hdr = res.rgb  # [M, H, W, 3]
    ldr = crf(hdr.mean(0))
    if cfg.exposure_compensation:
        ldr = torch.exp(exp_a) * ldr + exp_b
    alpha = res.alpha.detach()
    weight = None
    depth_mask = obs.depth_mask
    if tracking:
        weight = alpha.mean(0)
        if obs.edge_weight is not None:
            weight = weight * obs.edge_weight
        depth_mask = obs.depth_mask[None] & (alpha > 0.95)
    l_i = photometric_l1(ldr, obs.rgb, obs.rgb_mask, weight)
    rendered_depth = res.expected_depth if cfg.expected_depth else res.depth
    l_d = min_depth_loss(rendered_depth, obs.depth, depth_mask)
    total = cfg.lambda_id * (cfg.lambda_i * l_i + cfg.lambda_d * l_d)
    l_he = l_ne = torch.zeros((), dtype=hdr.dtype, device=hdr.device)
    if use_events and obs.event_maps is not None and hdr.shape[0] > 1:
        pred = rendered_event_maps(hdr, eps)
        valid = (alpha > 0.5).all(0) if tracking else None
        l_he, l_ne = event_loss(pred, obs.event_maps, theta[0], theta[1], valid)
        lam_ne = cfg.lambda_ne if cfg.no_event_loss else 0.0
        total = total + cfg.lambda_e * (l_he + lam_ne * l_ne)
    return LossParts(total, float(l_i.detach()), float(l_d.detach()), float(l_he.detach()),
                     float(l_ne.detach()))
