"""Throughput of the ESIM event simulator on a moving photographic texture.

Input: scikit-image's ``brick`` texture (sRGB, linearised), translated by a sub-pixel amount per
sample (bilinear warp), converted to ``log(luma + eps)``; 448x256 by default, one sample per
millisecond. Only :meth:`EventSimulator.step` is timed (frame synthesis is excluded); numba
compilation is done before timing. Wall and CPU time are both recorded. Each configuration
is run ``--repeats`` times interleaved
with the others and the median is reported, since the machine may be shared.

Usage: ``python benchmarks/bench_esim.py [--samples 400] [--repeats 3]``
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Iterator

import cv2
import numpy as np
from skimage import data
from tabulate import tabulate

from egs_bench.datasets.esim import EventSimConfig, EventSimulator

CONFIGS = {
    "theta=0.25 (default)": EventSimConfig(),
    "theta=0.10": EventSimConfig(pos_threshold=0.1, neg_threshold=0.1),
    "theta=0.10, sigma=0.03, refr=100us, noise=1Hz": EventSimConfig(
        pos_threshold=0.1, neg_threshold=0.1, sigma=0.03, refractory_us=100, noise_rate_hz=1.0
    ),
}


def srgb_to_linear(srgb01: np.ndarray) -> np.ndarray:
    """sRGB EOTF (IEC 61966-2-1) on values in [0, 1]."""
    return np.where(srgb01 <= 0.04045, srgb01 / 12.92, ((srgb01 + 0.055) / 1.055) ** 2.4)


def moving_texture(
    n: int, height: int, width: int, eps: float, velocity_px: tuple[float, float]
) -> Iterator[np.ndarray]:
    """Yield ``n`` [height, width] float64 log-brightness frames of a translating texture."""
    tex = srgb_to_linear(data.brick().astype(np.float64) / 255.0).astype(np.float32)
    reps = (int(np.ceil((height + n * abs(velocity_px[1])) / tex.shape[0])) + 2,
            int(np.ceil((width + n * abs(velocity_px[0])) / tex.shape[1])) + 2)
    big = np.tile(tex, reps)
    for k in range(n):
        shift = np.array([[1.0, 0.0, -k * velocity_px[0]], [0.0, 1.0, -k * velocity_px[1]]])
        if velocity_px[0] < 0:
            shift[0, 2] += big.shape[1] - width
        if velocity_px[1] < 0:
            shift[1, 2] += big.shape[0] - height
        frame = cv2.warpAffine(big, shift, (width, height), flags=cv2.INTER_LINEAR)
        yield np.log(frame.astype(np.float64) + eps)


def run_once(
    config: EventSimConfig, frames: list[np.ndarray], times: np.ndarray
) -> tuple[float, float, int]:
    """Wall and CPU seconds spent in ``step`` over all frames, and the number of events."""
    h, w = frames[0].shape
    sim = EventSimulator(config, h, w)
    sim.reset(frames[0], int(times[0]))
    wall = cpu = 0.0
    n_events = 0
    for frame, t in zip(frames[1:], times[1:], strict=True):
        w0, c0 = time.perf_counter(), time.process_time()
        ev = sim.step(frame, int(t))
        wall += time.perf_counter() - w0
        cpu += time.process_time() - c0
        n_events += len(ev)
    return wall, cpu, n_events


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=400, help="number of samples")
    parser.add_argument("--repeats", type=int, default=3, help="runs per configuration")
    parser.add_argument("--width", type=int, default=448)
    parser.add_argument("--height", type=int, default=256)
    parser.add_argument("--speed", type=float, default=1.0, help="texture motion, px/sample")
    args = parser.parse_args()

    eps = 1e-3
    velocity = (args.speed, 0.35 * args.speed)
    # float32 storage keeps the input small (400 x 448 x 256 x 4 B = 184 MB); the simulator
    # converts each sample to float64.
    frames = [f.astype(np.float32) for f in moving_texture(
        args.samples, args.height, args.width, eps, velocity)]
    times = np.arange(args.samples, dtype=np.int64) * 1000  # 1 kHz sampling
    run_once(EventSimConfig(), frames[:3], times[:3])  # compile / load the numba cache

    results: dict[str, list[tuple[float, float, int]]] = {name: [] for name in CONFIGS}
    for _ in range(args.repeats):
        for name, config in CONFIGS.items():
            results[name].append(run_once(config, frames, times))

    steps = args.samples - 1
    rows = []
    for name, runs in results.items():
        wall = statistics.median(r[0] for r in runs)
        cpu = statistics.median(r[1] for r in runs)
        n_events = runs[0][2]
        rows.append([
            name, f"{n_events / steps:,.0f}", f"{1e3 * wall / steps:.2f}",
            f"{1e3 * cpu / steps:.2f}", f"{steps / cpu:,.0f}", f"{n_events / cpu / 1e6:.1f}",
        ])
    print(f"ESIM step() throughput, {args.width}x{args.height}, {args.samples} samples, "
          f"texture speed {args.speed} px/sample, median of {args.repeats} runs")
    print("(samples/s and Mevents/s from CPU time, which is less affected by other load; "
          "the code is single-threaded)")
    print(tabulate(rows, headers=["config", "events/sample", "wall ms/sample", "CPU ms/sample",
                                  "samples/s", "Mevents/s"], tablefmt="github"))


if __name__ == "__main__":
    main()
