"""Rasteriser time on a SLAM run's own map: what a late frame's renders cost.

A 150-frame run at 448x256 ends with about half a million Gaussians, where the synthetic scene
of ``bench_render.py`` has 20,000; at the coarse levels of the ``cpu`` preset the time then
goes to per-Gaussian work (projection, binning, the tiles' long lists) more than to blends.
This renders the map of RUN from the estimated pose of one of its frames with C cameras a few
millimetres apart (a blurred frame's sub-poses), forward and backward, at each scale, and prints
the median time of the calls after a warm-up one and the work they did.

usage: python benchmarks/bench_render_map.py RUN [--frame 140] [--cameras 3]
       [--scales 0.25 0.5 1.0] [--calls 5] [--pose-only]

RUN is a finished run folder (``map.ply``, ``appearance.json``, ``trajectory.txt``), e.g. one
of ``benchmarks/sweeps/cpu_448_150_prior01.yaml``. Time two versions of the code with the same
RUN in turn (whole process, A B A B) to compare them.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")  # see bench_render.py

import numpy as np
import torch

# the installed egs_bench (no path insertion), so PYTHONPATH can pick another checkout's code
from egs_bench.errors import EgsBenchError
from egs_bench.render.work import RenderWork, counting
from egs_bench.slam.map_export import frame_pose, open_map


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("run", type=Path)
    ap.add_argument("--frame", type=int, default=140)
    ap.add_argument("--cameras", type=int, default=3)
    ap.add_argument("--scales", type=float, nargs="+", default=[0.25, 0.5, 1.0])
    ap.add_argument("--calls", type=int, default=5)
    ap.add_argument("--pose-only", action="store_true",
                    help="gradients to the poses only (tracking); default: map and poses")
    args = ap.parse_args()
    try:
        src = open_map(args.run)
        if src.appearance is None:
            sys.exit(f"{args.run}: no appearance.json (needed for the camera)")
        world_to_cam = np.linalg.inv(frame_pose(src, args.frame))
    except EgsBenchError as err:  # a missing or unfinished run, a frame it does not have
        sys.exit(f"bench_render_map: {err}")
    cam = src.appearance.camera
    gmap = src.gmap.clone().requires_grad_(not args.pose_only)
    views = torch.tensor(np.stack([world_to_cam] * args.cameras), dtype=gmap.dtype)
    views[:, 0, 3] += 0.003 * torch.arange(args.cameras, dtype=gmap.dtype)
    print(f"{args.run}: {len(gmap)} Gaussians, frame {args.frame}, {args.cameras} cameras, "
          f"{'pose' if args.pose_only else 'map and pose'} gradients")
    for scale in args.scales:
        width, height = round(cam.width * scale), round(cam.height * scale)
        K = torch.tensor(cam.K, dtype=gmap.dtype)
        K[:2] *= scale
        times, work = [], RenderWork()
        for call in range(args.calls + 1):
            poses = views.clone().requires_grad_(True)
            start = time.perf_counter()
            with counting(work if call == 0 else RenderWork()):
                out = gmap.render(poses, K.expand(args.cameras, 3, 3), width, height)
                (out.rgb.sum() + out.depth.sum()).backward()
            if call > 0:
                times.append(time.perf_counter() - start)
        print(f"{width}x{height}: {statistics.median(times) * 1e3:.0f} ms per call "
              f"(min {min(times) * 1e3:.0f}, max {max(times) * 1e3:.0f}); "
              f"{work.isects / 1e6:.2f} M tile intersections, "
              f"{work.blends_fwd / 1e6:.2f} M blends forward")


if __name__ == "__main__":
    main()
