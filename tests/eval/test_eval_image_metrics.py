"""PSNR / SSIM against independent float64 implementations written here with plain numpy."""

import math

import numpy as np
import pytest
from numpy.lib.stride_tricks import sliding_window_view
from skimage.metrics import peak_signal_noise_ratio, structural_similarity

from egs_bench.eval.image_metrics import psnr, psnr_masked, ssim


def _pair(seed: int = 0, h: int = 37, w: int = 52) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:h, 0:w]
    base = np.stack([np.sin(xx / 5.0), np.cos(yy / 7.0), np.sin((xx + yy) / 9.0)], -1)
    ref = np.clip(0.5 + 0.4 * base + rng.normal(0, 0.05, base.shape), 0, 1)
    ref[:4, :6] = 0.0  # a black corner (matters for the masked PSNR)
    pred = np.clip(ref + rng.normal(0, 0.08, ref.shape), 0, 1)
    return pred, ref


def _ssim_reference(a: np.ndarray, b: np.ndarray, zero_pad: bool) -> float:
    """Direct definition: weighted window sums at every position (no convolution routine)."""
    x = np.arange(11) - 5.0
    g = np.exp(-(x**2) / (2 * 1.5**2))
    win = np.outer(g, g) / np.outer(g, g).sum()
    vals = []
    for c in range(3):
        pa, pb = a[..., c], b[..., c]
        if zero_pad:
            pa, pb = np.pad(pa, 5), np.pad(pb, 5)
        wa, wb = sliding_window_view(pa, (11, 11)), sliding_window_view(pb, (11, 11))
        mu_a = np.einsum("ijkl,kl->ij", wa, win)
        mu_b = np.einsum("ijkl,kl->ij", wb, win)
        va = np.einsum("ijkl,kl->ij", wa * wa, win) - mu_a**2
        vb = np.einsum("ijkl,kl->ij", wb * wb, win) - mu_b**2
        cov = np.einsum("ijkl,kl->ij", wa * wb, win) - mu_a * mu_b
        c1, c2 = 0.01**2, 0.03**2
        vals.append(((2 * mu_a * mu_b + c1) * (2 * cov + c2))
                    / ((mu_a**2 + mu_b**2 + c1) * (va + vb + c2)))
    return float(np.mean(vals))


@pytest.mark.parametrize("seed", [0, 1])
def test_ssim_variants_match_float64_reference(seed: int) -> None:
    pred, ref = _pair(seed)
    assert abs(ssim(pred, ref, "3dgs") - _ssim_reference(pred, ref, zero_pad=True)) < 1e-10
    assert abs(ssim(pred, ref, "standard") - _ssim_reference(pred, ref, zero_pad=False)) < 1e-10
    # the standard variant is also scikit-image's Gaussian SSIM
    sk = structural_similarity(pred, ref, data_range=1.0, channel_axis=-1, gaussian_weights=True,
                               sigma=1.5, use_sample_covariance=False)
    assert abs(ssim(pred, ref, "standard") - sk) < 1e-9
    # and the two conventions really differ (zero padding lowers border means)
    assert abs(ssim(pred, ref, "3dgs") - ssim(pred, ref, "standard")) > 1e-4


def test_ssim_uint8_and_identity() -> None:
    pred, ref = _pair(2)
    ref8 = np.round(ref * 255).astype(np.uint8)
    assert ssim(ref8, ref8) == pytest.approx(1.0, abs=1e-12)
    assert abs(ssim(ref8, ref8 // 2) - _ssim_reference(ref8 / 255.0, (ref8 // 2) / 255.0, True)) \
        < 1e-10
    with pytest.raises(ValueError, match="variant"):
        ssim(pred, ref, "ms-ssim")  # type: ignore[arg-type]  # the runtime check
    with pytest.raises(ValueError, match="sizes differ"):
        ssim(pred, ref[:-1])
    with pytest.raises(ValueError, match="at least 11x11"):
        ssim(pred[:8, :8], ref[:8, :8])


def test_psnr_full_and_masked_match_references() -> None:
    pred, ref = _pair(4)
    mse = np.mean((pred - ref) ** 2)
    assert abs(psnr(pred, ref) - 10 * math.log10(1 / mse)) < 1e-10
    assert abs(psnr(pred, ref) - peak_signal_noise_ratio(ref, pred, data_range=1.0)) < 1e-10
    mask = ref > 0
    mse_masked = np.sum(((pred - ref) ** 2)[mask]) / mask.sum()
    assert abs(psnr_masked(pred, ref) - 10 * math.log10(1 / mse_masked)) < 1e-10
    assert psnr_masked(pred, ref) != psnr(pred, ref)
    assert psnr(ref, ref) == math.inf
    assert math.isnan(psnr_masked(pred, np.zeros_like(ref)))
    p8, r8 = np.round(pred * 255).astype(np.uint8), np.round(ref * 255).astype(np.uint8)
    assert abs(psnr(p8, r8) - peak_signal_noise_ratio(r8, p8, data_range=255)) < 1e-10
