"""Loss terms of EGS-SLAM (paper §III.C–D) and the MonoGS masks they are used with.

Images are channels-last: rendered / observed colour [H, W, 3], depth [H, W] in metres,
event maps [K, H, W] (sum of polarities per segment). Every mean runs over *all* pixels with
masked pixels contributing zero, as MonoGS does, so terms keep their scale when masks shrink.
"""

from __future__ import annotations

import cv2
import numpy as np
import torch

from egs_bench.color import luma


def rgb_boundary_mask(obs_rgb: torch.Tensor, threshold: float = 0.01) -> torch.Tensor:
    """Pixels whose channel sum exceeds ``threshold`` (MonoGS drops near-black pixels) [H, W]."""
    return obs_rgb.sum(-1) > threshold


def depth_valid_mask(obs_depth: torch.Tensor, min_depth: float = 0.01) -> torch.Tensor:
    """Pixels with a valid depth measurement (> ``min_depth`` metres) [H, W]."""
    return obs_depth > min_depth


def edge_mask(obs_rgb: np.ndarray, edge_threshold: float, blocks: int | None = 32) -> np.ndarray:
    """MonoGS tracking mask of high-gradient pixels, float32 [H, W] in {0, 1}.

    Gradient magnitude of the channel-mean image (Scharr 3x3, reflect padding, /32), zeroed
    next to near-black pixels (any 3x3 neighbour <= 0.01). With ``blocks`` the image is cut into
    a blocks x blocks grid and a pixel is kept where its magnitude exceeds ``edge_threshold``
    times its block's median (MonoGS's Replica mode; unlike MonoGS, the remainder rows/columns
    that do not fill a block are binarised against the last block too). Without ``blocks`` the
    global median is used (MonoGS's TUM mode).

    Args:
        obs_rgb: observed LDR image [H, W, 3] in [0, 1].
    """
    gray = np.asarray(obs_rgb, dtype=np.float32).mean(-1)
    gx = cv2.Scharr(gray, cv2.CV_32F, 1, 0, borderType=cv2.BORDER_REFLECT) / 32.0
    gy = cv2.Scharr(gray, cv2.CV_32F, 0, 1, borderType=cv2.BORDER_REFLECT) / 32.0
    mag = np.sqrt(gx * gx + gy * gy)
    dark = cv2.dilate((np.abs(gray) <= 0.01).astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    mag[dark] = 0.0
    h, w = gray.shape
    if blocks is None or h < blocks or w < blocks:
        return (mag > edge_threshold * np.median(mag)).astype(np.float32)
    out = np.zeros_like(mag)
    bh, bw = h // blocks, w // blocks
    for i in range(blocks):
        r1 = h if i == blocks - 1 else (i + 1) * bh
        for j in range(blocks):
            c1 = w if j == blocks - 1 else (j + 1) * bw
            block = mag[i * bh:r1, j * bw:c1]
            out[i * bh:r1, j * bw:c1] = block > edge_threshold * np.median(block)
    return out


def photometric_l1(pred: torch.Tensor, obs: torch.Tensor, mask: torch.Tensor,
                   weight: torch.Tensor | None = None) -> torch.Tensor:
    """``mean(weight * |pred - obs|)`` over all 3 H W values, masked pixels count as zero.

    Args:
        pred, obs: LDR images [H, W, 3]. mask: bool [H, W]. weight: [H, W] or None (MonoGS
        tracking passes edge mask x detached rendered opacity).
    """
    m = mask.to(pred.dtype)
    if weight is not None:
        m = m * weight.to(pred.dtype)
    return (m[..., None] * (pred - obs).abs()).mean()


def depth_l1(pred: torch.Tensor, obs: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """``mean(|pred - obs|)`` over all H W pixels of depth [H, W], masked pixels count zero."""
    return (mask.to(pred.dtype) * (pred - obs).abs()).mean()


def min_depth_loss(pred: torch.Tensor, obs: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Paper's ``L_D = min_k ||D_obs - D(T(eta_k))||_1`` for rendered depths [M, H, W].

    Args:
        pred: rendered depth per sub-pose [M, H, W]. obs: observed depth [H, W].
        mask: bool [H, W] (shared) or [M, H, W] (per sub-pose, e.g. rendered opacity > 0.95).
    """
    if mask.dim() == 2:
        mask = mask[None]
    if pred.dim() != 3 or mask.dim() != 3 or mask.shape[1:] != pred.shape[1:]:
        raise ValueError(f"depth [M,H,W] {tuple(pred.shape)} and mask {tuple(mask.shape)} differ")
    per_pose = (mask.to(pred.dtype) * (pred - obs[None]).abs()).mean(dim=(1, 2))  # [M]
    return per_pose.min()


def rendered_event_maps(hdr_rgb: torch.Tensor, eps: float) -> torch.Tensor:
    """``E^_k = log(B(T(eta_k)) + eps) - log(B(T(eta_{k-1})) + eps)`` [K, H, W].

    Args:
        hdr_rgb: linear renders at the K+1 sub-poses [K+1, H, W, 3].
        eps: the log offset of the sequence (docs/design.md §2).
    """
    log_b = torch.log(luma(hdr_rgb).clamp_min(0.0) + eps)
    return log_b[1:] - log_b[:-1]


def event_loss(pred_maps: torch.Tensor, event_maps: torch.Tensor, theta_pos: float,
               theta_neg: float, valid: torch.Tensor | None = None
               ) -> tuple[torch.Tensor, torch.Tensor]:
    """Paper's ``L_HE`` and ``L_NE`` (per-pixel means over all H W pixels, averaged over K).

    ``L_HE``: over pixels with ``E_k != 0`` of ``|theta E_k - E^_k|`` where theta is the
    positive or negative contrast threshold by the sign of ``E_k``; ``L_NE``: over ``E_k == 0``
    of ``|E^_k|``.

    Args:
        pred_maps: rendered log-luma differences [K, H, W].
        event_maps: observed polarity sums [K, H, W] (any integer/float dtype).
        valid: optional bool [H, W] of pixels to use (e.g. excluding unobserved map regions).
    """
    e = event_maps.to(pred_maps.dtype)
    theta = torch.where(e > 0, torch.full_like(e, theta_pos), torch.full_like(e, theta_neg))
    has_event = e != 0
    resid_he = (theta * e - pred_maps).abs() * has_event
    resid_ne = pred_maps.abs() * (~has_event)
    if valid is not None:
        v = valid.to(pred_maps.dtype)[None]
        resid_he, resid_ne = resid_he * v, resid_ne * v
    return resid_he.mean(), resid_ne.mean()


def isotropic_loss(scales: torch.Tensor) -> torch.Tensor:
    """MonoGS isotropic regulariser: mean over Gaussians and axes of |s - mean(s)| [N, 3]."""
    return (scales - scales.mean(-1, keepdim=True)).abs().mean()
