"""CLI commands of the evaluation area: eval, ate, compare-images, leaderboard, plot, import-run.

Thin wrappers: each parses its options and calls a library function in ``egs_bench.eval``.
"""

from __future__ import annotations

from pathlib import Path

import typer
from rich.console import Console
from rich.table import Table

from egs_bench.cli.app import app
from egs_bench.eval.protocols import DEFAULT_PROTOCOL

_out = Console(highlight=False, soft_wrap=True)


def _fmt(value: float | None, digits: int) -> str:
    return "--" if value is None else f"{value:.{digits}f}"


@app.command("eval")
def eval_cmd(
    run_dir: Path = typer.Argument(..., help="Run folder to evaluate (see docs: run folder)."),
    protocol: str = typer.Option(DEFAULT_PROTOCOL, "--protocol", "-p",
                                 help="Evaluation protocol: egs (default) or monogs."),
) -> None:
    """Score a run (ATE, PSNR, SSIM, LPIPS, FPS) and write RUN_DIR/metrics.json."""
    from egs_bench.eval.evaluate import evaluate_run

    m = evaluate_run(run_dir, protocol, write=True, progress=True)
    table = Table(title=f"{m['run']['method']} on {m['run']['sequence']} "
                        f"(protocol {m['protocol']['name']})")
    for col in ("ATE RMSE (cm)", "PSNR (dB)", "SSIM", "LPIPS", "frames", "FPS"):
        table.add_column(col, justify="right")
    ate, rnd, spd = m["ate"], m["rendering"] or {}, m["speed"] or {}
    table.add_row(_fmt(100 * ate["rmse_m"], 2), _fmt(rnd.get("psnr_db"), 2),
                  _fmt(rnd.get("ssim"), 3), _fmt(rnd.get("lpips"), 3),
                  str(rnd.get("n_frames", "--")), _fmt(spd.get("fps"), 2))
    _out.print(table)
    for note in m["notes"]:
        _out.print(f"note: {note}")
    _out.print(f"wrote {Path(run_dir) / 'metrics.json'}")


@app.command("ate")
def ate_cmd(
    estimate: Path = typer.Argument(..., help="Estimated trajectory, TUM format."),
    groundtruth: Path = typer.Argument(..., help="Ground-truth trajectory, TUM format."),
    align: str = typer.Option("se3", "--align", "-a", help="Alignment: se3, sim3 or none."),
    max_diff: float = typer.Option(0.01, "--max-diff",
                                   help="Timestamp association tolerance in seconds."),
) -> None:
    """ATE (translation, after alignment) of two TUM files, computed with evo."""
    from egs_bench.eval.ate import ate_from_files

    r = ate_from_files(estimate, groundtruth, align=align, max_diff_s=max_diff)
    table = Table(title=f"ATE ({r.alignment} alignment, {r.n_matched} poses matched within "
                        f"{r.max_diff_s} s)")
    for col in ("rmse", "mean", "median", "std", "min", "max"):
        table.add_column(f"{col} (m)", justify="right")
    table.add_row(*(f"{v:.6f}" for v in (r.rmse, r.mean, r.median, r.std, r.min, r.max)))
    _out.print(table)
    if r.alignment == "sim3":
        _out.print(f"scale: {r.scale:.6f}")


@app.command("compare-images")
def compare_images_cmd(
    image_a: Path = typer.Argument(..., help="First image (e.g. a render), 8-bit RGB."),
    image_b: Path = typer.Argument(..., help="Second image (the reference), 8-bit RGB."),
    lpips_net: str = typer.Option("alex", "--lpips-net", help="LPIPS backbone: alex or vgg."),
) -> None:
    """PSNR (full and masked), SSIM (3DGS and standard) and LPIPS of two images."""
    from egs_bench.eval.compare import compare_image_files

    result = compare_image_files(image_a, image_b, lpips_net=lpips_net)
    table = Table(title=f"{image_a.name} vs {image_b.name}")
    table.add_column("metric")
    table.add_column("value", justify="right")
    for key, value in result.items():
        table.add_row(key, f"{value:.6f}")
    _out.print(table)


