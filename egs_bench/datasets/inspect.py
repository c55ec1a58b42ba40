"""Summaries and pictures of a sequence (``egs-bench info`` / ``egs-bench show``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import cv2
import numpy as np

from egs_bench.color import to_uint8
from egs_bench.datasets.pipeline import LatentFrame, max_flow_px
from egs_bench.datasets.sequence import Sequence
from egs_bench.fileio import atomic_path


def blur_extent_px(seq: Sequence, i: int) -> float | None:
    """Largest pixel motion of the scene during frame ``i``'s exposure, from ground truth.

    Uses the dense ground-truth trajectory for the pose at exposure start and the depth at
    exposure end. None when the sequence has no dense trajectory covering the exposure.
    """
    dense = seq.dense_trajectory
    if dense is None:
        return None
    from egs_bench.geometry import interpolate_trajectory

    t0, t1 = seq.exposure(i)
    ts = dense.timestamps
    if t0 * 1e-6 < ts[0] - 1e-6 or t1 * 1e-6 > ts[-1] + 1e-6:
        return None
    start = interpolate_trajectory(ts, dense.poses, np.array([max(t0 * 1e-6, ts[0])]))[0]
    depth = seq.depth(i)
    a = LatentFrame(rgb=np.zeros(0), depth=depth, pose=seq.poses[i])
    b = LatentFrame(rgb=np.zeros(0), depth=depth, pose=start)
    return max_flow_px(a, b, seq.intrinsics)


def sharpness_ratio(observed: np.ndarray, sharp: np.ndarray) -> float:
    """Variance of the Laplacian of the observed frame over that of the sharp one (1 = no blur)."""
    def lap_var(img: np.ndarray) -> float:
        gray = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY).astype(np.float64)
        return float(cv2.Laplacian(gray, cv2.CV_64F).var())

    return lap_var(observed) / max(lap_var(sharp), 1e-12)


def sequence_summary(seq: Sequence, max_frames_for_blur: int = 20) -> dict[str, Any]:
    """Key facts of a sequence: frames, duration, resolution, intrinsics, events, exposure, blur.

    Blur measures are averaged over up to ``max_frames_for_blur`` evenly spaced frames.
    """
    n = len(seq)
    duration_s = (seq.t_end_us[-1] - seq.t_start_us[0]) * 1e-6
    picks = np.unique(np.linspace(0, n - 1, min(n, max_frames_for_blur)).astype(int))
    extents = [e for e in (blur_extent_px(seq, int(i)) for i in picks) if e is not None]
    sharp = {int(i): seq.sharp(int(i)) for i in picks} if seq.has_sharp else {}
    ratios = [sharpness_ratio(seq.rgb(i), img) for i, img in sharp.items() if img is not None]
    summary: dict[str, Any] = {
        "name": seq.name,
        "path": str(seq.path),
        "frames": n,
        "duration_s": round(float(duration_s), 4),
        "frame_rate_hz": round(float(seq.meta.get("frame_rate") or 0.0), 3),
        "resolution": f"{seq.width}x{seq.height}",
        "intrinsics": {k: round(float(seq.meta[k]), 4) for k in ("fx", "fy", "cx", "cy")},
        "exposure_ms": seq.exposure_us / 1000.0,
        "has_sharp_gt": seq.has_sharp,
        # a real recording's meta.yaml has no thresholds: the reader's default is no fact about it
        "event_thresholds": ({"pos": seq.pos_threshold, "neg": seq.neg_threshold}
                             if "event_thresholds" in seq.meta else "not recorded"),
        "eps": seq.eps,
        "crf": (seq.meta.get("crf") or {}).get("description", "unknown"),
    }
    if seq.has_events:
        count = len(seq.events)
        summary["events"] = count
        summary["event_rate_mev_s"] = round(count / max(duration_s, 1e-9) / 1e6, 4)
        in_exposure = sum(len(seq.events.window(*seq.exposure(int(i)))) for i in picks)
        summary["events_per_exposure"] = int(in_exposure / len(picks))
    if extents:
        summary["blur_extent_px_mean"] = round(float(np.mean(extents)), 2)
        summary["blur_extent_px_max"] = round(float(np.max(extents)), 2)
    if ratios:
        summary["sharpness_ratio_mean"] = round(float(np.mean(ratios)), 3)
    return summary


def event_map_image(counts: np.ndarray) -> np.ndarray:
    """Signed event counts [H, W] -> uint8 RGB [H, W, 3]: white background, positive red,
    negative blue, saturation at the 99th percentile of |count|."""
    scale = max(float(np.percentile(np.abs(counts[counts != 0]), 99)), 1.0) \
        if (counts != 0).any() else 1.0
    level = np.clip(np.abs(counts) / scale, 0.0, 1.0)
    img = np.ones((*counts.shape, 3))
    pos, neg = counts > 0, counts < 0
    img[pos, 1] -= level[pos]
    img[pos, 2] -= level[pos]
    img[neg, 0] -= level[neg]
    img[neg, 1] -= level[neg]
    return to_uint8(img)


def save_frame_panel(seq: Sequence, i: int, out: str | Path) -> Path:
    """Write a 2x2 PNG panel for frame ``i``: observed, sharp GT, depth, exposure event map."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if not 0 <= i < len(seq):
        raise IndexError(f"frame {i} out of range (sequence has {len(seq)} frames)")
    out = Path(out)
    fig, axes = plt.subplots(2, 2, figsize=(10, 10 * seq.height / seq.width + 0.8))
    t0, t1 = seq.exposure(i)
    axes[0, 0].imshow(seq.rgb(i))
    axes[0, 0].set_title(f"observed frame {i} (exposure {(t1 - t0) / 1000:.1f} ms)")
    sharp = seq.sharp(i)
    if sharp is not None:
        axes[0, 1].imshow(sharp)
        axes[0, 1].set_title("sharp ground truth (exposure end)")
    else:
        axes[0, 1].set_title("no sharp ground truth")
    depth = seq.depth(i)
    shown = axes[1, 0].imshow(np.where(depth > 0, depth, np.nan), cmap="turbo")
    axes[1, 0].set_title("depth (m)")
    fig.colorbar(shown, ax=axes[1, 0], fraction=0.046, pad=0.02)
    if seq.has_events:
        counts = seq.event_maps(i)[0]
        axes[1, 1].imshow(event_map_image(counts))
        axes[1, 1].set_title(f"events in exposure: {int(np.abs(counts).sum())} "
                             "(red +, blue -)")
    else:
        axes[1, 1].set_title("no events")
    for ax in axes.flat:
        ax.set_xticks([])
        ax.set_yticks([])
    fig.suptitle(f"{seq.name}")
    fig.tight_layout()
    with atomic_path(out) as tmp:
        fig.savefig(tmp, format="png", dpi=100)
    plt.close(fig)
    return out
