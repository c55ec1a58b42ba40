"""Speed of the synthetic-scene generator: one render, and a whole sequence with events.

1. Per-render time of :class:`egs_bench.datasets.synthetic.Renderer` for every scene at
   448x256 from the scene's anchor view, supersample 1 and 2, interleaved ``--repeats`` times
   (median wall and CPU time; numba compiled beforehand).
2. ``make_synthetic`` for ``--frames`` frames at 448x256 with events (default sampling of the
   pipeline), wall time, number of latent renders and the share of time spent rendering.
   ``--compare-sampling`` adds a run with ``max_bisections=0`` (flow rule only).

``--montage PNG`` also writes a montage of the scenes (sharp LDR, anchor views).

Usage: ``python benchmarks/bench_synthetic.py [--frames 100] [--repeats 5] [--scene office]``
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np
from tabulate import tabulate

from egs_bench.color import LdrResponse
from egs_bench.datasets.pipeline import SamplingConfig
from egs_bench.datasets.synthetic import SCENES, Renderer, build_scene, make_synthetic, pack_scene
from egs_bench.datasets.synthetic.source import default_intrinsics


def bench_renders(width: int, height: int, repeats: int) -> list[list]:
    cam = default_intrinsics(width, height)
    renderers = {}
    for name in SCENES:
        scene = build_scene(name)
        for ss in (1, 2):
            r = Renderer(pack_scene(scene), cam, supersample=ss)
            r.render(scene.anchor_pose())  # compile / warm up
            renderers[(name, ss)] = (r, scene.anchor_pose())
    wall: dict = {k: [] for k in renderers}
    cpu: dict = {k: [] for k in renderers}
    for _ in range(repeats):
        for key, (r, pose) in renderers.items():
            w0, c0 = time.perf_counter(), time.process_time()
            r.render(pose)
            wall[key].append(time.perf_counter() - w0)
            cpu[key].append(time.process_time() - c0)
    return [[name, ss, f"{1e3 * statistics.median(wall[(name, ss)]):.1f}",
             f"{1e3 * statistics.median(cpu[(name, ss)]):.1f}"] for name, ss in renderers]


def bench_sequence(scene: str, frames: int, width: int, height: int,
                   sampling: SamplingConfig, label: str) -> list:
    render_time = [0.0]
    n_renders = [0]
    original = Renderer.render

    def timed(self, pose):
        t0 = time.perf_counter()
        out = original(self, pose)
        render_time[0] += time.perf_counter() - t0
        n_renders[0] += 1
        return out

    Renderer.render = timed
    try:
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            make_synthetic(scene, Path(tmp) / "seq", frames=frames, width=width, height=height,
                           sampling=sampling, progress=False)
            total = time.perf_counter() - t0
    finally:
        Renderer.render = original
    return [label, frames, f"{total:.1f}", n_renders[0], f"{n_renders[0] / frames:.1f}",
            f"{1e3 * render_time[0] / max(1, n_renders[0]):.1f}",
            f"{100 * render_time[0] / total:.0f}%"]


def write_montage(path: Path, width: int, height: int) -> None:
    from egs_bench.images import write_ldr_image

    cam = default_intrinsics(width, height)
    tiles = []
    for name in SCENES:
        scene = build_scene(name)
        rgb, _ = Renderer(pack_scene(scene), cam, supersample=3).render(scene.anchor_pose())
        tiles.append(LdrResponse().to_ldr(rgb))
    rows = [np.concatenate(tiles[i:i + 2], axis=1) for i in range(0, len(tiles), 2)]
    if rows[-1].shape != rows[0].shape:
        rows[-1] = np.pad(rows[-1], ((0, 0), (0, rows[0].shape[1] - rows[-1].shape[1]), (0, 0)))
    write_ldr_image(path, np.concatenate(rows, axis=0))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=100)
    ap.add_argument("--width", type=int, default=448)
    ap.add_argument("--height", type=int, default=256)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--scene", default="office")
    ap.add_argument("--compare-sampling", action="store_true")
    ap.add_argument("--skip-sequence", action="store_true")
    ap.add_argument("--montage", type=Path, default=None)
    args = ap.parse_args()

    if args.montage is not None:
        write_montage(args.montage, args.width, args.height)
        print(f"wrote {args.montage}")
    rows = bench_renders(args.width, args.height, args.repeats)
    print(f"\nper render at {args.width}x{args.height} (anchor view, median of {args.repeats})")
    print(tabulate(rows, headers=["scene", "supersample", "wall ms", "CPU ms"]))
    if args.skip_sequence:
        return
    make_synthetic(args.scene, Path(tempfile.mkdtemp()) / "warm", frames=2, width=32,
                   height=24, progress=False)  # compile everything first
    seq_rows = [bench_sequence(args.scene, args.frames, args.width, args.height,
                               SamplingConfig(), "default sampling")]
    if args.compare_sampling:
        seq_rows.append(bench_sequence(args.scene, args.frames, args.width, args.height,
                                       SamplingConfig(max_bisections=0),
                                       "flow rule only (max_bisections=0)"))
    print(f"\nmake_synthetic {args.scene}, {args.width}x{args.height}, speed 1, events on")
    print(tabulate(seq_rows, headers=["sampling", "frames", "wall s", "renders",
                                      "renders/frame", "ms/render", "render share"]))


if __name__ == "__main__":
    main()
