"""EDI benchmark: time per frame and sharpness gain of :mod:`egs_bench.baselines.edi`.

For each sequence: per frame the EDI wall time (threshold search included), the chosen ``c``,
and PSNR against the sharp ground truth of the blurred frame, of EDI with the searched ``c`` and
of EDI with the sequence's true threshold; the table gives medians / means over the frames.

    python benchmarks/bench_edi.py [--seq demo-fast] [--full-res-frames 4] [--repeats 3]

``--full-res-frames`` also generates a short 448x256 office sequence with strong blur (speed
1.2, 20 ms exposures) into a temporary folder, the size the issue's speed target names.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from egs_bench.baselines.edi import EdiConfig, deblur_sequence_frame
from egs_bench.datasets.sequence import Sequence
from egs_bench.eval.image_metrics import psnr


def bench(seq: Sequence, repeats: int) -> dict:
    times, cs, events, p_blur, p_edi, p_true = [], [], [], [], [], []
    true_c = EdiConfig(c=seq.pos_threshold)
    for i in range(len(seq)):
        sharp = seq.sharp(i)
        best = np.inf
        for _ in range(repeats):
            t = time.perf_counter()
            image, res = deblur_sequence_frame(seq, i)
            best = min(best, time.perf_counter() - t)
        known, _ = deblur_sequence_frame(seq, i, true_c)
        times.append(best)
        cs.append(res.c if res.c is not None else np.nan)
        events.append(res.n_events)
        p_blur.append(psnr(seq.rgb(i), sharp))
        p_edi.append(psnr(image, sharp))
        p_true.append(psnr(known, sharp))
    return {
        "sequence": seq.name, "size": f"{seq.width}x{seq.height}", "frames": len(seq),
        "events/frame": int(np.mean(events)), "ms/frame (median)": 1000 * np.median(times),
        "ms/frame (max)": 1000 * np.max(times), "c median": np.nanmedian(cs),
        "c range": f"{np.nanmin(cs):.3f}-{np.nanmax(cs):.3f}", "true c": seq.pos_threshold,
        "PSNR blurred": np.mean(p_blur), "PSNR EDI": np.mean(p_edi),
        "PSNR EDI true c": np.mean(p_true),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seq", action="append", default=None, help="sequence folder or name")
    ap.add_argument("--full-res-frames", type=int, default=4)
    ap.add_argument("--repeats", type=int, default=3, help="timing: best of N per frame")
    args = ap.parse_args()
    from egs_bench.slam.runner import resolve_sequence

    rows = [bench(resolve_sequence(name), args.repeats) for name in (args.seq or ["demo-fast"])]
    if args.full_res_frames > 0:
        from egs_bench.datasets.synthetic import make_synthetic

        with tempfile.TemporaryDirectory() as tmp:
            path = make_synthetic("office", Path(tmp) / "office-448-fast",
                                  frames=args.full_res_frames, speed=1.2, seed=7,
                                  progress=False)
            rows.append(bench(Sequence.open(path), args.repeats))
    print(pd.DataFrame(rows).to_markdown(index=False, floatfmt=".3f"))


if __name__ == "__main__":
    main()
