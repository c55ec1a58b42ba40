"""Headless plots of a run: trajectory top view, ATE over time, qualitative image grid.

Uses matplotlib's object-oriented ``Figure`` API (no pyplot, no global style changes, no
display needed). Files are written atomically as PNG.
"""

from __future__ import annotations

from collections.abc import Sequence as Seq
from pathlib import Path

import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure

from egs_bench.errors import ConfigError, InputError
from egs_bench.eval.ate import AteResult
from egs_bench.fileio import atomic_path

FIGURE_FORMATS = ("png", "pdf", "svg")


def save_figure(fig: Figure, path: Path) -> Path:
    """Write ``fig`` atomically in the format of the path's suffix (png, pdf or svg).

    Raises:
        ConfigError: another suffix.
        InputError: ``path`` is a folder.
    """
    fmt = path.suffix.lower().lstrip(".")
    if fmt not in FIGURE_FORMATS:
        raise ConfigError(f"{path}: figures are written as {', '.join(FIGURE_FORMATS)} "
                          "(choose the file suffix)")
    if path.is_dir():
        raise InputError(path, "is a folder; expected a file name")
    import matplotlib

    # SVG text as text (searchable, editable in a paper's figure), not as glyph outlines
    with atomic_path(path) as tmp, matplotlib.rc_context({"svg.fonttype": "none"}):
        fig.savefig(tmp, format=fmt, dpi=150 if fmt == "png" else None, bbox_inches="tight")
    return path


def _save(fig: Figure, path: Path) -> Path:
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=120, bbox_inches="tight")
    return path


def top_view_axes(gt_positions: np.ndarray) -> tuple[int, int]:
    """The two world axes with the largest spread of the ground truth (the 'top view' plane)."""
    spread = np.ptp(gt_positions, axis=0)
    a, b = sorted(np.argsort(spread)[::-1][:2])
    return int(a), int(b)


def plot_trajectory_top_view(ate: AteResult, path: str | Path, title: str = "") -> Path:
    """Aligned estimate coloured by its position error over the dashed ground truth.

    Args:
        ate: result of :func:`~egs_bench.eval.ate.compute_ate` (aligned, associated positions).
        path: output PNG.
    """
    a, b = top_view_axes(ate.gt_positions)
    names = "xyz"
    fig = Figure(figsize=(6, 5))
    ax = fig.add_subplot()
    ax.plot(ate.gt_positions[:, a], ate.gt_positions[:, b], "--", color="0.4", lw=1,
            label="ground truth")
    pts = ate.est_positions[:, [a, b]]
    segments = np.stack([pts[:-1], pts[1:]], axis=1)
    err_cm = 100 * ate.errors
    lines = LineCollection(list(segments), cmap="viridis", lw=2, label="estimate (aligned)")
    lines.set_array(0.5 * (err_cm[:-1] + err_cm[1:]))
    ax.add_collection(lines)
    ax.autoscale()
    ax.set_aspect("equal", adjustable="datalim")
    fig.colorbar(lines, ax=ax, label="position error [cm]")
    ax.set_xlabel(f"{names[a]} [m]")
    ax.set_ylabel(f"{names[b]} [m]")
    ax.set_title(title or f"ATE RMSE {100 * ate.rmse:.2f} cm ({ate.alignment})")
    ax.legend(loc="best", fontsize=8)
    return _save(fig, Path(path))


def plot_ate_over_time(ate: AteResult, path: str | Path, title: str = "") -> Path:
    """Per-pose position error [cm] against time since the first associated pose."""
    fig = Figure(figsize=(7, 3))
    ax = fig.add_subplot()
    t = ate.timestamps - ate.timestamps[0]
    ax.plot(t, 100 * ate.errors, lw=1)
    ax.axhline(100 * ate.rmse, color="C3", ls="--", lw=1, label=f"RMSE {100 * ate.rmse:.2f} cm")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("position error [cm]")
    ax.set_title(title or "ATE over time")
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)
    return _save(fig, Path(path))


