"""How faithfully a run's saved map reproduces the run's renders, per colour path.

For every frame of a finished SLAM run folder (with ``appearance.json``) the run's own render
``renders/%06d.png`` is compared (PSNR, 8-bit) with:

* ``render-map``: the map rendered by ``egs-bench render-map RUN --frame I`` (the run's CRF);
* ``export``: the display-space export (``egs-bench export-map``) rendered the way the INRIA
  3DGS renderer does (degree-0 SH + 0.5, clamped at 0 per Gaussian; sigmoid opacity, exp
  scale; the blended pixel clamped to [0, 1]), same camera;
* ``export, no 0-clamp``: the same without the per-Gaussian clamp at 0 (gsplat's viewer);
* ``legacy``: what ``render-map`` did before ``appearance.json`` (linear colours sRGB-encoded,
  no CRF), at the run's pose and camera.

It also reports the median rendered alpha and the share of Gaussians with a negative colour
channel (what the INRIA clamp at 0 changes). The export applies the CRF per Gaussian before
blending, the run after it: the two agree where the CRF is one straight line and differ where it
bends (see :func:`egs_bench.slam.map_export.blend_response`).

``--crf-shift S`` (what-if): replace the run's CRF by a learnable curve whose node inputs are
moved by up to ``S`` (seeded, kept monotone) from the run's, and use ``render-map`` through that
curve as the reference instead of the run's renders (a run too short to learn its curve stands
in for one that did).

Usage: ``python benchmarks/check_portable_maps.py RUN_DIR [--crf-shift 0.018]``
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tabulate import tabulate

from egs_bench.eval.image_metrics import psnr
from egs_bench.render.ply import read_ply
from egs_bench.render.rasterize import rasterize
from egs_bench.runs.folder import RunFolder
from egs_bench.slam.crf import CameraResponse, LeakyPiecewiseLinearCRF, crf_to_dict
from egs_bench.slam.map_export import export_display_ply, frame_pose, open_map, render_map_view


def _shifted_crf(crf: CameraResponse, shift: float) -> LeakyPiecewiseLinearCRF:
    """A learnable curve with the nodes of ``crf`` (its identity start for other kinds) moved
    by up to ``shift``, seed 0, alternating in sign so the curve bends at every node."""
    nodes = (crf.nodes().detach().numpy().astype(np.float64)
             if isinstance(crf, LeakyPiecewiseLinearCRF) else np.linspace(0.0, 1.0, 16))
    rng = np.random.default_rng(0)
    signs = np.where(np.arange(len(nodes)) % 2 == 0, 1.0, -1.0)
    moved = nodes + signs * rng.uniform(0.5, 1.0, len(nodes)) * shift
    moved[0], moved[-1] = 0.0, 1.0
    gaps = np.diff(moved)
    if (gaps <= 0).any():
        raise SystemExit(f"--crf-shift {shift} makes the curve non-monotone")
    out = LeakyPiecewiseLinearCRF(len(nodes), crf.alpha if isinstance(
        crf, LeakyPiecewiseLinearCRF) else 0.01)
    with torch.no_grad():
        out.gap_logits.copy_(torch.tensor(np.log(gaps / gaps.sum()), dtype=torch.float32))
    print(f"CRF nodes moved by up to {np.abs(out.nodes().detach().numpy() - nodes).max():.4f}")
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--crf-shift", type=float, default=None,
                        help="what-if: move the CRF's nodes by up to this much (see above)")
    args = parser.parse_args()
    run = RunFolder.open(args.run_dir)
    src = open_map(args.run_dir)
    legacy_src = open_map(args.run_dir / "map.ply")
    app = src.appearance
    if app is None:
        raise SystemExit(f"{args.run_dir} has no appearance.json")
    if args.crf_shift is not None:
        app.crf = _shifted_crf(app.crf, args.crf_shift)

    def reference(frame: int) -> np.ndarray:
        if args.crf_shift is None:
            return run.read_render(frame)
        return render_map_view(src, frame=frame)[0]
    with tempfile.TemporaryDirectory() as tmp:
        exported, _ = read_ply(export_display_ply(src, Path(tmp) / "display.ply"))
    inria = exported.colors.clamp_min(0.0)  # 3DGS: SH_C0 f_dc + 0.5, clamped at 0
    K = torch.tensor(app.camera.K[None], dtype=torch.float32)

    def shown(colors: torch.Tensor, view: torch.Tensor) -> tuple[np.ndarray, float]:
        with torch.no_grad():
            out = rasterize(exported.means, exported.quats, exported.scales,
                            exported.opacities, colors, view, K, app.camera.width,
                            app.camera.height, near_plane=app.near_plane)
        img = (out.rgb[0].clamp(0, 1).numpy() * 255 + 0.5).astype(np.uint8)
        return img, float(out.alpha[0].median())

    rows: list[list[Any]] = []
    for frame in (int(f) for f in app.frames):
        ref = reference(frame)
        pose = frame_pose(src, frame)
        own, _ = render_map_view(src, frame=frame)
        legacy, _ = render_map_view(legacy_src, pose=pose, camera=app.camera, colors="linear")
        view = torch.tensor(np.linalg.inv(pose)[None], dtype=torch.float32)
        exp_img, alpha = shown(inria, view)
        raw_img, _ = shown(exported.colors, view)
        rows.append([frame, psnr(own, ref), psnr(exp_img, ref), psnr(raw_img, ref),
                     psnr(legacy, ref), alpha])
    arr = np.array(rows, dtype=np.float64)
    rows.append(["mean", *arr[:, 1:].mean(axis=0)])  # inf stays inf (identical images)
    rows.append(["min", *arr[:, 1:].min(axis=0)])
    print(tabulate(rows, headers=["frame", "render-map PSNR", "export PSNR",
                                  "export, no 0-clamp", "legacy PSNR", "median alpha"],
                   floatfmt=".2f"))
    negative = float((exported.colors < 0).any(dim=1).float().mean())
    print(f"{len(exported)} Gaussians ({100 * negative:.2f} % with a negative colour channel); "
          f"render-map identical to the run's render in {int(np.isinf(arr[:, 1]).sum())} of "
          f"{len(arr)} frames; CRF {crf_to_dict(app.crf)['kind']}")


if __name__ == "__main__":
    main()
