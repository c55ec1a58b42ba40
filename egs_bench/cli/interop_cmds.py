"""CLI commands of the interoperability area: ``export`` (thin wrapper over
:func:`egs_bench.interop.export.export_sequence`)."""

from __future__ import annotations

from pathlib import Path

import typer

from egs_bench.cli.app import OUT_REQUIRED, QUIET, app, output_path
from egs_bench.cli.choices import ExportFormat, Retime


@app.command("export")
def export_cmd(
    seq: str = typer.Argument(..., help="Sequence folder, or a name under $EGS_BENCH_DATA."),
    old_out: Path | None = typer.Argument(None, hidden=True),  # deprecated: the output positional
    out: Path | None = typer.Option(None, "--out", "-o",
                                    help=f"Export folder to create {OUT_REQUIRED}."),
    fmt: ExportFormat = typer.Option(..., "--format", "-f",
                            help="tum-rgbd (MonoGS, ORB-SLAM2, Photo-SLAM), replica "
                                 "(NICE-SLAM-style loaders, MonoGS), eds (RampVO)."),
    retime: Retime = typer.Option("auto", "--retime",
                               help="tum-rgbd time stamps: auto (rewrite to t0 + j/30 s only "
                                    "if frames are <= 1/32 s apart, which MonoGS drops), never, "
                                    "always."),
    jpeg_quality: int = typer.Option(95, "--jpeg-quality",
                                     help="JPEG quality of the replica layout (1-100)."),
    overwrite: bool = typer.Option(False, "--overwrite",
                                   help="Replace an earlier egs-bench export at --out."),
    quiet: bool = QUIET,
) -> None:
    """Export a sequence in a layout another SLAM system reads, with its camera files."""
    from egs_bench.datasets.registry import resolve_sequence
    from egs_bench.interop.export import export_sequence

    out = output_path(out, old_out, "export")
    result = export_sequence(resolve_sequence(seq, progress=not quiet), out, fmt=fmt,
                             overwrite=overwrite, retime=retime, jpeg_quality=jpeg_quality,
                             progress=not quiet)
    typer.echo(f"exported {result.frames} frames ({result.format}) to {result.path}")
    for consumer, name in result.files.items():
        typer.echo(f"  {consumer:12s} {result.path / name}")
    for note in result.notes:
        typer.echo(f"note: {note}")
