"""The demos. :func:`run_demo` is the end-to-end demo behind ``make demo``: data -> EGS-SLAM and
the MonoGS-style baseline -> evaluation -> leaderboard, plots, a side-by-side figure and the
HTML report (``<out>/report/``), on a built-in blurred sequence. :func:`render_demo` is
``egs-bench render-demo``: one synthetic RGB-D view turned into a Gaussian map and rendered, the
render example of docs/guide/other-systems.md and a quick visual check.

The default shows what the method is for: ``demo-blur`` (24 frames of ``demo-fast``'s strong
blur) processed at its own 224x128 with the cpu budget (at half resolution the blur shrinks by
half and the deblurring gain with it; docs/notes/slam.md).

Re-running resumes: the generated sequence and finished runs are reused; the demo's own
unfinished runs (failed, interrupted) are run again and its frame panel is rewritten. A
finished run made with another seed or other settings (an earlier version's preset) is kept
and the demo stops, naming it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from egs_bench.geometry import Intrinsics

if TYPE_CHECKING:
    from egs_bench.render.gaussian_map import GaussianMap
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
        OutputError: a finished run in ``out`` was made with another seed or other settings
            than this code's ``preset`` and ``options`` give (it is kept; give another
            ``out``).
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
    from egs_bench.runs.locations import run_location
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
        run_dir = run_location(out, seq.name, method.name)
        finished = RunFolder.is_run_folder(run_dir) and \
            RunFolder.open(run_dir).read_status().state == "done"
        if isinstance(method, ConfiguredSlamMethod) and options:
            method = method.with_options(options)
        if finished:
            record = RunFolder.open(run_dir).read_config()
            run_seed = record.get("seed")
            if run_seed != seed:
                raise OutputError(run_dir, f"is a finished demo run with seed {run_seed}, not "
                                           f"{seed}; give another --out to keep both")
            changed = _changed_settings(record, method, preset, seq.meta)
            if changed:
                raise OutputError(run_dir, f"is a finished demo run made with other settings "
                                           f"({changed}), e.g. an earlier version's preset; "
                                           f"give another --out to keep both")
            say(f"      {name}: reusing finished run {run_dir}")
        else:
            extra: dict = {"overwrite": True} if supports_overwrite(method) else {}
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


def _changed_settings(record: dict, method: object, preset: str,
                      meta: dict | None) -> str:
    """The settings in which a finished run's ``config.yaml`` (``record``) differs from what
    ``method`` would run now with ``preset`` on a sequence with ``meta``: a few dotted keys,
    ``""`` when they agree or the method has no SLAM configuration to compare."""
    from egs_bench.eval.results import flatten
    from egs_bench.report.config_diff import config_rows
    from egs_bench.slam.methods import ConfiguredSlamMethod

    if not isinstance(method, ConfiguredSlamMethod):
        return ""
    now = flatten({"slam": method.config(preset, dict(meta or {})).to_dict()})
    stored = {"slam": record.get("slam") or {}}
    changed = [row.key for row in config_rows(stored, now) if row.changed]
    changed += sorted(set(now) - set(flatten(stored)))  # fields the run does not record
    if record.get("preset") != preset:
        changed.insert(0, "preset")
    shown = ", ".join(changed[:3])
    return shown + (f" and {len(changed) - 3} more" if len(changed) > 3 else "")


def synthetic_rgbd(width: int = 224, height: int = 128) -> tuple[np.ndarray, np.ndarray,
                                                                   Intrinsics]:
    """Ray-cast a box room (floor, back and side walls, checker/stripe textures) with a sphere,
    seen from the origin looking down +z (OpenCV axes).

    Returns: linear RGB [H, W, 3] float32 in [0, 1], depth [H, W] float32 metres, intrinsics.
    """
    intr = Intrinsics(0.8 * width, 0.8 * width, width / 2, height / 2, width, height)
    v, u = np.mgrid[0:height, 0:width].astype(np.float64)
    d = np.stack([(u + 0.5 - intr.cx) / intr.fx, (v + 0.5 - intr.cy) / intr.fy,
                  np.ones_like(u)], -1)  # ray directions with z = 1
    best = np.full((height, width), np.inf)
    rgb = np.zeros((height, width, 3))

    def plane(axis: int, value: float, colour_fn: Callable[[np.ndarray], np.ndarray]) -> None:
        with np.errstate(divide="ignore", invalid="ignore"):
            t = value / d[..., axis]
        hit = (t > 0) & (t < best)
        p = d * t[..., None]
        best[hit] = t[hit]
        rgb[hit] = colour_fn(p[hit])

    def checker(p: np.ndarray, a: int, b: int, c0: tuple[float, float, float],
                c1: tuple[float, float, float]) -> np.ndarray:
        k = (np.floor(p[:, a] * 2) + np.floor(p[:, b] * 2)) % 2
        return np.where(k[:, None] > 0, np.array(c0), np.array(c1))

    plane(2, 4.0, lambda p: checker(p, 0, 1, (0.75, 0.7, 0.6), (0.25, 0.3, 0.45)))  # back
    plane(1, 1.0, lambda p: checker(p, 0, 2, (0.8, 0.8, 0.8), (0.1, 0.1, 0.1)))  # floor
    plane(0, -2.0, lambda p: np.where(((p[:, 1] * 3) % 1 < 0.5)[:, None],
                                      np.array((0.7, 0.2, 0.2)), np.array((0.9, 0.8, 0.3))))
    plane(0, 2.0, lambda p: np.tile(np.array((0.2, 0.6, 0.3)), (p.shape[0], 1)))  # right wall
    # sphere of radius 0.6 at (0.3, 0.3, 2.5), shaded by a light from the upper left
    centre, radius = np.array([0.3, 0.3, 2.5]), 0.6
    b = (d * centre).sum(-1)
    dd = (d * d).sum(-1)
    disc = b * b - dd * (centre @ centre - radius**2)
    t = np.where(disc > 0, (b - np.sqrt(np.maximum(disc, 0))) / dd, np.inf)
    hit = (t > 0) & (t < best)
    n = (d[hit] * t[hit, None] - centre) / radius
    shade = 0.25 + 0.75 * np.clip(n @ np.array([-0.5, -0.6, -0.6]), 0, 1)
    rgb[hit] = shade[:, None] * np.array([0.2, 0.45, 0.9])
    best[hit] = t[hit]
    depth = np.where(np.isfinite(best), best, 0.0)  # t is z because ray z = 1
    return rgb.astype(np.float32), depth.astype(np.float32), intr


def render_demo(out_png: str | Path, width: int = 224, height: int = 128, downsample: int = 2,
                seed: int = 0) -> GaussianMap:
    """Build a map from :func:`synthetic_rgbd` (one view, ``add_from_depth``), render it from the
    same pose and from a pose moved 0.3 m right and turned 8 degrees, and save
    ``[input | render | depth | novel view]`` as an 8-bit sRGB PNG. Returns the map."""
    import matplotlib
    import torch

    from egs_bench.color import linear_to_srgb8, to_uint8
    from egs_bench.images import write_ldr_image
    from egs_bench.render.gaussian_map import GaussianMap
    from egs_bench.render.rasterize import rasterize

    rgb, depth, intr = synthetic_rgbd(width, height)
    gmap = GaussianMap.empty()
    gmap.add_from_depth(rgb, depth, intr, np.eye(4), downsample=downsample, point_size=0.5,
                        opacity=0.9, generator=torch.Generator().manual_seed(seed))
    a = np.radians(8.0)
    T_wc = np.eye(4)
    T_wc[:3, :3] = [[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]]
    T_wc[0, 3] = 0.3
    viewmats = torch.tensor(np.stack([np.eye(4), np.linalg.inv(T_wc)]), dtype=torch.float32)
    Ks = torch.tensor(intr.K, dtype=torch.float32).expand(2, 3, 3)
    with torch.no_grad():
        out = rasterize(gmap.means, gmap.quats, gmap.scales, gmap.opacities, gmap.colors,
                        viewmats, Ks, width, height)

    dep = out.expected_depth[0].numpy()
    cmap = matplotlib.colormaps["viridis"]
    dep_rgb = to_uint8(cmap(np.clip(dep / max(depth.max(), 1e-6), 0, 1))[..., :3])
    dep_rgb[out.alpha[0].numpy() < 0.5] = 0
    gap = np.full((height, 4, 3), 255, np.uint8)
    panel = np.concatenate([linear_to_srgb8(rgb), gap, linear_to_srgb8(out.rgb[0].numpy()), gap,
                            dep_rgb, gap, linear_to_srgb8(out.rgb[1].numpy())], axis=1)
    write_ldr_image(out_png, panel)
    return gmap
