"""A sequence's page: its facts (``egs-bench info``), every method's trajectory against the
ground truth (top view and per axis), ATE and PSNR over time, and an image strip at chosen
frames (observed, each method's render, the reference; zoomed crops; PSNR).

Each leaderboard row (a method with one set of settings) is drawn by one representative run:
its evaluated run with the lowest seed.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from egs_bench.eval.leaderboard import Leaderboard
from egs_bench.eval.results import EVALUATED
from egs_bench.report.assets import STRIP_WIDTH, AssetStore
from egs_bench.report.collect import ReportData, RunRecord
from egs_bench.report.sources import RunSources

#: Frames of the image strip when none are chosen.
STRIP_FRAMES = 3
#: Methods (leaderboard rows) in the image strip; a wider sweep shows its first rows.
STRIP_METHODS = 6
#: Longest column title of the image strip (longer row labels are cut, with an ellipsis).
STRIP_TITLE_CHARS = 36


@dataclass(frozen=True)
class Picture:
    """An image of a page: its caption and its path relative to the report folder."""

    caption: str
    src: str


@dataclass
class SequencePage:
    """What a sequence page shows (``page``: file stem under ``sequences/``; ``view``: the data
    of its 3D view, whose trajectories ``view_labels`` name)."""

    name: str
    page: str
    facts: list[tuple[str, str]] = field(default_factory=list)
    figures: list[Picture] = field(default_factory=list)
    strip: Picture | None = None
    frames: list[int] = field(default_factory=list)
    runs: list[RunRecord] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    view: dict[str, Any] | None = None
    view_labels: list[str] = field(default_factory=list)


def representatives(board: Leaderboard, sequence: str, records: dict[str, RunRecord]
                    ) -> list[tuple[str, RunRecord]]:
    """``(row label, run)`` per leaderboard row with an evaluated run on ``sequence``."""
    out = []
    for row in board.rows:
        cell = board.cells.get((row, sequence))
        evaluated = [r for r in cell.runs if r.status in EVALUATED] if cell else []
        if evaluated:
            out.append((row.label, records[str(evaluated[0].path)]))
    return out


def pick_frames(available: Sequence[int], wanted: Sequence[int] | None,
                count: int = STRIP_FRAMES) -> tuple[list[int], list[int]]:
    """The strip's frames: ``wanted`` ones that are ``available`` (all runs rendered them),
    or ``count`` evenly spaced available frames; also returns the wanted frames left out."""
    avail = sorted(set(available))
    if wanted:
        return [f for f in wanted if f in avail], [f for f in wanted if f not in avail]
    if not avail:
        return [], []
    picks = np.linspace(0, len(avail) - 1, min(count, len(avail))).round().astype(int)
    return [avail[i] for i in sorted(set(picks.tolist()))], []


def short_title(label: str, limit: int = STRIP_TITLE_CHARS) -> str:
    """``label`` cut to ``limit`` characters with an ellipsis (titles share a narrow column)."""
    return label if len(label) <= limit else label[:limit - 1] + "…"


def _facts(summary: dict[str, Any], page_dir: Path | None = None) -> list[tuple[str, str]]:
    """The summary's items as page facts; its ``path`` relative to ``page_dir`` (a shared
    report names no folder of the machine that wrote it), left out without one."""
    def text(value: Any) -> str:
        if isinstance(value, dict):
            return ", ".join(f"{k}={v}" for k, v in value.items())
        return str(value)

    items = dict(summary)
    if "path" in items:
        path = items.pop("path")
        if page_dir is not None:
            items = {"path": Path(os.path.relpath(Path(path).resolve(),
                                                  page_dir.resolve())).as_posix(), **items}
    return [(key.replace("_", " "), text(value)) for key, value in items.items()]


def build_sequence_page(name: str, page_name: str, data: ReportData, sources: RunSources,
                        store: AssetStore, frames: Sequence[int] | None = None,
                        page_dir: Path | None = None) -> SequencePage:
    """Compute the figures of sequence ``name`` into ``store`` and return the content of its
    page ``sequences/<page_name>.html`` (``page_dir``: where that page will finally live; the
    sequence folder's path is shown relative to it)."""
    from egs_bench.datasets.inspect import sequence_summary
    from egs_bench.eval.figures import Panel, detail_crops, plot_comparison_grid, plot_trajectories
    from egs_bench.report.figures import plot_curves, plot_trajectory_axes
    from egs_bench.report.viewer import sequence_view
    from egs_bench.runs.folder import RunFolder

    page = SequencePage(name, page_name)
    page.runs = [r for r in data.runs if r.result.sequence == name]
    board = data.boards[data.protocols[0]]
    records = {str(r.result.path): r for r in data.runs}
    reps = representatives(board, name, records)
    seq = next((s for s in (sources.sequence(r) for r in page.runs) if s is not None), None)
    if seq is None:
        page.notes.append("sequence folder not available: no facts and no image strip")
    else:
        try:
            page.facts = _facts(sequence_summary(seq), page_dir)
        except Exception as exc:
            page.notes.append(f"{seq.path}: sequence facts not computed ({exc})")
    ates = [(label, ate) for label, r in reps if (ate := sources.ate(r)) is not None]
    page.view = sequence_view([r for _, r in reps], [label for label, _ in reps], sources)
    if page.view is not None:
        page.view_labels = [run["label"] for run in page.view["runs"]]
    if ates:
        page.figures.append(Picture("Trajectories, top view (each aligned to the ground truth)",
                                    store.figure(lambda p: plot_trajectories(ates, p))))
        page.figures.append(Picture("Positions per axis against time",
                                    store.figure(lambda p: plot_trajectory_axes(ates, p))))
        curves = [(label, a.timestamps - a.timestamps[0], 100 * a.errors) for label, a in ates]
        page.figures.append(Picture("ATE over time", store.figure(lambda p: plot_curves(
            curves, p, xlabel="time [s]", ylabel="position error [cm]"))))
    psnr = []
    for label, r in reps:
        rendering = (r.metrics.rendering if r.metrics is not None else None) or {}
        per_frame = rendering.get("per_frame") or {}
        if per_frame.get("frame") and per_frame.get("psnr_db"):
            psnr.append((label, np.asarray(per_frame["frame"]),
                         np.asarray(per_frame["psnr_db"], dtype=float)))
    if psnr:
        page.figures.append(Picture(f"PSNR over time (protocol {data.protocols[0]})",
                                    store.figure(lambda p: plot_curves(
                                        psnr, p, xlabel="frame", ylabel="PSNR [dB]",
                                        markers=True))))
    strip_reps = reps[:STRIP_METHODS]
    if len(reps) > len(strip_reps):
        page.notes.append(f"the image strip shows the first {len(strip_reps)} of the "
                          f"{len(reps)} leaderboard rows")
    if seq is not None and strip_reps:
        rendered = [set(RunFolder.open(r.result.path).render_indices()) for _, r in strip_reps]
        common = sorted(set.intersection(*rendered) & set(range(len(seq))))
        page.frames, missing = pick_frames(common, frames)
        if missing:
            page.notes.append("frames without a render of every method, left out of the strip: "
                              + ", ".join(map(str, missing)))
        sharp = sources.protocol.reference_images == "sharp"
        ref_of = seq.sharp if sharp else seq.rgb
        if page.frames and ref_of(page.frames[0]) is not None:
            rows = [[Panel("observed", seq.rgb(f))]
                    + [Panel(short_title(label), RunFolder.open(r.result.path).read_render(f))
                       for label, r in strip_reps]
                    + [Panel("sharp GT" if sharp else "reference", ref_of(f))]
                    for f in page.frames]
            crops = detail_crops(rows[0][-1].image, n=2)
            page.strip = Picture(
                "Observed frame, each method's render and the reference, with zoomed crops "
                "and PSNR against the reference",
                store.figure(lambda p: plot_comparison_grid(
                    rows, p, crops=crops, row_labels=[f"frame {f}" for f in page.frames]),
                    max_width=STRIP_WIDTH))
    for r in page.runs:
        for where in (str(r.result.path), str(sources.sequence_path(r))):
            page.notes += [n for n in sources.notes.get(where, []) if n not in page.notes]
    return page
