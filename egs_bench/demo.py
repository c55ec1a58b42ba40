"""The end-to-end demo behind ``make demo``: data -> EGS-SLAM and the MonoGS-style baseline ->
evaluation -> leaderboard, plots, a side-by-side figure and the HTML report (``<out>/report/``),
on a built-in blurred sequence.

The default shows what the method is for: ``demo-blur`` (24 frames of ``demo-fast``'s strong
blur) processed at its own 224x128 with the cpu budget (at half resolution the blur shrinks by
half and the deblurring gain with it; docs/notes/slam.md).

Re-running resumes: the generated sequence and finished runs are reused; the demo's own
unfinished runs (failed, interrupted) are run again and its frame panel is rewritten.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from egs_bench.report import ReportResult

DEMO_SEQUENCE = "demo-blur"
DEMO_METHODS = ("egs", "monogs")
DEMO_PRESET = "cpu"
# Budget overrides of the demo (none: the cpu preset as a user gets it).
DEMO_OPTIONS: dict[str, object] = {}


@dataclass
class DemoResult:
    """Where the demo wrote things."""

    sequence: Path
    panel: Path
    runs: dict[str, Path] = field(default_factory=dict)
    comparison: Path | None = None
    plots: dict[str, list[Path]] = field(default_factory=dict)
    leaderboard_md: str = ""
    report: ReportResult | None = None


def run_demo(out: str | Path, *, sequence: str = DEMO_SEQUENCE,
             methods: tuple[str, ...] = DEMO_METHODS, preset: str = DEMO_PRESET,
             options: dict | None = None, seed: int = 0,
             say: Callable[[str], None] = print, progress: bool = True) -> DemoResult:
    """Generate (or reuse) ``sequence``, run ``methods`` on it, evaluate, plot and rank them.

    Args:
        out: demo output folder (runs under ``out/runs/<sequence>/<method>``, a frame panel).
        sequence: sequence name or path (built-in names are generated on first use).
        methods: registered method names.
        preset: SLAM configuration preset (compute budget).
        options: configuration overrides of built-in methods (default :data:`DEMO_OPTIONS`
            for the default sequence, none otherwise).
        seed: the SLAM runs' seed (insertion subsampling, random mapping views); the sequence
            is the same for every seed.
        say: where progress messages go.
        progress: show progress bars.

    Raises:
        OutputError: a finished run in ``out`` was made with another seed (it is kept; give
            another ``out``).
    """
    from egs_bench.datasets.inspect import save_frame_panel, sequence_summary
    from egs_bench.datasets.registry import load_sequence
    from egs_bench.errors import OutputError
    from egs_bench.eval.evaluate import evaluate_run
    from egs_bench.eval.figures import detail_crops, qualitative_figure
    from egs_bench.eval.leaderboard import leaderboard
    from egs_bench.eval.plots import plot_run
    from egs_bench.outputs import prepare_output
    from egs_bench.runs.folder import RunFolder
    from egs_bench.runs.registry import get_method, supports_overwrite
    from egs_bench.slam.methods import ConfiguredSlamMethod

    out = Path(out)
    if options is None:
        options = DEMO_OPTIONS if sequence == DEMO_SEQUENCE else {}
    say(f"[1/4] sequence {sequence!r} (generated on first use)")
    seq = load_sequence(sequence, progress=progress)
    # the demo rewrites its own panel and re-runs its own unfinished runs, nothing else
    panel_path = prepare_output(out / f"{seq.name}_frame.png", "png", overwrite=True,
                                inputs=[seq.path])
    summary = sequence_summary(seq)
    say("      " + ", ".join(f"{k}={summary[k]}" for k in (
        "frames", "resolution", "exposure_ms", "events", "blur_extent_px_mean") if k in summary))
    panel = save_frame_panel(seq, len(seq) // 2, panel_path)
    result = DemoResult(sequence=seq.path, panel=panel)

    settings = "".join(f", {k}={v}" for k, v in options.items())
    say(f"[2/4] running {', '.join(methods)} (preset {preset}, seed {seed}{settings})")
    for name in methods:
        method = get_method(name)
        run_dir = out / "runs" / seq.name / method.name
        finished = RunFolder.is_run_folder(run_dir) and \
            RunFolder.open(run_dir).read_status().state == "done"
        if finished:
            run_seed = RunFolder.open(run_dir).read_config().get("seed")
            if run_seed != seed:
                raise OutputError(run_dir, f"is a finished demo run with seed {run_seed}, not "
                                           f"{seed}; give another --out to keep both")
            say(f"      {name}: reusing finished run {run_dir}")
        else:
            extra: dict = {"overwrite": True} if supports_overwrite(method) else {}
            if options and isinstance(method, ConfiguredSlamMethod):
                method = method.with_options(options)
            method.run(seq, run_dir, preset=preset, device="cpu", seed=seed, max_frames=None,
                       progress=progress, **extra)
        result.runs[name] = run_dir

    say("[3/4] evaluating (protocol egs: ATE on all frames, renders vs sharp GT)")
    for name, run_dir in result.runs.items():
        evaluate_run(run_dir)
        result.plots[name] = plot_run(run_dir)

    say("[4/4] leaderboard and side-by-side comparison")
    result.leaderboard_md = leaderboard(out / "runs", fmt="md")
    say(result.leaderboard_md)
    frames = [len(seq) // 3, (2 * len(seq)) // 3]
    reference = seq.sharp(frames[0])
    if result.runs and reference is not None:
        crops = detail_crops(reference, n=2)
        path = prepare_output(out / f"{seq.name}_comparison.png", "figure", overwrite=True,
                              inputs=[seq.path])
        result.comparison = qualitative_figure(list(result.runs.values()), path, frames, crops)
        say(f"comparison (observed | renders | sharp GT, zoomed crops, PSNR vs sharp GT): "
            f"{result.comparison}")
    from egs_bench.report import SIDE_REPORT_DIR, write_side_report

    result.report = write_side_report(out / "runs", out / SIDE_REPORT_DIR, say)
    say(f"frame panel: {panel}")
    for name, paths in result.plots.items():
        say(f"plots ({name}): " + ", ".join(str(p) for p in paths))
    return result
