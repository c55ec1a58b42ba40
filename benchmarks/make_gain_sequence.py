"""A copy of a sequence whose colour frames change exposure: frame ``t`` of ``N`` becomes
``clip(exp(a_t) I_t, 0, 1)``, ``a_t = gain_log * t / (N - 1)``, rounded to 8 bits (a camera
whose gain rises smoothly, as auto-exposure does). Depth, events, poses and the sharp frames
are copied unchanged, so the sharp frames stay at the first frame's exposure, which is the
map's brightness that the protocol scores against.

It checks whether a method's per-frame exposure compensation (and a prior on it,
``budget.lambda_exposure_prior``) still follows a real change of exposure
(``benchmarks/sweeps/exposure_prior.yaml``). The built-in sequences have none.

    python benchmarks/make_gain_sequence.py data/demo-blur data/demo-blur-gain --gain-log 0.3
"""

from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

import numpy as np
from PIL import Image

from egs_bench.fileio import atomic_dir


def apply_gain_ramp(source: Path, target: Path, gain_log: float) -> list[float]:
    """Write ``target``, a copy of the sequence folder ``source`` with the gain ramp applied to
    ``rgb/*.png``; returns ``a_t`` per frame (natural log of the gain)."""
    frames = sorted((source / "rgb").glob("*.png"))
    if not frames:
        raise SystemExit(f"error: {source}/rgb: no PNG frames")
    logs = [gain_log * t / max(len(frames) - 1, 1) for t in range(len(frames))]
    with atomic_dir(target) as staging:
        shutil.copytree(source, staging)
        for a, frame in zip(logs, frames, strict=True):
            ldr = np.asarray(Image.open(frame)).astype(np.float64) / 255.0
            gained = np.round(np.clip(np.exp(a) * ldr, 0.0, 1.0) * 255.0).astype(np.uint8)
            Image.fromarray(gained).save(staging / "rgb" / frame.name)
        meta = (staging / "meta.yaml").read_text()
        name = f"name: {source.name}\n"
        if meta.startswith(name):
            meta = f"name: {target.name}\n" + meta[len(name):]
        (staging / "meta.yaml").write_text(meta)
    return logs


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("source", type=Path, help="sequence folder to copy")
    parser.add_argument("target", type=Path, help="new sequence folder (must not exist)")
    parser.add_argument("--gain-log", type=float, default=0.3,
                        help="log gain of the last frame (0.3: exp(0.3) = 1.35x brighter)")
    args = parser.parse_args(argv)
    if args.target.exists():
        print(f"error: {args.target}: exists; give a new folder", file=sys.stderr)
        return 2
    logs = apply_gain_ramp(args.source, args.target, args.gain_log)
    print(f"{args.target}: {len(logs)} frames, log gain 0 to {logs[-1]:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
