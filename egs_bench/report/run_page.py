"""A run's page: status (with the reason of a flagged run), metrics, timing (FPS, seconds per
frame, tracking iterations, map size), keyframes and divergences, frame thumbnails, the
configuration with the values that differ from the method's preset highlighted, and links to
the run's own files."""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import quote

import numpy as np

from egs_bench.eval.metrics_file import RunMetrics
from egs_bench.report.assets import AssetStore
from egs_bench.report.collect import RunRecord
from egs_bench.report.config_diff import ConfigRow, config_rows, preset_baseline
from egs_bench.report.sequence_page import Picture
from egs_bench.report.sources import RunSources
from egs_bench.runs.summary import work_lines

_DIVERGED = re.compile(r"^frame (\d+):")


@dataclass
class RunPage:
    """What a run page shows."""

    record: RunRecord
    metrics: list[tuple[str, str]] = field(default_factory=list)
    timing: list[tuple[str, str]] = field(default_factory=list)
    divergences: list[str] = field(default_factory=list)
    figures: list[Picture] = field(default_factory=list)
    thumbs: list[tuple[int, list[Picture]]] = field(default_factory=list)
    config: list[ConfigRow] = field(default_factory=list)
    baseline: str = ""
    files: list[tuple[str, str]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


def _fmt(value: Any, digits: int = 4) -> str:
    if isinstance(value, float):
        return f"{value:.{digits}g}"
    return str(value)


def metric_items(metrics: RunMetrics | None) -> list[tuple[str, str]]:
    """The numbers of ``metrics.json``: ATE statistics [cm], rendering means, coverage."""
    if metrics is None:
        return []
    out: list[tuple[str, str]] = []
    ate = metrics.ate
    for key in ("rmse_m", "mean_m", "median_m", "std_m", "max_m"):
        if isinstance(ate.get(key), int | float):
            out.append((f"ATE {key.removesuffix('_m')} [cm]", f"{100 * ate[key]:.2f}"))
    for key in ("n_matched", "alignment", "frames"):
        if key in ate:
            out.append((f"ATE {key.replace('_', ' ')}", _fmt(ate[key])))
    rendering = metrics.rendering or {}
    for key, label in (("psnr_db", "PSNR [dB]"), ("ssim", "SSIM"), ("lpips", "LPIPS"),
                       ("n_frames", "rendered frames scored")):
        if rendering.get(key) is not None:
            out.append((label, _fmt(rendering[key])))
    if metrics.frames_processed is not None:
        out.append(("frames covered",
                    f"{metrics.frames_processed} of {metrics.frames_in_sequence}"))
    return out


def timing_items(record: RunRecord) -> list[tuple[str, str]]:
    """FPS (and after frame 0), wall time, per-frame seconds, compile and initialisation
    time, the rendering work (slam_stats.json's ``work``), map size and keyframes of a run."""
    out: list[tuple[str, str]] = []
    timing, stats = record.timing, record.slam_stats or {}
    if timing is not None:
        out.append(("FPS (SLAM loop)", f"{timing.fps:.3g}"))
        out.append(("wall time [s]", f"{timing.total_wall_s:.1f}"))
        if len(timing.per_frame_s):
            per = timing.per_frame_s
            out.append(("seconds per frame (median, max)",
                        f"{float(np.median(per)):.3g}, {float(per.max()):.3g}"))
        if timing.fps_after_init is not None:
            out.append(("FPS after frame 0", f"{timing.fps_after_init:.3g}"))
        if timing.init_s is not None:
            out.append(("frame 0, map initialisation [s]", f"{timing.init_s:.1f}"))
        if timing.compile_s is not None:
            out.append(("kernels compiled or loaded before the loop [s]",
                        f"{timing.compile_s:.1f}"))
        if timing.render_fps is not None:
            out.append(("render FPS", f"{timing.render_fps:.3g}"))
    if isinstance(stats.get("work"), dict):
        out.extend(work_lines(stats["work"]).items())
    if isinstance(stats.get("gaussians"), int):
        out.append(("map size (Gaussians at the end)", str(stats["gaussians"])))
    if record.keyframes:
        shown = ", ".join(map(str, record.keyframes[:40]))
        more = f" (+{len(record.keyframes) - 40} more)" if len(record.keyframes) > 40 else ""
        out.append((f"keyframes ({len(record.keyframes)})", shown + more))
    return out


def divergent_frames(divergences: Sequence[str]) -> list[int]:
    """Frame indices of ``slam_stats.json``'s ``divergences`` lines (``"frame 12: ..."``)."""
    return [int(m.group(1)) for d in divergences if (m := _DIVERGED.match(d))]


def file_links(record: RunRecord, page_dir: Path) -> list[tuple[str, str]]:
    """``(name, href)`` of the run's own files, relative to the page's final folder."""
    rel = Path(os.path.relpath(record.result.path.resolve(), page_dir.resolve()))
    return [(name, quote((rel / name).as_posix())) for name in record.files]


def build_run_page(record: RunRecord, sources: RunSources, store: AssetStore,
                   frames: Sequence[int], page_dir: Path,
                   baselines: dict[tuple[str, str, str], dict[str, Any] | None]) -> RunPage:
    """Compute the run's figures into ``store`` and return its page content.

    Args:
        frames: the thumbnails' frames (the sequence page's strip).
        page_dir: where the page will finally live (for links to the run's files).
        baselines: cache of :func:`preset_baseline` by (method, preset, sequence folder).
    """
    from egs_bench.eval.plots import plot_ate_over_time
    from egs_bench.report.figures import plot_run_timing
    from egs_bench.runs.folder import RunFolder

    page = RunPage(record, metric_items(record.metrics), timing_items(record))
    stats = record.slam_stats or {}
    divergences = stats.get("divergences")
    page.divergences = [str(d) for d in divergences] if isinstance(divergences, list) else []
    page.files = file_links(record, page_dir)
    page.notes = list(record.problems)
    ate = sources.ate(record)
    if ate is not None:
        page.figures.append(Picture("ATE over time", store.figure(
            lambda p: plot_ate_over_time(ate, p, "position error after alignment"))))
    timing = record.timing
    if timing is not None and len(timing.per_frame_s):
        iterations = stats.get("tracking_iterations")
        iters = iterations if isinstance(iterations, list) and all(
            isinstance(i, int) for i in iterations) else None
        page.figures.append(Picture("Wall time and tracking iterations per frame", store.figure(
            lambda p: plot_run_timing(timing.per_frame_s, iters, record.keyframes,
                                      divergent_frames(page.divergences), p))))
    sizes = stats.get("gaussians_per_frame")
    if isinstance(sizes, list) and sizes and all(isinstance(g, int) for g in sizes):
        from egs_bench.report.figures import plot_curves

        size_curve = [(record.result.method or "map", np.arange(len(sizes)),
                       np.asarray(sizes, dtype=float))]
        page.figures.append(Picture("Map size over time", store.figure(lambda p: plot_curves(
            size_curve, p, xlabel="frame", ylabel="Gaussians"))))
    seq = sources.sequence(record)
    method = record.result.method or ""
    meta = seq.meta if seq is not None else None
    key = (method, record.preset or "", str(sources.sequence_path(record)))
    if key not in baselines:
        baselines[key] = preset_baseline(method, record.preset, meta)
    baseline = baselines[key]
    page.config = config_rows(record.config, baseline)
    page.baseline = (f"highlighted: values that differ from {method}'s {record.preset} preset"
                     if baseline is not None else
                     f"{method or 'this method'} is not a built-in SLAM method: no preset to "
                     "compare with")
    if seq is not None and record.result.status not in ("broken",):
        run = RunFolder.open(record.result.path)
        rendered = set(run.render_indices())
        sharp = sources.protocol.reference_images == "sharp"
        for f in frames:
            if f not in rendered:
                continue
            pics = [Picture("observed", store.image(seq.rgb(f))),
                    Picture(method, store.image(run.read_render(f)))]
            ref = seq.sharp(f) if sharp else None
            if ref is not None:
                pics.append(Picture("sharp GT", store.image(ref)))
            page.thumbs.append((f, pics))
    page.notes += [n for n in sources.notes.get(str(record.result.path), [])
                   if n not in page.notes]
    return page
