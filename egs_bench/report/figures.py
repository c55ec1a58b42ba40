"""The report's own figures (PNG, matplotlib's object API): curves of several runs on one
sequence, and a run's timing. The top view and the image strip reuse
:mod:`egs_bench.eval.figures`; a single run's ATE curve reuses :mod:`egs_bench.eval.plots`.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from egs_bench.eval.ate import AteResult
from egs_bench.eval.plots import save_figure

_AXES = "xyz"


def plot_trajectory_axes(results: Sequence[tuple[str, AteResult]], path: Path) -> Path:
    """Aligned positions per world axis against time, one colour per run, ground truth dashed.

    Args:
        results: ``(label, ate)`` per run on one sequence (time in seconds since the first
            ground-truth pose, positions in metres).
        path: output PNG.
    """
    if not results:
        raise ValueError("no trajectories to plot")
    ref = max((r for _, r in results), key=lambda r: len(r.gt_positions))
    t0 = float(ref.timestamps[0])
    fig = Figure(figsize=(7, 5.2), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    for k, ax in enumerate(axes):
        for i, (label, ate) in enumerate(results):
            ax.plot(ate.timestamps - t0, ate.est_positions[:, k], lw=1.3, color=f"C{i}",
                    label=label)
        ax.plot(ref.timestamps - t0, ref.gt_positions[:, k], "--", color="black", lw=1.0,
                label="ground truth")
        ax.set_ylabel(f"{_AXES[k]} [m]")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="best", fontsize=7)
    axes[-1].set_xlabel("time [s]")
    return save_figure(fig, path)


def plot_curves(curves: Sequence[tuple[str, np.ndarray, np.ndarray]], path: Path, *,
                xlabel: str, ylabel: str, title: str = "", markers: bool = False) -> Path:
    """Several runs' values over time or frames on one plot.

    Args:
        curves: ``(label, x [N], y [N])`` per run.
        path: output PNG.
        markers: draw the points (for sparse samples such as every 5th frame's PSNR).
    """
    fig = Figure(figsize=(7, 2.8), layout="constrained")
    ax = fig.add_subplot()
    for i, (label, x, y) in enumerate(curves):
        ax.plot(x, y, lw=1.2, color=f"C{i}", label=label, marker="o" if markers else None,
                ms=3)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(alpha=0.3)
    if curves:
        ax.legend(loc="best", fontsize=7)
    if title:
        ax.set_title(title, fontsize=9)
    return save_figure(fig, path)


def plot_run_timing(per_frame_s: np.ndarray, iterations: Sequence[int] | None,
                    keyframes: Sequence[int], divergent: Sequence[int], path: Path) -> Path:
    """A run's wall time per frame [s] (keyframes marked, divergences as red lines) and, when
    known, its tracking iterations per frame on a second axis.

    Args:
        per_frame_s: wall time of each processed frame, [N] seconds.
        iterations: tracking iterations of each frame, [N] (``None``: not recorded).
        keyframes: frame indices of the keyframes.
        divergent: frame indices where tracking diverged.
        path: output PNG.
    """
    frames = np.arange(len(per_frame_s))
    fig = Figure(figsize=(7, 2.8), layout="constrained")
    ax = fig.add_subplot()
    ax.plot(frames, per_frame_s, lw=1.2, color="C0", label="wall time per frame")
    kf = [k for k in keyframes if 0 <= k < len(per_frame_s)]
    if kf:
        ax.plot(kf, per_frame_s[kf], "v", color="C0", ms=5, label="keyframe")
    for i, k in enumerate(divergent):
        ax.axvline(k, color="C3", lw=1, ls=":", label="tracking diverged" if i == 0 else None)
    ax.set_xlabel("frame")
    ax.set_ylabel("wall time [s]")
    ax.grid(alpha=0.3)
    # Frame 0 builds the map and can take many times a tracked frame: scale the axis to the
    # frames after it, and name frame 0's time when it is off the scale.
    if len(per_frame_s) > 1:
        top = 1.15 * float(np.max(per_frame_s[1:]))
        if float(per_frame_s[0]) > top > 0:
            ax.set_ylim(0, top)
            ax.annotate(f"frame 0 (map initialisation): {float(per_frame_s[0]):.1f} s",
                        (0, top), xytext=(4, -12), textcoords="offset points", fontsize=7)
    handles, labels = ax.get_legend_handles_labels()
    if iterations is not None and len(iterations) == len(per_frame_s):
        twin = ax.twinx()
        twin.plot(frames, iterations, lw=1.0, color="C1", label="tracking iterations")
        twin.set_ylabel("tracking iterations")
        more_h, more_l = twin.get_legend_handles_labels()
        handles, labels = handles + more_h, labels + more_l
    ax.legend(handles, labels, loc="best", fontsize=7)
    return save_figure(fig, path)
