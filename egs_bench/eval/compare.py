"""Compare two image files with every image metric (``egs-bench compare-images``)."""

from __future__ import annotations

from pathlib import Path

from egs_bench.errors import InputError
from egs_bench.eval.image_metrics import psnr, psnr_masked, ssim
from egs_bench.eval.lpips import lpips_distance
from egs_bench.eval.protocols import LpipsNet
from egs_bench.images import read_ldr_image


def compare_image_files(path_a: str | Path, path_b: str | Path,
                        lpips_net: LpipsNet = "alex") -> dict[str, float]:
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