def plot_qualitative_grid(rows: Seq[tuple[int, Seq[np.ndarray | None]]], column_titles: Seq[str],
                          path: str | Path, title: str = "") -> Path:
    """Grid of images: one row per frame, one column per source (e.g. observed/render/sharp).

    Args:
        rows: ``(frame_index, images)``; each image uint8 [H, W, 3] or ``None`` (left blank).
        column_titles: one title per column.
        path: output PNG.
    """
    if not rows:
        raise ValueError("no frames to plot")
    n_rows, n_cols = len(rows), len(column_titles)
    h, w = next(img.shape[:2] for _, imgs in rows for img in imgs if img is not None)
    scale = 3.0 / max(w, 1)
    fig = Figure(figsize=(n_cols * w * scale, n_rows * h * scale + 0.4))
    axes = fig.subplots(n_rows, n_cols, squeeze=False)
    for r, (frame, images) in enumerate(rows):
        for c, img in enumerate(images):
            ax = axes[r][c]
            ax.set_xticks([])
            ax.set_yticks([])
            if img is not None:
                ax.imshow(img)
            if r == 0:
                ax.set_title(column_titles[c], fontsize=9)
            if c == 0:
                ax.set_ylabel(f"frame {frame}", fontsize=9)
    if title:
        fig.suptitle(title)
    return _save(fig, Path(path))


def plot_run(run_dir: str | Path, protocol: str = "egs",
             frames: Seq[int] | None = None) -> list[Path]:
    """Write ``plots/trajectory_top.png``, ``plots/ate_over_time.png`` and (with renders and a
    sequence) ``plots/qualitative.png`` for a run; returns the written paths.

    Args:
        run_dir: a finished run folder.
        protocol: protocol whose ATE settings are used.
        frames: frames of the qualitative grid (default: up to 3 rendered frames spread over the
            sequence).

    Raises:
        InputError: the run or its files are bad (e.g. a requested frame has no render).
    """
    from egs_bench.eval.evaluate import compute_run_ate, open_sequence
    from egs_bench.eval.protocols import get_protocol
    from egs_bench.runs.folder import PLOT_FILES, RunFolder

    proto = get_protocol(protocol)
    run = RunFolder.open(run_dir)
    status = run.read_status()
    if status.state != "done" and not (status.state == "interrupted"
                                       and run.trajectory_path.is_file()):
        raise InputError(run.path, f"run is {status.state}"
                                   + (f" ({status.reason})" if status.reason else "")
                                   + "; nothing to plot")
    seq = open_sequence(run.sequence_path) if run.sequence_path is not None else None
    ate = compute_run_ate(run, proto, seq)
    label = f"{run.method} on {run.sequence_name}"
    top, over_time, grid = (run.plots_dir / name for name in PLOT_FILES)
    # every input is read before the first plot is written: bad input leaves no partial set
    rows: list[tuple[int, list[np.ndarray | None]]] = []
    rendered = run.render_indices()
    if seq is not None and rendered:
        if frames is None:
            picks = np.linspace(0, len(rendered) - 1, min(3, len(rendered))).round().astype(int)
            frames = [rendered[i] for i in sorted(set(picks.tolist()))]
        for f in frames:
            if not 0 <= f < len(seq):
                raise InputError(seq.path, f"frame {f} outside the sequence (0..{len(seq) - 1})")
            rows.append((f, [seq.rgb(f), run.read_render(f), seq.sharp(f)]))
    out = [
        plot_trajectory_top_view(ate, top, f"{label}: ATE RMSE {100 * ate.rmse:.2f} cm"),
        plot_ate_over_time(ate, over_time, f"{label}: ATE over time"),
    ]
    if rows:
        out.append(plot_qualitative_grid(rows, ["observed (blurred)", run.method, "sharp GT"],
                                         grid, label))
    return out
