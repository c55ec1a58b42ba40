"""Pieces of the EGS-SLAM loss (paper §III.C–D) and the MonoGS masks it is used with.

Images are channels-last: rendered / observed colour [H, W, 3], depth [H, W] in metres,
event maps [K, H, W] (sum of polarities per segment). The loss itself, batched over frames, is
:func:`egs_bench.slam.render_model.blur_loss`; this module holds its pieces and masks.
"""

from __future__ import annotations

import cv2
import numpy as np
import torch

from egs_bench.color import LUMA_BT601


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


def rendered_event_maps(hdr_rgb: torch.Tensor, eps: float,
                        luma_weights: torch.Tensor | None = None) -> torch.Tensor:
    """``E^_k = log(B(T(eta_k)) + eps) - log(B(T(eta_{k-1})) + eps)`` [..., K, H, W].

    Args:
        hdr_rgb: linear renders at the K+1 sub-poses [..., K+1, H, W, 3].
        eps: the log offset of the sequence's event model.
        luma_weights: BT.601 weights [3] on the renders' device (made here when None; pass
            them from a loop to avoid a host-to-device copy per call).
    """
    if luma_weights is None:
        luma_weights = torch.tensor(LUMA_BT601, dtype=hdr_rgb.dtype, device=hdr_rgb.device)
    log_b = torch.log((hdr_rgb @ luma_weights).clamp_min(0.0) + eps)
    return log_b[..., 1:, :, :] - log_b[..., :-1, :, :]


def isotropic_loss(scales: torch.Tensor) -> torch.Tensor:
    """MonoGS isotropic regulariser: mean over Gaussians and axes of |s - mean(s)| [N, 3]."""
    return (scales - scales.mean(-1, keepdim=True)).abs().mean()


def exposure_prior_gradient(exposure_ab: np.ndarray, weight: float) -> np.ndarray:
    """Gradient of the exposure prior ``weight * (a^2 + b^2)`` per frame (DSO's affine
    brightness prior; ``budget.lambda_exposure_prior``).

    The prior is applied on the host, where the SLAM's Adam steps the exposures, so it is a
    numpy function; its value is not part of the reported loss.

    Args:
        exposure_ab: exposure compensation ``(a, b)`` of ``exp(a) I + b`` per frame, [..., 2].
        weight: the prior's weight (0: no prior).
    Returns:
        ``2 weight (a, b)``, [..., 2] float64.
    """
    return 2.0 * float(weight) * np.asarray(exposure_ab, dtype=np.float64)
