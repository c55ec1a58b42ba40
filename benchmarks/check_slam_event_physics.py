"""Check of the SLAM event-loss physics on a synthetic sequence (a measurement, not a test).

Renders the sharp linear HDR image of the synthetic scene at the ground-truth (dense
trajectory) poses at the SLAM's sub-pose edges of a few frames, turns them into predicted
event maps with the SLAM's own :func:`egs_bench.slam.losses.rendered_event_maps` (BT.601
linear luma, the sequence's eps), and compares them with ``theta * E_k`` from
``seq.event_maps(i, edges)`` ((a, b] windows). Agreement (correlation, slope near 1) means
the sub-pose edges, the event windows, the luma and eps of the event loss are consistent
with how the data were generated.

    python benchmarks/check_slam_event_physics.py SEQUENCE_DIR [--frames 3,10,20] [--k 3]
"""

from __future__ import annotations

import argparse

import numpy as np
import torch

from egs_bench.datasets.sequence import Sequence
from egs_bench.datasets.synthetic.raycast import Renderer
from egs_bench.datasets.synthetic.scene import pack_scene
from egs_bench.datasets.synthetic.scenes import build_scene
from egs_bench.geometry import interpolate_trajectory
from egs_bench.slam.exposure import segment_edges_us, subpose_fractions
from egs_bench.slam.losses import rendered_event_maps


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sequence", help="synthetic sequence folder (meta.yaml names its scene)")
    ap.add_argument("--frames", default="3,10,20", help="comma-separated frame indices")
    ap.add_argument("--k", type=int, default=3, help="segments K per exposure")
    args = ap.parse_args()

    seq = Sequence.open(args.sequence)
    dense = seq.dense_trajectory
    if dense is None or "synthetic" not in seq.meta:
        raise SystemExit(f"{args.sequence}: needs a synthetic sequence with a dense trajectory")
    renderer = Renderer(pack_scene(build_scene(seq.meta["synthetic"]["scene"])),
                        seq.intrinsics, supersample=int(seq.meta["synthetic"]["supersample"]))
    for i in (int(v) for v in args.frames.split(",")):
        t0, t1 = (int(v) for v in seq.exposure(i))
        fractions = subpose_fractions(seq.events.window(t0, t1 + 1).t, t0, t1, args.k)
        edges = segment_edges_us(fractions, t0, t1)
        poses = interpolate_trajectory(dense.timestamps * 1e6, dense.poses,
                                       edges.astype(np.float64))
        hdr = np.stack([renderer.render(p)[0] for p in poses])
        pred = rendered_event_maps(torch.from_numpy(hdr).double(), seq.eps).numpy()
        ev = seq.event_maps(i, edges).astype(np.float64)
        target = np.where(ev > 0, seq.pos_threshold, seq.neg_threshold) * ev
        on = ev != 0
        slope = (pred[on] * target[on]).sum() / (target[on] ** 2).sum()
        corr = np.corrcoef(pred[on], target[on])[0, 1]
        print(f"frame {i}: sub-pose edges {edges - t0} us; event pixels: corr {corr:.3f}, "
              f"slope {slope:.3f}, mean |pred - theta E| {np.abs(pred[on] - target[on]).mean():.3f}"
              f" vs mean |theta E| {np.abs(target[on]).mean():.3f}; silent pixels: mean |pred| "
              f"{np.abs(pred[~on]).mean():.4f}")


if __name__ == "__main__":
    main()
