"""PSNR and SSIM for one rendered image against its reference, in the conventions of the field.

Inputs are LDR images, either uint8 [H, W, 3] (scaled by 1/255) or float [H, W, 3] in [0, 1].
Everything is computed in float64 on the CPU, one image at a time (kornia's ``psnr`` pools the
MSE over a batch, which is not what papers report).

Variants:

- ``psnr``: 10 log10(1 / MSE) over all pixels and channels.
- ``psnr_masked``: MonoGS' variant, MSE over the elements where the reference is > 0.
- ``ssim(..., variant="3dgs")``: the 3DGS / MonoGS SSIM: 11x11 Gaussian window, sigma 1.5,
  **zero padding**, mean over all pixels and channels. kornia has no zero-padding mode, so this
  one is a few lines of ``conv2d``.
- ``ssim(..., variant="standard")``: Wang et al. SSIM as in scikit-image (Gaussian window
  sigma 1.5, population covariance), averaged over the window positions fully inside the image;
  computed with ``kornia.metrics.ssim(padding="valid")``.
"""

from __future__ import annotations

import math
from typing import get_args

import numpy as np
import torch
import torch.nn.functional as F

from egs_bench.eval.protocols import SsimVariant

SSIM_VARIANTS: tuple[SsimVariant, ...] = get_args(SsimVariant)
_WINDOW = 11
_SIGMA = 1.5
_C1 = 0.01**2
_C2 = 0.03**2


def to_float_image(image: np.ndarray | torch.Tensor) -> torch.Tensor:
    """Convert an LDR image [H, W, 3] (uint8, or float in [0, 1]) to float64 [1, 3, H, W]."""
    if isinstance(image, torch.Tensor):
        image = image.detach().cpu().numpy()
    image = np.asarray(image)
    if image.ndim != 3 or image.shape[2] != 3:
        raise ValueError(f"expected an image [H, W, 3], got shape {image.shape}")
    if image.dtype == np.uint8:
        arr = image.astype(np.float64) / 255.0
    elif np.issubdtype(image.dtype, np.floating):
        arr = image.astype(np.float64)
    else:
        raise ValueError(f"unsupported image dtype {image.dtype} (use uint8 or float in [0, 1])")
    return torch.from_numpy(np.ascontiguousarray(arr)).permute(2, 0, 1)[None]


def _check_pair(pred: torch.Tensor, ref: torch.Tensor) -> None:
    if pred.shape != ref.shape:
        raise ValueError(f"image sizes differ: {tuple(pred.shape[-2:][::-1])} vs "
                         f"{tuple(ref.shape[-2:][::-1])} (W, H)")


def psnr(pred: np.ndarray | torch.Tensor, ref: np.ndarray | torch.Tensor) -> float:
    """PSNR in dB of ``pred`` against ``ref`` (peak 1.0; ``inf`` for identical images)."""
    a, b = to_float_image(pred), to_float_image(ref)
    _check_pair(a, b)
    mse = float(torch.mean((a - b) ** 2))
    return math.inf if mse == 0.0 else 10.0 * math.log10(1.0 / mse)


def psnr_masked(pred: np.ndarray | torch.Tensor, ref: np.ndarray | torch.Tensor) -> float:
    """MonoGS' PSNR: MSE over the elements (pixel, channel) where ``ref > 0``.

    Returns ``nan`` when the reference is entirely zero.
    """
    a, b = to_float_image(pred), to_float_image(ref)
    _check_pair(a, b)
    mask = b > 0
    if not bool(mask.any()):
        return math.nan
    mse = float(torch.mean((a[mask] - b[mask]) ** 2))
    return math.inf if mse == 0.0 else 10.0 * math.log10(1.0 / mse)


def _gaussian_window(channels: int) -> torch.Tensor:
    x = torch.arange(_WINDOW, dtype=torch.float64) - _WINDOW // 2
    g = torch.exp(-(x**2) / (2 * _SIGMA**2))
    g = g / g.sum()
    return torch.outer(g, g).expand(channels, 1, _WINDOW, _WINDOW).contiguous()


def ssim_3dgs_map(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """SSIM map of the 3DGS convention (zero padding), inputs [B, C, H, W] -> [B, C, H, W]."""
    channels = a.shape[1]
    w = _gaussian_window(channels).to(a.dtype)
    pad = _WINDOW // 2

    def blur(x: torch.Tensor) -> torch.Tensor:
        return F.conv2d(x, w, padding=pad, groups=channels)

    mu_a, mu_b = blur(a), blur(b)
    var_a = blur(a * a) - mu_a**2
    var_b = blur(b * b) - mu_b**2
    cov = blur(a * b) - mu_a * mu_b
    num = (2 * mu_a * mu_b + _C1) * (2 * cov + _C2)
    den = (mu_a**2 + mu_b**2 + _C1) * (var_a + var_b + _C2)
    return num / den


def ssim(
    pred: np.ndarray | torch.Tensor,
    ref: np.ndarray | torch.Tensor,
    variant: SsimVariant = "3dgs",
) -> float:
    """SSIM of ``pred`` against ``ref`` (see the module docstring for the two variants).

    Raises:
        ValueError: unknown variant, different sizes, or an image smaller than 11x11.
    """
    if variant not in SSIM_VARIANTS:
        raise ValueError(f"unknown SSIM variant {variant!r}; choose one of {SSIM_VARIANTS}")
    a, b = to_float_image(pred), to_float_image(ref)
    _check_pair(a, b)
    if min(a.shape[-2:]) < _WINDOW:
        raise ValueError(f"SSIM needs images of at least {_WINDOW}x{_WINDOW} pixels")
    if variant == "3dgs":
        return float(ssim_3dgs_map(a, b).mean())
    import kornia.metrics

    return float(kornia.metrics.ssim(a, b, _WINDOW, max_val=1.0, eps=0.0, padding="valid").mean())
