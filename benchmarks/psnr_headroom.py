"""How much PSNR can deblurring gain on a sequence at a given processing resolution, and how
much do runs gain, by blur extent?

For the frames the ``egs`` protocol renders (every 5th), prints the mean masked PSNR against
the sharp ground truth of

* the blurred input frame itself (what a map that reproduces the blurred images scores), and
* the sharp frame area-downsampled by ``--scale`` and bilinearly upsampled back (roughly what a
  perfect map built at the processing resolution scores when rendered at full resolution).

Where the second number is not above the first, the blur is finer than the processing
resolution and no deblurring method can show a PSNR gain there.

With ``--run NAME=RUN_FOLDER`` (evaluated runs on the one ``--seq``), the same frames are also
split by their blur extent (the ground-truth motion of the frame's exposure, in full-resolution
pixels, as ``egs-bench info`` reports it) and each run's PSNR from its ``metrics.json`` is shown
per bin: whether a method's gain grows with the blur, and how close it gets to the two bounds.

    EGS_BENCH_DATA=data python benchmarks/psnr_headroom.py --seq demo --seq demo-fast --scale 0.5
    EGS_BENCH_DATA=data python benchmarks/psnr_headroom.py --seq office-l --scale 0.5 \\
      --run egs=bench_out/paper_scale/runs/office-l/egs/seed0 \\
      --run monogs=bench_out/paper_scale/runs/office-l/monogs/seed0
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np

from egs_bench.datasets.inspect import blur_extent_px
from egs_bench.datasets.registry import load_sequence
from egs_bench.datasets.sequence import Sequence
from egs_bench.eval.image_metrics import psnr_masked
from egs_bench.eval.metrics_file import read_metrics

BLUR_BINS_PX = (0.0, 6.0, 10.0, 14.0, float("inf"))


def resolution_round_trip(image: np.ndarray, scale: float) -> np.ndarray:
    """``image`` [H, W, 3] uint8 area-downsampled by ``scale`` and bilinearly upsampled back."""
    h, w = image.shape[:2]
    small = cv2.resize(image, (round(w * scale), round(h * scale)), interpolation=cv2.INTER_AREA)
    return cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR)


def frame_bounds(seq: Sequence, frames: list[int], scale: float
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Per frame: masked PSNR [dB] of the blurred input and of the sharp frame through the
    processing resolution, both against the sharp ground truth; shapes [len(frames)]."""
    blurred, ceiling = [], []
    for i in frames:
        sharp = seq.sharp(i)
        if sharp is None:
            raise SystemExit(f"{seq.path}: frame {i} has no sharp ground truth")
        blurred.append(psnr_masked(seq.rgb(i), sharp))
        ceiling.append(psnr_masked(resolution_round_trip(sharp, scale), sharp))
    return np.array(blurred), np.array(ceiling)


def run_psnr(run_dir: Path) -> dict[int, float]:
    """A run's per-frame PSNR [dB] from its ``metrics.json``, by frame index."""
    per_frame = (read_metrics(run_dir).rendering or {}).get("per_frame")
    if not per_frame:
        raise SystemExit(f"{run_dir}/metrics.json: no per-frame rendering metrics")
    return dict(zip(per_frame["frame"], per_frame["psnr_db"], strict=True))


def print_by_blur(seq: Sequence, runs: dict[str, dict[int, float]], scale: float) -> None:
    """The table by blur extent over the frames every run rendered."""
    frames = sorted(set.intersection(*(set(r) for r in runs.values())))
    blurred, ceiling = frame_bounds(seq, frames, scale)
    extent = np.array([blur_extent_px(seq, i) for i in frames], dtype=float)
    names = list(runs)
    print(f"\n{seq.name}, {len(frames)} frames; blur extent mean {np.nanmean(extent):.1f} px")
    print("| blur px | frames | blurred input dB | sharp at scale dB | "
          + " | ".join(f"{n} dB" for n in names) + " |")
    print("|:--|--:|--:|--:|" + "--:|" * len(names))
    edges = list(zip(BLUR_BINS_PX[:-1], BLUR_BINS_PX[1:], strict=True)) + [(0.0, float("inf"))]
    for lo, hi in edges:
        sel = (extent >= lo) & (extent < hi)
        if not sel.any():
            continue
        label = "all" if (lo, hi) == (0.0, float("inf")) else \
            (f"{lo:g}-{hi:g}" if np.isfinite(hi) else f">= {lo:g}")
        cells = [f"{np.mean([runs[n][f] for f, s in zip(frames, sel, strict=True) if s]):.2f}"
                 for n in names]
        print(f"| {label} | {int(sel.sum())} | {blurred[sel].mean():.2f} | "
              f"{ceiling[sel].mean():.2f} | " + " | ".join(cells) + " |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seq", action="append", required=True, help="sequence folder or name")
    ap.add_argument("--scale", type=float, default=0.5, help="processing resolution factor")
    ap.add_argument("--stride", type=int, default=5, help="every n-th frame (the protocol's)")
    ap.add_argument("--run", action="append", default=[], metavar="NAME=RUN_FOLDER",
                    help="an evaluated run on the (single) --seq, for the table by blur extent")
    args = ap.parse_args()
    print(f"| sequence | blurred input dB | sharp at scale {args.scale} dB | headroom dB |")
    print("|:--|--:|--:|--:|")
    for name in args.seq:
        seq = load_sequence(name)
        blurred, ceiling = frame_bounds(seq, list(range(0, len(seq), args.stride)), args.scale)
        b, c = float(np.mean(blurred)), float(np.mean(ceiling))
        print(f"| {seq.name} | {b:.2f} | {c:.2f} | {c - b:+.2f} |")
    if args.run:
        if len(args.seq) != 1:
            raise SystemExit("--run needs exactly one --seq (the runs' sequence)")
        runs = {}
        for item in args.run:
            label, sep, folder = item.partition("=")
            if not sep or not label or not folder:
                raise SystemExit(f"--run {item!r}: expected NAME=RUN_FOLDER")
            runs[label] = run_psnr(Path(folder))
        print_by_blur(load_sequence(args.seq[0]), runs, args.scale)


if __name__ == "__main__":
    main()
