"""CLI commands of the evaluation area: eval, ate, rpe, compare-images, leaderboard, plot,
import-run.

Thin wrappers: each parses its options and calls a library function in ``egs_bench.eval``.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import typer
from rich.table import Table
from typer._click import Context
from typer.core import TyperCommand

from egs_bench.cli.app import OUT_REQUIRED, QUIET, app, comma_list, counted, output_path
from egs_bench.cli.app import out as _out
from egs_bench.cli.choices import (
    Alignment,
    BoardFormat,
    BoardLayout,
    DeltaUnit,
    LpipsNet,
    PoseRelation,
    Protocol,
    QuaternionOrder,
    TableWidth,
)
from egs_bench.eval.protocols import DEFAULT_PROTOCOL

if TYPE_CHECKING:
    from egs_bench.eval.ate import AteResult
    from egs_bench.eval.metrics_file import RunMetrics
    from egs_bench.eval.rpe import RpeResult


def _fmt(value: float | None, digits: int) -> str:
    return "--" if value is None else f"{value:.{digits}f}"


@app.command("eval")
def eval_cmd(
    run_dir: Path = typer.Argument(..., help="Run folder to evaluate (see docs: run folder)."),
    protocol: Protocol = typer.Option(DEFAULT_PROTOCOL, "--protocol", "-p",
                                      help="Evaluation protocol: egs (default) or monogs."),
    quiet: bool = QUIET,
) -> None:
    """Score a run (ATE, PSNR, SSIM, LPIPS, FPS) and write RUN_DIR/metrics.json."""
    evaluate_and_print(run_dir, protocol, progress=not quiet)


def evaluate_and_print(run_dir: Path, protocol: str = DEFAULT_PROTOCOL, *,
                       progress: bool) -> None:
    """Score ``run_dir``, write its ``metrics.json`` and print it (``eval``, ``run --eval``)."""
    from egs_bench.eval.evaluate import evaluate_run
    from egs_bench.eval.metrics_file import parse_metrics
    from egs_bench.runs.folder import METRICS_FILE

    path = Path(run_dir) / METRICS_FILE
    print_metrics(parse_metrics(evaluate_run(run_dir, protocol, write=True, progress=progress),
                                path), path)


def _count(value: int | None) -> str:
    return "--" if value is None else str(value)


def print_metrics(m: RunMetrics, path: Path) -> None:
    """The table of a run's scores (``m``, read from ``path``), its RPE lines and notes: what
    ``eval`` and ``run --eval`` print."""
    table = Table(title=f"{m.method} on {m.sequence} (protocol {m.protocol})")
    # ATE and the image metrics are taken over different frames (renders every Nth frame)
    for col in ("ATE RMSE (cm)", "ATE poses", "PSNR (dB)", "SSIM", "LPIPS", "renders scored",
                "FPS"):
        table.add_column(col, justify="right")
    ate_cm = None if m.ate_rmse_m is None else 100 * m.ate_rmse_m
    table.add_row(_fmt(ate_cm, 2), _count(m.ate_poses), _fmt(m.psnr_db, 2), _fmt(m.ssim, 3),
                  _fmt(m.lpips, 3), _count(m.renders_scored), _fmt(m.fps, 2))
    _out.print(table)
    for rpe, label in ((m.rpe_per_frame, "per frame"), (m.rpe_per_metre, "per metre")):
        if rpe is not None:
            cm = None if rpe.translation_m is None else 100 * rpe.translation_m
            _out.print(f"RPE {label}: {_fmt(cm, 3)} cm, {_fmt(rpe.rotation_deg, 3)} deg "
                       f"(RMSE over {counted(rpe.n_pairs, 'pair')})")
    for note in m.notes:
        _out.print(f"note: {note}")
    _out.print(f"wrote {path}")


def _roles(first: Path, second: Path, est_first: bool, command: str) -> tuple[Path, Path]:
    """(ground truth, estimate) from the two file arguments, refusing names that say the
    roles are swapped (see :func:`egs_bench.eval.ate.check_argument_order`)."""
    from egs_bench.eval.ate import check_argument_order

    gt, est = (second, first) if est_first else (first, second)
    hint = "or drop --est-first" if est_first else "or pass --est-first for the old EST GT order"
    check_argument_order(gt, est, command=f"egs-bench {command}", swap_hint=hint)
    return gt, est


def _print_stats(title: str, unit: str, r: AteResult | RpeResult) -> None:
    """One-row table of the error statistics of an ATE or RPE result, and the Sim(3) scale."""
    table = Table(title=title)
    for col in ("rmse", "mean", "median", "std", "min", "max"):
        table.add_column(f"{col} ({unit})", justify="right")
    table.add_row(*(f"{v:.6f}" for v in (r.rmse, r.mean, r.median, r.std, r.min, r.max)))
    _out.print(table)
    if r.alignment == "sim3":
        _out.print(f"scale: {r.scale:.6f}")


_EST_FIRST = typer.Option(False, "--est-first",
                          help="The files are given as EST GT (egs-bench's former order) "
                               "instead of GT EST.")
_ALIGN_VALUES = ("se3", "sim3", "none")
_ALIGN_HELP = "se3, sim3 or none; evo's flags also work: -a alone is se3, -as is sim3"


def _is_not_a_value(rest: list[str]) -> bool:
    """Whether the token after ``-a`` is something else than its value: nothing, an option, or
    a file (evo's ``-a`` takes no value); a bad value such as ``affine`` stays a value, so that
    its message names it."""
    if not rest or rest[0] in _ALIGN_VALUES:
        return not rest
    nxt = rest[0]
    return nxt.startswith("-") or "/" in nxt or "." in nxt or Path(nxt).exists()


def _evo_alignment_args(args: list[str]) -> list[str]:
    """``args`` with evo's alignment flags spelled as ``--align VALUE``: ``-a`` / ``--align``
    without a value is SE(3), ``-as`` / ``-sa`` and ``-a ... -s`` (``--correct_scale``) are
    Sim(3); ``-a VALUE`` is left as it is.

    Raises:
        ConfigError: ``-s`` without ``-a`` (evo's scale-only correction, not offered).
    """
    from egs_bench.errors import ConfigError

    out: list[str] = []
    scale, flag_at, i = False, None, 0
    while i < len(args):
        arg = args[i]
        if arg == "--":
            out += args[i:]
            break
        if arg in ("-as", "-sa"):
            out += ["--align", "sim3"]
        elif arg in ("-s", "--correct_scale"):
            scale = True
        elif arg in ("-a", "--align") and _is_not_a_value(args[i + 1:]):
            out += ["--align", "se3"]
            flag_at = len(out) - 1
        else:
            out.append(arg)
        i += 1
    if scale:
        if flag_at is None:
            raise ConfigError("-s / --correct_scale needs -a (evo's -as: Sim(3) alignment); "
                              "scale correction without alignment is not offered")
        out[flag_at] = "sim3"
    return out


class _EvoSpellings(TyperCommand):
    """A command that also reads evo's alignment flags (:func:`_evo_alignment_args`)."""

    def parse_args(self, ctx: Context, args: list[str]) -> list[str]:
        return super().parse_args(ctx, _evo_alignment_args(args))


def _save_option(metric: str) -> Any:  # typer.Option's OptionInfo, typed Any by typer
    return typer.Option(None, "--save-results", "--save_results",
                        help=f"Also write the {metric} statistics, settings and per-pose errors "
                             "to this JSON file (evo's option; JSON, not evo's .zip).")


_OVERWRITE = typer.Option(False, "--overwrite", help="Replace an existing --save-results file.")
_MAX_DIFF = typer.Option(0.01, "--max-diff", "--t_max_diff", min=0.0,
                         help="Timestamp association tolerance in seconds (evo's --t_max_diff).")
_RELATIONS_HELP = "trans_part (m), angle_deg, angle_rad, rot_part, full, point_distance"


def _warn(notes: tuple[str, ...]) -> None:
    for note in notes:
        _out.print(f"warning: {note}", markup=False)


@app.command("ate", cls=_EvoSpellings)
def ate_cmd(
    groundtruth: Path = typer.Argument(..., help="Ground-truth (reference) trajectory, TUM."),
    estimate: Path = typer.Argument(..., help="Estimated trajectory, TUM format."),
    align: Alignment = typer.Option("se3", "--align", "-a", help=f"Alignment: {_ALIGN_HELP}."),
    relation: PoseRelation = typer.Option("trans_part", "--pose-relation", "--pose_relation", "-r",
                                 help=f"Pose relation of the error: {_RELATIONS_HELP} "
                                      "(evo_ape's -r; angle_deg is the rotation ATE)."),
    max_diff: float = _MAX_DIFF,
    save_results: Path | None = _save_option("ATE"),
    overwrite: bool = _OVERWRITE,
    est_first: bool = _EST_FIRST,
) -> None:
    """ATE (after alignment) of two TUM files, computed with evo.

    Files in evo's order: `egs-bench ate GT EST` = `evo_ape tum GT EST -a`.
    """
    from egs_bench.eval.ate import check_results_path, results_json, trajectory_ate
    from egs_bench.fileio import write_text_atomic

    gt, est = _roles(groundtruth, estimate, est_first, "ate")
    if save_results is not None:
        check_results_path(save_results, overwrite=overwrite, inputs=[gt, est])
    r = trajectory_ate(gt, est, align=align, relation=relation, max_diff_s=max_diff)
    _warn(r.notes)
    what = "" if r.relation == "trans_part" else f" {r.relation}"
    _print_stats(f"ATE{what} ({r.alignment} alignment, {r.n_matched} poses matched within "
                 f"{r.max_diff_s} s)\nreference {gt}\nestimate  {est}", r.unit, r)
    if save_results is not None:
        write_text_atomic(save_results, results_json(r, metric="ATE", reference=gt,
                                                     estimate=est))
        _out.print(f"wrote {save_results}", markup=False)


@app.command("rpe", cls=_EvoSpellings)
def rpe_cmd(
    groundtruth: Path = typer.Argument(..., help="Ground-truth (reference) trajectory, TUM."),
    estimate: Path = typer.Argument(..., help="Estimated trajectory, TUM format."),
    relation: PoseRelation = typer.Option("trans_part", "--pose-relation", "--pose_relation", "-r",
                                 help=f"{_RELATIONS_HELP} (evo_rpe's -r)."),
    delta: float = typer.Option(1.0, "--delta", "-d", help="Pair spacing, in --delta-unit."),
    delta_unit: DeltaUnit = typer.Option("f", "--delta-unit", "--delta_unit", "-u",
                                   help="f (frames), m (metres of path), d / r (degrees / "
                                        "radians of rotation)."),
    all_pairs: bool = typer.Option(False, "--all-pairs", "--all_pairs",
                                   help="All pairs delta apart instead of consecutive pairs."),
    delta_tol: float = typer.Option(0.1, "--delta-tol", "--delta_tol",
                                    help="Relative tolerance of delta with --all-pairs."),
    align: Alignment = typer.Option("none", "--align", "-a",
                              help=f"Alignment (evo_rpe's default: none): {_ALIGN_HELP}."),
    max_diff: float = _MAX_DIFF,
    save_results: Path | None = _save_option("RPE"),
    overwrite: bool = _OVERWRITE,
    est_first: bool = _EST_FIRST,
) -> None:
    """RPE (relative pose error) of two TUM files, computed with evo.

    `egs-bench rpe GT EST -r angle_deg -d 1 -u m` = `evo_rpe tum GT EST -r angle_deg -d 1 -u m`.
    """
    from egs_bench.eval.ate import check_results_path, results_json
    from egs_bench.eval.rpe import trajectory_rpe
    from egs_bench.fileio import write_text_atomic

    gt, est = _roles(groundtruth, estimate, est_first, "rpe")
    if save_results is not None:
        check_results_path(save_results, overwrite=overwrite, inputs=[gt, est])
    r = trajectory_rpe(gt, est, relation=relation, delta=delta, delta_unit=delta_unit,
                       all_pairs=all_pairs, align=align, max_diff_s=max_diff,
                       rel_delta_tol=delta_tol)
    _warn(r.notes)
    pairs = "all pairs" if r.all_pairs else "consecutive pairs"
    aligned = "no" if r.alignment == "none" else r.alignment
    _print_stats(f"RPE {r.relation} for delta {r.delta:g} {r.delta_unit} ({pairs}, "
                 f"{r.n_pairs} pairs of {r.n_matched} matched poses, {aligned} "
                 f"alignment)\nreference {gt}\nestimate  {est}", r.unit, r)
    if save_results is not None:
        write_text_atomic(save_results, results_json(r, metric="RPE", reference=gt,
                                                     estimate=est))
        _out.print(f"wrote {save_results}", markup=False)


@app.command("compare-images")
def compare_images_cmd(
    image_a: Path = typer.Argument(..., help="First image (e.g. a render), 8-bit RGB."),
    image_b: Path = typer.Argument(..., help="Second image (the reference), 8-bit RGB."),
    lpips_net: LpipsNet = typer.Option("alex", "--lpips-net", help="LPIPS backbone: alex or vgg."),
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
    fmt: BoardFormat = typer.Option("md", "--format", "-f",
                            help="Output format: md, latex, csv (one row per run, units in the "
                                 "column names) or csv-summary (mean/std per method, settings "
                                 "and sequence)."),
    by: BoardLayout = typer.Option("sequence", "--by",
                           help="Column groups: sequence (rows = methods) or method."),
    protocol: Protocol = typer.Option(DEFAULT_PROTOCOL, "--protocol", "-p",
                                 help="Protocol of the numbers (runs are evaluated if needed)."),
    metrics: str = typer.Option("ate,psnr,ssim,lpips", "--metrics",
                                help="Comma-separated metrics: ate, psnr, ssim, lpips, fps."),
    no_eval: bool = typer.Option(False, "--no-eval",
                                 help="Do not evaluate runs that lack metrics.json."),
    output: Path | None = typer.Option(None, "--out", "-o", "--output",
                                       help="Write the table to this file instead of stdout."),
    overwrite: bool = typer.Option(False, "--overwrite",
                                   help="Replace an existing text file at --out."),
    caption: str | None = typer.Option(None, "--caption", help="LaTeX caption."),
    label: str | None = typer.Option(None, "--label",
                                     help="LaTeX label (default tab:<RUNS_ROOT name>)."),
    width: TableWidth = typer.Option("auto", "--width",
                              help="LaTeX width: auto, natural, column (shrink to the column) "
                                   "or page (table* shrunk to the text width)."),
) -> None:
    """Leaderboard of all runs under RUNS_ROOT: mean ± std over seeds, best bold, second
    underlined."""
    from egs_bench.eval.leaderboard import leaderboard
    from egs_bench.fileio import write_text_atomic
    from egs_bench.outputs import prepare_output

    if output is not None:
        prepare_output(output, "text", overwrite=overwrite, inputs=[runs_root],
                       option="--out")
    text = leaderboard(runs_root, fmt=fmt, by=by, protocol=protocol,
                       metrics=comma_list(metrics, "--metrics"),
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
    protocol: Protocol = typer.Option(DEFAULT_PROTOCOL, "--protocol", "-p",
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


def _known_import_format(value: str) -> str:
    """``--from``'s check: one of the registry's import formats, read when the command parses
    (the registry is not imported with the CLI, and a system registered later is known)."""
    from egs_bench.interop.registry import import_formats

    formats = import_formats()
    if value not in formats:
        raise typer.BadParameter(f"{value!r} is not one of {', '.join(map(repr, formats))}.")
    return value


def _import_format_completion(incomplete: str) -> list[str]:
    from egs_bench.interop.registry import import_formats

    return [f for f in import_formats() if f.startswith(incomplete)]


class _ImportRunCommand(TyperCommand):
    """``import-run``, whose ``--from`` and ``--render-ply`` help list the systems of
    :mod:`egs_bench.interop.registry`, filled in when the command shows its help or parses
    its arguments: importing the CLI does not import the registry (its systems' readers load
    scipy), and a system registered after the CLI was imported is listed too."""

    def get_params(self, ctx: Context) -> list[Any]:
        from egs_bench.interop.registry import TUM, import_formats, importable_systems

        params: list[Any] = super().get_params(ctx)
        systems = importable_systems()
        for param in params:
            if param.name == "fmt":
                listed = [f"{s.key} ({s.output})" if s.output else s.key for s in systems]
                param.help = f"What SOURCE is: {TUM} (a TUM trajectory), {', '.join(listed)}."
                param.metavar = f"[{'|'.join(import_formats())}]"
            elif param.name == "render_ply":
                drawn = [s for s in systems if s.gaussian_map is not None]
                param.help = (
                    f"--from {' / '.join(s.key for s in drawn)}: render its Gaussian map "
                    f"({', '.join(dict.fromkeys(str(s.gaussian_map) for s in drawn))}) at the "
                    "imported poses." if drawn else "Render the system's Gaussian map (no "
                    "system of the registry writes one).")
        return params


@app.command("import-run", cls=_ImportRunCommand)
def import_run_cmd(
    source: Path = typer.Argument(..., help="External output: a TUM file, or the file / folder "
                                            "the system wrote (see --from)."),
    old_out: Path | None = typer.Argument(None, hidden=True),  # deprecated: the output positional
    out: Path | None = typer.Option(None, "--out", "-o",
                                    help=f"Run folder to create {OUT_REQUIRED}."),
    # the help and the choices are the registry's (_ImportRunCommand, _known_import_format)
    fmt: str = typer.Option("tum", "--from", callback=_known_import_format,
                            autocompletion=_import_format_completion),
    export_dir: Path | None = typer.Option(None, "--export",
                                           help="The egs-bench export the system ran on (maps "
                                                "its stamps / frame ids to sequence frames)."),
    method: str | None = typer.Option(None, "--method", "-m",
                                      help="Method name for leaderboards (default: the "
                                           "system's name; required for --from tum)."),
    sequence: str | None = typer.Option(None, "--sequence", "-s",
                                        help="Sequence name for leaderboards (default: the "
                                             "exported sequence's)."),
    sequence_path: Path | None = typer.Option(None, "--sequence-path",
                                              help="Canonical sequence folder (GT + images)."),
    groundtruth: Path | None = typer.Option(None, "--groundtruth",
                                            help="--from tum: ground-truth TUM file (no "
                                                 "sequence folder)."),
    renders: Path | None = typer.Option(None, "--renders",
                                        help="Folder of renders named <frame index>.png."),
    render_ply: bool = typer.Option(False, "--render-ply"),  # help: _ImportRunCommand
    quaternion: QuaternionOrder = typer.Option("rampvo", "--quaternion",
                                   help="--from rampvo: quaternion columns as RampVO writes "
                                        "them (rampvo: qy qz qw qx) or wxyz."),
    overwrite: bool = typer.Option(False, "--overwrite", help="Replace an existing run folder."),
) -> None:
    """Import an external system's output (trajectory, renders) as a finished run folder."""
    from egs_bench.errors import ConfigError
    from egs_bench.interop.importing import import_external_run, import_tum_run

    out_dir = output_path(out, old_out, "import-run")
    if fmt == "tum":
        if not method or not sequence:
            raise ConfigError("--from tum needs --method and --sequence")
        run = import_tum_run(source, out_dir, method=method, sequence_name=sequence,
                             sequence_path=sequence_path, groundtruth=groundtruth,
                             renders_dir=renders, overwrite=overwrite)
    else:
        if groundtruth is not None:
            raise ConfigError(f"--groundtruth is for --from tum; --from {fmt} maps onto the "
                              "sequence (--export or --sequence-path)")
        run = import_external_run(source, out_dir, fmt=fmt, export_dir=export_dir,
                                  method=method, sequence_name=sequence,
                                  sequence_path=sequence_path, renders_dir=renders,
                                  render_ply=render_ply, quaternion=quaternion,
                                  overwrite=overwrite)
    est = run.info.get("estimate")
    what = f" (poses: {est['poses']}, renders: {est['renders']})" if est else ""
    _out.print(f"imported {run.method} on {run.sequence_name} into {run.path}{what}")
