"""EventReplica generator speed and interpolation quality at 448x256.

Input: the analytic textured room of the tests (``tests/helpers/replica_testscene.py``,
photographs from scikit-image on the walls, a floating box for occlusions) rendered at Replica's
1200x680 with Replica's intrinsics, exported to the NICE-SLAM layout as JPEG + 16-bit depth, as
a real Replica scene would be. Per-frame camera motion: about 2 cm and 1 degree (roughly 5-8 px
at 448x256), i.e. Replica-like hand-held motion at stride 1-2.

Reported:
1. Interpolators on one key-frame pair (after resize + crop to 448x256): preparation time,
   time per in-between frame (median over ``--repeats`` x 7 fractions), and PSNR of the frame at
   t = 0.5 against a direct render at the interpolated pose (rendered at 1200x680 and passed
   through the same resize + crop), beside naive 50/50 blending. Numba compilation is excluded.
2. ``make_eventreplica`` end to end for both interpolators (adaptive sampling, ESIM, blur,
   writing): wall and CPU time per output frame (CPU time is the steadier number on a shared
   machine), latent samples per frame, events per frame.

Usage: ``python benchmarks/bench_eventreplica.py [--frames 9] [--repeats 3]``
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from tabulate import tabulate

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this checkout's tests package

from egs_bench.color import linear_to_srgb
from egs_bench.datasets.eventreplica import (
    INTERPOLATORS,
    ReplicaSource,
    ResizeCrop,
    make_eventreplica,
)
from egs_bench.datasets.replica import export_replica_layout, read_replica
from egs_bench.datasets.sequence import Sequence
from egs_bench.geometry import Intrinsics, interpolate_pose
from tests.helpers import replica_testscene as scene

REPLICA = Intrinsics(600.0, 600.0, 600.0, 340.0, 1200, 680)  # egs-bench convention


def trajectory(n: int) -> list[np.ndarray]:
    return [scene.look_pose([0.02 * k, -0.006 * k, 0.012 * k], yaw_deg=1.0 * k,
                            pitch_deg=-0.4 * k, roll_deg=0.2 * k) for k in range(n)]


def render_replica(pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    i = REPLICA
    return scene.render(pose, i.fx, i.fy, i.cx, i.cy, i.width, i.height, supersample=1)


def make_input(folder: Path, n: int) -> tuple[Path, list[np.ndarray]]:
    poses = trajectory(n)
    rgbs, depths = [], []
    for pose in poses:
        rgb, depth = render_replica(pose)
        rgbs.append(np.round(linear_to_srgb(rgb) * 255).astype(np.uint8))
        depths.append(depth)
    # no cam_params.json: the reader's Replica defaults apply, exactly as for the real data
    return export_replica_layout(rgbs, depths, poses, folder / "scene"), poses


def psnr(x: np.ndarray, y: np.ndarray) -> float:
    return float(10 * np.log10(1.0 / np.mean((np.clip(x, 0, 1) - np.clip(y, 0, 1)) ** 2)))


def bench_interpolators(scene_dir: Path, poses: list[np.ndarray], repeats: int) -> list[list]:
    geo = ResizeCrop()
    mid_rgb, _ = render_replica(interpolate_pose(poses[1], poses[2], 0.5))
    # the reference goes through the same sRGB quantisation as the exported key frames
    mid_ldr = np.round(linear_to_srgb(mid_rgb) * 255) / 255.0
    mid_lin = np.where(mid_ldr <= 0.04045, mid_ldr / 12.92, ((mid_ldr + 0.055) / 1.055) ** 2.4)
    reference = geo.rgb(mid_lin.astype(np.float32), REPLICA)
    rows = []
    fractions = np.linspace(0.125, 0.875, 7)
    for name, make in INTERPOLATORS.items():
        src = ReplicaSource(read_replica(scene_dir), fps=30.0, interpolator=make())
        a, b = src.key_frame(1), src.key_frame(2)
        src.interpolator.prepare(a, b, src.intrinsics)(0.5)  # warm-up (numba compile)
        prep, per_frame = [], []
        for _ in range(repeats):
            t0 = time.perf_counter()
            pair = src.interpolator.prepare(a, b, src.intrinsics)
            prep.append(time.perf_counter() - t0)
            for f in fractions:
                t0 = time.perf_counter()
                pair(float(f))
                per_frame.append(time.perf_counter() - t0)
        rgb_mid, _ = src.interpolator.prepare(a, b, src.intrinsics)(0.5)
        rows.append([name, f"{1e3 * statistics.median(prep):.1f}",
                     f"{1e3 * statistics.median(per_frame):.1f}",
                     f"{psnr(rgb_mid, reference):.2f}"])
        if name == "depth":
            naive = psnr(0.5 * a.rgb + 0.5 * b.rgb, reference)
    rows.append(["naive 50/50 blend", "-", "-", f"{naive:.2f}"])
    return rows


def bench_end_to_end(scene_dir: Path, out_root: Path) -> list[list]:
    rows = []
    for name in INTERPOLATORS:
        out = out_root / f"seq_{name}"
        t0, c0 = time.perf_counter(), time.process_time()
        make_eventreplica(scene_dir, out, fps=30.0, exposure_ms=20.0, interpolator=name,
                          progress=False)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        seq = Sequence.open(out)
        n = len(seq)
        samples = seq.meta["sampling"]["num_samples"]
        rows.append([name, n, f"{wall / n:.2f}", f"{cpu / n:.2f}", f"{samples / n:.1f}",
                     f"{len(seq.events) / n:,.0f}"])
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--frames", type=int, default=9, help="input frames at 1200x680")
    parser.add_argument("--repeats", type=int, default=3, help="timing repeats (median)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench_eventreplica_") as tmp:
        t0 = time.perf_counter()
        scene_dir, poses = make_input(Path(tmp), args.frames)
        print(f"input: {args.frames} frames 1200x680 rendered + exported in "
              f"{time.perf_counter() - t0:.1f} s (not part of the generator)")
        print("\nInterpolators, one key-frame pair at 448x256 (median times):")
        print(tabulate(bench_interpolators(scene_dir, poses, args.repeats),
                       headers=["interpolator", "prepare pair [ms]", "per frame [ms]",
                                "PSNR t=0.5 vs direct render [dB]"], tablefmt="github"))
        print("\nmake_eventreplica end to end (448x256, 30 fps, 20 ms exposure, upsample auto):")
        print(tabulate(bench_end_to_end(scene_dir, Path(tmp)),
                       headers=["interpolator", "output frames", "wall s per output frame",
                                "CPU s per output frame",
                                "latent samples per frame", "events per frame"],
                       tablefmt="github"))


if __name__ == "__main__":
    main()
