"""Comparison figures across methods: trajectories on one plot, a qualitative grid with zoomed
crops and per-image PSNR. PNG, PDF or SVG (chosen by the file suffix).

:func:`plot_comparison_grid` works on plain images and is meant to be reused (e.g. for a demo
figure)::

    from egs_bench.eval.figures import Panel, plot_comparison_grid

    rows = [[Panel("observed", blurred), Panel("egs", render_a), Panel("monogs", render_b),
             Panel("sharp GT", sharp)]]                       # uint8 [H, W, 3] each
    plot_comparison_grid(rows, "grid.pdf", crops=[(40, 30, 32, 24)], row_labels=["frame 20"])

Each image gets the crop rectangles drawn on it and, under it, the crops enlarged side by side
(border colours match the rectangles); every panel except the reference (the last one of a row
by default) is labelled with its PSNR against the reference (the protocol's masked PSNR).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from egs_bench.errors import ConfigError, InputError
from egs_bench.eval.ate import AteResult
from egs_bench.eval.plots import save_figure, top_view_axes

if TYPE_CHECKING:
    from egs_bench.runs.folder import RunFolder

CROP_COLORS = ("#e41a1c", "#377eb8", "#4daf4a", "#ff7f00")
_GAP = 4  # px between an image and its crop strip


@dataclass(frozen=True)
class Panel:
    """One image of the grid: a column title and an 8-bit sRGB image, uint8 [H, W, 3]."""

    title: str
    image: np.ndarray


def plot_trajectories(results: Sequence[tuple[str, AteResult]], path: str | Path,
                      title: str = "") -> Path:
    """Several methods' aligned trajectories over the ground truth, top view.

    Args:
        results: ``(label, ate)`` per method on one sequence (each estimate aligned to the
            ground truth by its own ATE alignment, as ``evo_traj --ref GT -a``).
        path: ``.png``, ``.pdf`` or ``.svg``.
    """
    if not results:
        raise ValueError("no trajectories to plot")
    gt = max((r for _, r in results), key=lambda r: len(r.gt_positions)).gt_positions
    a, b = top_view_axes(gt)
    names = "xyz"
    fig = Figure(figsize=(6, 5))
    ax = fig.add_subplot()
    for i, (label, ate) in enumerate(results):
        ax.plot(ate.est_positions[:, a], ate.est_positions[:, b], lw=1.6, color=f"C{i}",
                label=f"{label} (ATE {100 * ate.rmse:.2f} cm)", zorder=2)
    # ground truth last and dashed: stays visible where an estimate lies on it
    ax.plot(gt[:, a], gt[:, b], "--", color="black", lw=1.2, label="ground truth", zorder=3)
    ax.plot(gt[0, a], gt[0, b], "o", color="black", ms=4, zorder=3, label="start")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel(f"{names[a]} [m]")
    ax.set_ylabel(f"{names[b]} [m]")
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    if title:
        ax.set_title(title)
    return save_figure(fig, Path(path))


def _check_crops(crops: Sequence[tuple[int, int, int, int]], w: int, h: int) -> None:
    if len(crops) > len(CROP_COLORS):
        raise ConfigError(f"at most {len(CROP_COLORS)} crops")
    for x, y, cw, ch in crops:
        if cw < 1 or ch < 1 or x < 0 or y < 0 or x + cw > w or y + ch > h:
            raise ConfigError(f"crop {x},{y},{cw},{ch} (x,y,w,h) is outside the {w}x{h} image")


def detail_crops(image: np.ndarray, n: int = 2, size: tuple[int, int] | None = None
                 ) -> list[tuple[int, int, int, int]]:
    """``n`` non-overlapping boxes ``(x, y, w, h)`` where ``image`` (uint8 [H, W, 3], e.g. the
    sharp ground truth) has the most detail (sum of squared gradients of its grey values), so
    zoomed crops show fine structure; chosen from the reference alone, not from the methods'
    renders. ``size`` defaults to a fifth of the width by a quarter of the height."""
    import cv2

    h, w = image.shape[:2]
    cw, ch = size or (max(4, w // 5), max(4, h // 4))
    grey = image.astype(np.float32).mean(-1)
    energy = cv2.Sobel(grey, cv2.CV_32F, 1, 0) ** 2 + cv2.Sobel(grey, cv2.CV_32F, 0, 1) ** 2
    box_sum = cv2.boxFilter(energy, -1, (cw, ch), normalize=False, anchor=(0, 0),
                            borderType=cv2.BORDER_CONSTANT)[: h - ch + 1, : w - cw + 1]
    crops: list[tuple[int, int, int, int]] = []
    free = np.ones_like(box_sum, dtype=bool)
    for _ in range(n):
        if not free.any():
            break
        y, x = np.unravel_index(np.argmax(np.where(free, box_sum, -np.inf)), box_sum.shape)
        crops.append((int(x), int(y), cw, ch))
        # no later box may overlap this one
        free[max(0, y - ch + 1): y + ch, max(0, x - cw + 1): x + cw] = False
    return crops


def crop_strip(image: np.ndarray, crops: Sequence[tuple[int, int, int, int]]) -> np.ndarray:
    """The crops of ``image`` enlarged (nearest neighbour, so pixels stay visible) side by side
    across the image's width, at most half its height, each with a 2-px border in its colour;
    uint8 [h_strip, W, 3]."""
    import cv2

    h, w = image.shape[:2]
    slot = w // len(crops)
    tiles = []
    for i, (x, y, cw, ch) in enumerate(crops):
        scale = min((slot - 4) / cw, (h // 2 - 4) / ch)
        size = (max(1, round(cw * scale)), max(1, round(ch * scale)))
        tile = cv2.resize(np.ascontiguousarray(image[y:y + ch, x:x + cw]), size,
                          interpolation=cv2.INTER_NEAREST)
        color = np.array([int(CROP_COLORS[i][k:k + 2], 16) for k in (1, 3, 5)], np.uint8)
        tile = np.pad(tile, ((2, 2), (2, 2), (0, 0)))
        tile[:2], tile[-2:], tile[:, :2], tile[:, -2:] = color, color, color, color
        tiles.append(tile)
    strip = np.full((max(t.shape[0] for t in tiles), w, 3), 255, np.uint8)
    for i, t in enumerate(tiles):
        x0 = i * slot + (slot - t.shape[1]) // 2
        strip[:t.shape[0], x0:x0 + t.shape[1]] = t
    return strip


def plot_comparison_grid(rows: Sequence[Sequence[Panel]], path: str | Path, *,
                         crops: Sequence[tuple[int, int, int, int]] = (),
                         reference_index: int | None = -1,
                         row_labels: Sequence[str] | None = None, title: str = "") -> Path:
    """Qualitative grid: one row per frame, one column per panel, zoomed crops, per-image PSNR.

    Args:
        rows: per frame the panels (same count and image size everywhere).
        path: ``.png``, ``.pdf`` or ``.svg``.
        crops: boxes ``(x, y, w, h)`` in pixels, drawn on every image and enlarged under it.
        reference_index: the panel every other one is compared with (PSNR in its title);
            ``None`` for no PSNR.
        row_labels: one label per row (e.g. ``"frame 20"``).
    """
    from egs_bench.eval.image_metrics import psnr_masked

    if not rows or not rows[0]:
        raise ValueError("no images to plot")
    n_cols = len(rows[0])
    h, w = rows[0][0].image.shape[:2]
    for row in rows:
        if len(row) != n_cols or any(p.image.shape != (h, w, 3) or p.image.dtype != np.uint8
                                     for p in row):
            raise ValueError(f"every row needs {n_cols} uint8 images of {w}x{h}x3")
    _check_crops(crops, w, h)
    strips = [[crop_strip(p.image, crops) if crops else None for p in row] for row in rows]
    first = strips[0][0]
    strip_h = first.shape[0] + _GAP if first is not None else 0
    total_h = h + strip_h
    scale = 2.6 / w
    fig = Figure(figsize=(n_cols * w * scale + 0.4, len(rows) * (total_h * scale + 0.5)),
                 layout="constrained")
    axes = fig.subplots(len(rows), n_cols, squeeze=False)
    for r, row in enumerate(rows):
        ref = row[reference_index].image if reference_index is not None else None
        for c, panel in enumerate(row):
            ax = axes[r][c]
            canvas = np.full((total_h, w, 3), 255, np.uint8)
            canvas[:h] = panel.image
            if crops:
                canvas[h + _GAP:] = strips[r][c]
            ax.imshow(canvas, interpolation="nearest")
            for i, (x, y, cw, ch) in enumerate(crops):
                ax.add_patch(Rectangle((x - 0.5, y - 0.5), cw, ch, fill=False, lw=1.2,
                                       edgecolor=CROP_COLORS[i]))
            ax.set_xticks([])
            ax.set_yticks([])
            for spine in ax.spines.values():
                spine.set_visible(False)
            label = panel.title
            if reference_index is not None and ref is not None \
                    and c != reference_index % n_cols:
                label += f"\nPSNR {psnr_masked(panel.image, ref):.2f} dB"
            ax.set_title(label, fontsize=8)
            if c == 0 and row_labels is not None:
                ax.set_ylabel(row_labels[r], fontsize=8)
    if title:
        fig.suptitle(title, fontsize=10)
    return save_figure(fig, Path(path))


# ------------------------------------------------------------------------- from run folders
def trajectory_figure(run_dirs: Sequence[str | Path], path: str | Path,
                      protocol: str = "egs", labels: Sequence[str] | None = None) -> Path:
    """:func:`plot_trajectories` for run folders of one sequence (ATE under ``protocol``).

    Raises:
        InputError: a run is unreadable, or the runs are on different sequences.
    """
    from egs_bench.eval.evaluate import compute_run_ate, open_sequence
    from egs_bench.eval.protocols import get_protocol
    from egs_bench.runs.folder import RunFolder

    proto = get_protocol(protocol)
    runs = [RunFolder.open(p) for p in run_dirs]
    if not runs:
        raise ConfigError("give at least one run folder")
    _same_sequence(runs)
    seq = open_sequence(runs[0].sequence_path) if runs[0].sequence_path is not None else None
    results = [(labels[i] if labels else r.method, compute_run_ate(r, proto, seq))
               for i, r in enumerate(runs)]
    return plot_trajectories(results, path, f"{runs[0].sequence_name}: estimates aligned to the "
                                            "ground truth")


def _same_sequence(runs: Sequence[RunFolder]) -> None:
    names = {r.sequence_name for r in runs}
    if len(names) > 1:
        raise InputError(runs[-1].path, f"runs are on different sequences "
                                        f"({', '.join(sorted(names))}); give runs of one")


def qualitative_figure(run_dirs: Sequence[str | Path], path: str | Path, frames: Sequence[int],
                       crops: Sequence[tuple[int, int, int, int]] = (), protocol: str = "egs",
                       labels: Sequence[str] | None = None, observed: bool = True) -> Path:
    """:func:`plot_comparison_grid` for run folders of one sequence: per frame the observed
    image, each run's render and the protocol's reference image (sharp ground truth for
    ``egs``, the observed frame for ``monogs``), with PSNR against that reference.

    Raises:
        InputError: unreadable runs, different sequences, a frame without a render.
    """
    from egs_bench.eval.evaluate import open_sequence
    from egs_bench.eval.protocols import get_protocol
    from egs_bench.runs.folder import RunFolder

    proto = get_protocol(protocol)
    runs = [RunFolder.open(p) for p in run_dirs]
    if not runs:
        raise ConfigError("give at least one run folder")
    _same_sequence(runs)
    if runs[0].sequence_path is None:
        raise InputError(runs[0].path, "has no sequence folder: no reference images")
    seq = open_sequence(runs[0].sequence_path)
    rows, row_labels = [], []
    for f in frames:
        if not 0 <= f < len(seq):
            raise InputError(seq.path, f"frame {f} outside the sequence (0..{len(seq) - 1})")
        ref = seq.sharp(f) if proto.reference_images == "sharp" else seq.rgb(f)
        if ref is None:
            raise InputError(seq.path, f"has no sharp ground truth for frame {f}")
        panels = [Panel("observed", seq.rgb(f))] if observed else []
        panels += [Panel(labels[i] if labels else r.method, r.read_render(f))
                   for i, r in enumerate(runs)]
        panels.append(Panel("sharp GT" if proto.reference_images == "sharp" else "reference",
                            ref))
        rows.append(panels)
        row_labels.append(f"frame {f}")
    return plot_comparison_grid(rows, path, crops=crops, row_labels=row_labels,
                                title=runs[0].sequence_name)
