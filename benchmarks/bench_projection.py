"""CPU projection: the fused numba kernels against the PyTorch statement, inside a render.

For N random Gaussians in front of C cameras at 224x128 (the ``cpu`` preset's processing
resolution), times one forward + backward of the numba backend's compositing with either
projection, interleaved call by call so both see the same machine load, as CPU time of one
thread (``time.process_time``; robust on a shared machine). Two cases: ``pose-only`` (tracking:
only the view matrices need gradients) and ``all-params`` (mapping). Prints the median of
``--runs`` calls after one warm-up.

usage: NUMBA_CACHE_DIR=.cache/numba python benchmarks/bench_projection.py [--n 20000 110000]
       [--cameras 5] [--runs 7]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")  # see bench_render.py

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from egs_bench.render.numba_backend import composite_tiles
from egs_bench.render.numba_projection import project_gaussians_fused
from egs_bench.render.projection import project_gaussians

WIDTH, HEIGHT = 224, 128


def _scene(n: int, cameras: int) -> dict[str, torch.Tensor]:
    g = torch.Generator().manual_seed(0)
    means = ((torch.rand(n, 3, generator=g) - 0.5) * torch.tensor([4.0, 3.0, 2.0])
             + torch.tensor([0.0, 0.0, 3.0]))
    viewmats = torch.eye(4).repeat(cameras, 1, 1)
    viewmats[:, 0, 3] = torch.linspace(0.0, 0.05, cameras)
    return {"means": means, "quats": torch.randn(n, 4, generator=g),
            "scales": torch.rand(n, 3, generator=g) * 0.02 + 0.005,
            "opacities": torch.rand(n, generator=g) * 0.9 + 0.05,
            "colors": torch.rand(n, 3, generator=g), "viewmats": viewmats,
            "Ks": torch.tensor([[115.0, 0, 112], [0, 115, 64], [0, 0, 1]]).repeat(
                cameras, 1, 1)}


def _render_seconds(project, scene: dict[str, torch.Tensor], pose_only: bool) -> float:
    s = {k: v.clone().requires_grad_(k == "viewmats" or not pose_only) if k != "Ks" else v
         for k, v in scene.items()}
    t0 = time.process_time()
    proj = project(s["means"], s["quats"], s["scales"], s["opacities"], s["viewmats"], s["Ks"],
                   WIDTH, HEIGHT)
    rgb, depth, alpha, _ = composite_tiles(proj, s["opacities"], s["colors"], WIDTH, HEIGHT)
    (rgb.sum() + depth.sum() + alpha.sum()).backward()
    return time.process_time() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, nargs="+", default=[20_000, 110_000])
    ap.add_argument("--cameras", type=int, default=5)
    ap.add_argument("--runs", type=int, default=7)
    args = ap.parse_args()
    torch.set_num_threads(1)
    import numba

    numba.set_num_threads(1)
    print(f"{WIDTH}x{HEIGHT}, C={args.cameras}, fwd+bwd, CPU ms of one thread, median of "
          f"{args.runs}")
    print("| N | grads | PyTorch projection | fused projection | speed-up |")
    print("|---:|---|---:|---:|---:|")
    for n in args.n:
        scene = _scene(n, args.cameras)
        for pose_only in (True, False):
            times: dict[str, list[float]] = {"torch": [], "fused": []}
            for i in range(args.runs + 1):
                for name, project in (("torch", project_gaussians),
                                      ("fused", project_gaussians_fused)):
                    t = _render_seconds(project, scene, pose_only)
                    if i:
                        times[name].append(t)
            a, b = statistics.median(times["torch"]), statistics.median(times["fused"])
            print(f"| {n:,} | {'pose-only' if pose_only else 'all-params'} | {1e3 * a:.0f} | "
                  f"{1e3 * b:.0f} | {a / b:.2f}x |")


if __name__ == "__main__":
    main()
