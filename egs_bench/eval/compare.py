"""Compare two image files with every image metric (``egs-bench compare-images``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from egs_bench.errors import InputError
from egs_bench.eval.image_metrics import psnr, psnr_masked, ssim
from egs_bench.eval.lpips import lpips_distance


def read_ldr_image(path: str | Path) -> np.ndarray:
    """Read an 8-bit image file as uint8 [H, W, 3] (grey is replicated, alpha dropped)."""
    import imageio.v3 as iio

    path = Path(path)
    if not path.is_file():
        raise InputError(path, "image not found")
    try:
        img = np.asarray(iio.imread(path))
    except Exception as exc:  # noqa: BLE001 (any decoder failure is a bad input file)
        raise InputError(path, f"cannot read image ({exc})") from None
    if img.dtype != np.uint8:
        raise InputError(path, f"expected an 8-bit image, found {img.dtype}")
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=2)
    if img.ndim != 3 or img.shape[2] not in (3, 4):
        raise InputError(path, f"expected an RGB image, found shape {img.shape}")
    return np.ascontiguousarray(img[..., :3])


def compare_image_files(path_a: str | Path, path_b: str | Path,
                        lpips_net: str = "alex") -> dict[str, float]:
    """PSNR (full, masked to ``b > 0``), SSIM (3DGS, standard) and LPIPS of ``a`` against ``b``.

    Raises:
        InputError: unreadable images or different sizes.
    """
    a, b = read_ldr_image(path_a), read_ldr_image(path_b)
    if a.shape != b.shape:
        raise InputError(path_a, f"is {a.shape[1]}x{a.shape[0]}, {Path(path_b).name} is "
                                 f"{b.shape[1]}x{b.shape[0]}: sizes must match")
    return {
        "psnr_db": psnr(a, b),
        "psnr_masked_db": psnr_masked(a, b),
        "ssim_3dgs": ssim(a, b, "3dgs"),
        "ssim_standard": ssim(a, b, "standard"),
        f"lpips_{lpips_net}": lpips_distance(a, b, net=lpips_net),
    }
