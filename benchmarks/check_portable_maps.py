"""How faithfully a run's saved map reproduces the run's renders, per colour path.

For every frame of a finished SLAM run folder (with ``appearance.json``) the run's own render
``renders/%06d.png`` is compared (PSNR, 8-bit) with:

* ``render-map``: the map rendered by ``egs-bench render-map RUN --frame I`` (the run's CRF);
* ``export``: the display-space export (``egs-bench export-map``) rendered the way 3DGS
  renderers do (degree-0 SH + 0.5, clamped at 0; sigmoid opacity, exp scale), same camera;
* ``legacy``: what ``render-map`` did before ``appearance.json`` (linear colours sRGB-encoded,
  no CRF), at the run's pose and camera.

It also reports the median rendered alpha: the export applies the CRF per Gaussian before
blending, the run after it, so the two differ most where the map is not opaque.

Usage: ``python benchmarks/check_portable_maps.py RUN_DIR``
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
import torch
from tabulate import tabulate

from egs_bench.eval.image_metrics import psnr
from egs_bench.render.ply import read_ply
from egs_bench.render.rasterize import rasterize
from egs_bench.runs.folder import RunFolder
from egs_bench.slam.map_export import export_display_ply, frame_pose, open_map, render_map_view


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    args = parser.parse_args()
    run = RunFolder.open(args.run_dir)
    src = open_map(args.run_dir)
    legacy_src = open_map(args.run_dir / "map.ply")
    app = src.appearance
    if app is None:
        raise SystemExit(f"{args.run_dir} has no appearance.json")
    with tempfile.TemporaryDirectory() as tmp:
        exported, _ = read_ply(export_display_ply(src, Path(tmp) / "display.ply"))
    shown = exported.colors.clamp_min(0.0)  # 3DGS: SH_C0 f_dc + 0.5, clamped at 0
    K = torch.tensor(app.camera.K[None], dtype=torch.float32)  # noqa: N806
    rows = []
    for frame in (int(f) for f in app.frames):
        ref = run.read_render(frame)
        pose = frame_pose(src, frame)
        own, _ = render_map_view(src, frame=frame)
        legacy, _ = render_map_view(legacy_src, pose=pose, camera=app.camera, colors="linear")
        view = torch.tensor(np.linalg.inv(pose)[None], dtype=torch.float32)
        with torch.no_grad():
            out = rasterize(exported.means, exported.quats, exported.scales,
                            exported.opacities, shown, view, K, app.camera.width,
                            app.camera.height, near_plane=app.near_plane)
        exp_img = (out.rgb[0].clamp(0, 1).numpy() * 255 + 0.5).astype(np.uint8)
        rows.append([frame, psnr(own, ref), psnr(exp_img, ref), psnr(legacy, ref),
                     float(out.alpha[0].median())])
    arr = np.array(rows, dtype=np.float64)
    rows.append(["mean", *arr[:, 1:].mean(axis=0)])  # inf stays inf (identical images)
    print(tabulate(rows, headers=["frame", "render-map PSNR", "export PSNR", "legacy PSNR",
                                  "median alpha"], floatfmt=".2f"))
    print(f"{len(exported)} Gaussians; render-map identical to the run's render in "
          f"{int(np.isinf(arr[:, 1]).sum())} of {len(arr)} frames")


if __name__ == "__main__":
    main()
