"""How much PSNR can deblurring gain on a sequence at a given processing resolution?

For the frames the ``egs`` protocol renders (every 5th), prints the mean masked PSNR against
the sharp ground truth of

* the blurred input frame itself (what a map that reproduces the blurred images scores), and
* the sharp frame area-downsampled by ``--scale`` and bilinearly upsampled back (roughly what a
  perfect map built at the processing resolution scores when rendered at full resolution).

Where the second number is not above the first, the blur is finer than the processing
resolution and no deblurring method can show a PSNR gain there.

    EGS_BENCH_DATA=data python benchmarks/psnr_headroom.py --seq demo --seq demo-fast --scale 0.5
"""

from __future__ import annotations

import argparse

import cv2
import numpy as np

from egs_bench.datasets.registry import load_sequence
from egs_bench.eval.image_metrics import psnr_masked


def resolution_round_trip(image: np.ndarray, scale: float) -> np.ndarray:
    """``image`` [H, W, 3] uint8 area-downsampled by ``scale`` and bilinearly upsampled back."""
    h, w = image.shape[:2]
    small = cv2.resize(image, (round(w * scale), round(h * scale)), interpolation=cv2.INTER_AREA)
    return cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seq", action="append", required=True, help="sequence folder or name")
    ap.add_argument("--scale", type=float, default=0.5, help="processing resolution factor")
    ap.add_argument("--stride", type=int, default=5, help="every n-th frame (the protocol's)")
    args = ap.parse_args()
    print(f"| sequence | blurred input dB | sharp at scale {args.scale} dB | headroom dB |")
    print("|:--|--:|--:|--:|")
    for name in args.seq:
        seq = load_sequence(name)
        blurred, ceiling = [], []
        for i in range(0, len(seq), args.stride):
            sharp = seq.sharp(i)
            if sharp is None:
                raise SystemExit(f"{seq.path}: frame {i} has no sharp ground truth")
            blurred.append(psnr_masked(seq.rgb(i), sharp))
            ceiling.append(psnr_masked(resolution_round_trip(sharp, args.scale), sharp))
        b, c = float(np.mean(blurred)), float(np.mean(ceiling))
        print(f"| {seq.name} | {b:.2f} | {c:.2f} | {c - b:+.2f} |")


if __name__ == "__main__":
    main()