@app.command("leaderboard")
def leaderboard_cmd(
    runs_root: Path = typer.Argument(..., help="Folder searched recursively for run folders."),
    fmt: str = typer.Option("md", "--format", "-f",
                            help="Output format: md, latex, csv (one row per run, units in the "
                                 "column names) or csv-summary (mean/std per method, settings "
                                 "and sequence)."),
    by: str = typer.Option("sequence", "--by",
                           help="Column groups: sequence (rows = methods) or method."),
    protocol: str = typer.Option(DEFAULT_PROTOCOL, "--protocol", "-p",
                                 help="Protocol of the numbers (runs are evaluated if needed)."),
    metrics: str = typer.Option("ate,psnr,ssim,lpips", "--metrics",
                                help="Comma-separated metrics: ate, psnr, ssim, lpips, fps."),
    no_eval: bool = typer.Option(False, "--no-eval",
                                 help="Do not evaluate runs that lack metrics.json."),
    output: Path | None = typer.Option(None, "--output", "-o",
                                       help="Write the table to this file instead of stdout."),
    caption: str | None = typer.Option(None, "--caption", help="LaTeX caption."),
    label: str | None = typer.Option(None, "--label",
                                     help="LaTeX label (default tab:<RUNS_ROOT name>)."),
    width: str = typer.Option("auto", "--width",
                              help="LaTeX width: auto, natural, column (shrink to the column) "
                                   "or page (table* shrunk to the text width)."),
) -> None:
    """Leaderboard of all runs under RUNS_ROOT: mean ± std over seeds, best bold, second
    underlined."""
    from egs_bench.eval.leaderboard import leaderboard
    from egs_bench.fileio import write_text_atomic

    text = leaderboard(runs_root, fmt=fmt, by=by, protocol=protocol,
                       metrics=[m.strip() for m in metrics.split(",") if m.strip()],
                       evaluate_missing=not no_eval, caption=caption, label=label,
                       width=width)
    if output is not None:
        write_text_atomic(output, text)
        _out.print(f"wrote {output}")
    else:
        typer.echo(text, nl=False)


@app.command("plot")
def plot_cmd(
    run_dir: Path = typer.Argument(..., help="Run folder; plots go to RUN_DIR/plots/."),
    protocol: str = typer.Option(DEFAULT_PROTOCOL, "--protocol", "-p",
                                 help="Protocol whose ATE settings are used."),
    frames: str | None = typer.Option(None, "--frames",
                                      help="Comma-separated frame indices of the image grid."),
) -> None:
    """Trajectory top view (error-coloured), ATE over time and a qualitative image grid."""
    from egs_bench.errors import ConfigError
    from egs_bench.eval.plots import plot_run

    picked = None
    if frames:
        try:
            picked = [int(f) for f in frames.split(",") if f.strip()]
        except ValueError:
            raise ConfigError(f"--frames must be comma-separated integers, got {frames!r}") \
                from None
    for path in plot_run(run_dir, protocol, picked):
        _out.print(f"wrote {path}")


@app.command("import-run")
def import_run_cmd(
    estimate: Path = typer.Argument(..., help="External estimate, TUM format."),
    out_dir: Path = typer.Argument(..., help="Run folder to create."),
    method: str = typer.Option(..., "--method", "-m", help="Method name for leaderboards."),
    sequence: str = typer.Option(..., "--sequence", "-s",
                                 help="Sequence name for leaderboards."),
    sequence_path: Path | None = typer.Option(None, "--sequence-path",
                                              help="Canonical sequence folder (GT + images)."),
    groundtruth: Path | None = typer.Option(None, "--groundtruth",
                                            help="Ground-truth TUM file (no sequence folder)."),
    renders: Path | None = typer.Option(None, "--renders",
                                        help="Folder of renders named <frame index>.png."),
    overwrite: bool = typer.Option(False, "--overwrite", help="Replace an existing run folder."),
) -> None:
    """Import an external system's trajectory (and renders) as a finished run folder."""
    from egs_bench.baselines.import_runs import import_tum_run

    run = import_tum_run(estimate, out_dir, method=method, sequence_name=sequence,
                         sequence_path=sequence_path, groundtruth=groundtruth,
                         renders_dir=renders, overwrite=overwrite)
    _out.print(f"imported {method} on {sequence} into {run.path}")
