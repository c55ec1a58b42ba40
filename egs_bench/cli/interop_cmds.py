"""CLI commands of the interoperability area: ``export`` (thin wrapper over
:func:`egs_bench.interop.export.export_sequence`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import typer
from typer._click import Context
from typer.core import TyperCommand

from egs_bench.cli.app import OUT_REQUIRED, QUIET, app, output_path
from egs_bench.cli.choices import ExportFormat, Retime


class _ExportCommand(TyperCommand):
    """``export``, whose ``--format`` help names the systems that read each layout
    (:func:`egs_bench.interop.registry.systems_reading`), filled in when the command shows its
    help or parses its arguments: importing the CLI does not import the registry, and a
    system registered after the CLI was imported is named too."""

    def get_params(self, ctx: Context) -> list[Any]:
        from egs_bench.interop.export import FORMATS
        from egs_bench.interop.registry import systems_reading

        params: list[Any] = super().get_params(ctx)
        for param in params:
            if param.name == "fmt":
                readers = {layout: ", ".join(s.title for s in systems_reading(layout))
                           for layout in FORMATS}
                param.help = ", ".join(f"{layout} ({titles})" if titles else layout
                                       for layout, titles in readers.items()) + "."
        return params


@app.command("export", cls=_ExportCommand)
def export_cmd(
    seq: str = typer.Argument(..., help="Sequence folder, or a name under $EGS_BENCH_DATA."),
    old_out: Path | None = typer.Argument(None, hidden=True),  # deprecated: the output positional
    out: Path | None = typer.Option(None, "--out", "-o",
                                    help=f"Export folder to create {OUT_REQUIRED}."),
    fmt: ExportFormat = typer.Option(..., "--format", "-f"),  # help: _ExportCommand
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
