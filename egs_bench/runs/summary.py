"""A run folder in a few lines: what ran, how it ended, what it cost (``egs-bench info RUN``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from egs_bench.runs.folder import RunFolder, read_json_object

STATS_FILE = "slam_stats.json"


def _millions(value: float | None) -> str:
    return "n/a" if value is None else f"{value / 1e6:.2f} M"


def work_lines(work: dict[str, Any]) -> dict[str, str]:
    """The ``work`` section of ``slam_stats.json`` as labelled lines: the mean per frame
    after frame 0, and each phase's total."""
    mean = work.get("per_frame_after_init") or {}
    lines = {"work per frame after frame 0":
             f"{mean.get('cameras') or 0:.1f} cameras, {_millions(mean.get('pixels'))} pixels, "
             f"{_millions(mean.get('blends_fwd'))} blends forward, "
             f"{_millions(mean.get('blends_bwd'))} backward"}
    for phase, counts in (work.get("by_phase") or {}).items():
        if counts.get("calls"):
            lines[f"work in {phase}"] = (f"{counts['cameras']} cameras, "
                                         f"{_millions(counts['pixels'])} pixels, "
                                         f"{_millions(counts.get('blends_fwd'))} blends forward")
    return lines


def run_summary(path: str | Path) -> dict[str, str]:
    """Labelled lines describing the run folder at ``path``: method, sequence, state,
    frames, map, speed (compile and frame-0 time apart) and the rendering work.

    Raises:
        InputError: ``path`` is not a readable run folder.
    """
    run = RunFolder.open(path)
    status = run.read_status()
    out = {"method": run.method, "sequence": run.sequence_name, "state": status.state}
    config = run.read_config()
    for key in ("preset", "device", "seed", "frames"):
        if key in config:
            out[key] = str(config[key])
    stats_path = run.path / STATS_FILE
    stats = read_json_object(stats_path) if stats_path.is_file() else {}
    if stats:
        out["map"] = (f"{stats.get('gaussians')} Gaussians, {stats.get('keyframes')} keyframes, "
                      f"{len(stats.get('divergences') or [])} divergence(s)")
    timing = run.read_timing()
    if timing is not None:
        parts = [f"{timing.fps:.3f} FPS over {len(timing.per_frame_s)} frames"]
        if timing.fps_after_init is not None:
            parts.append(f"{timing.fps_after_init:.3f} after frame 0")
        if timing.init_s is not None:
            parts.append(f"frame 0 (map initialisation) {timing.init_s:.1f} s")
        if timing.compile_s is not None:
            parts.append(f"kernels {timing.compile_s:.1f} s before the loop")
        out["speed"] = ", ".join(parts)
    if isinstance(stats.get("work"), dict):
        out.update(work_lines(stats["work"]))
    return out
