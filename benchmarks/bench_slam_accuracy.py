"""Accuracy benchmark: EGS-SLAM vs the MonoGS-style baseline and the ablations, side by side.

Runs every method on every sequence with one preset and seed, evaluates each run with the
default protocol (``egs_bench.eval.evaluate.evaluate_run``), and prints / writes one table
(ATE RMSE in cm, PSNR / SSIM against the sharp ground truth, FPS) plus the ratios the issue
asks for (ATE egs / monogs, PSNR egs - monogs).

    python benchmarks/bench_slam_accuracy.py --seq SEQ [--seq SEQ2 ...] [--preset cpu]
        [--methods egs,monogs,egs-no-events,...] [--max-frames N] [--out bench_out/slam]

Sequences are folders or names under $EGS_BENCH_DATA (built-in synthetic names are generated
on first use).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd

from egs_bench.eval.evaluate import evaluate_run
from egs_bench.slam.methods import BUILTIN, get_method
from egs_bench.slam.runner import resolve_sequence

DEFAULT_METHODS = ["monogs", "egs-no-events", "egs-no-event-mapping", "egs-no-event-tracking",
                   "egs-no-crf", "egs-no-ne-loss", "egs"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seq", action="append", required=True, help="sequence folder or name")
    ap.add_argument("--methods", default=",".join(DEFAULT_METHODS))
    ap.add_argument("--preset", default="cpu", choices=["cpu", "paper"])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--max-frames", type=int, default=None)
    ap.add_argument("--out", type=Path, default=Path("bench_out/slam"))
    args = ap.parse_args()

    rows = []
    for name in args.seq:
        seq = resolve_sequence(name)
        for method in args.methods.split(","):
            m = get_method(method) if method not in BUILTIN else BUILTIN[method]
            run_dir = args.out / seq.name / method
            try:
                m.run(seq, run_dir, preset=args.preset, device=args.device, seed=args.seed,
                      max_frames=args.max_frames, progress=True)
                met = evaluate_run(run_dir)
            except Exception as exc:  # one failed run must not hide the others
                rows.append({"sequence": seq.name, "method": method, "error": str(exc)[:80]})
                continue
            r = met.get("rendering") or {}
            rows.append({
                "sequence": seq.name, "method": method,
                "ate_cm": 100 * met["ate"]["rmse_m"] if met.get("ate") else None,
                "psnr_db": r.get("psnr_db"), "ssim": r.get("ssim"),
                "fps": (met.get("speed") or {}).get("fps"),
            })
    df = pd.DataFrame(rows)
    args.out.mkdir(parents=True, exist_ok=True)
    df.to_csv(args.out / "accuracy.csv", index=False)
    print(df.to_markdown(index=False, floatfmt=".3f"))
    if {"egs", "monogs"} <= set(df["method"]) and "ate_cm" in df:
        piv = df.pivot(index="sequence", columns="method", values=["ate_cm", "psnr_db"])
        ratio = (piv["ate_cm"]["egs"] / piv["ate_cm"]["monogs"]).mean()
        gain = (piv["psnr_db"]["egs"] - piv["psnr_db"]["monogs"]).mean()
        print(f"\nmean ATE(egs)/ATE(monogs) = {ratio:.3f}; mean PSNR(egs) - PSNR(monogs) = "
              f"{gain:+.2f} dB  (preset {args.preset}, seed {args.seed})")
    (args.out / "accuracy.md").write_text(df.to_markdown(index=False, floatfmt=".3f") + "\n")


if __name__ == "__main__":
    main()
