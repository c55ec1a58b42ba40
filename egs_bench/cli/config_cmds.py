"""CLI command ``config-reference``: the configuration reference of the SLAM methods (a thin
wrapper of :mod:`egs_bench.slam.config_reference`)."""

from __future__ import annotations

from pathlib import Path

import typer

from egs_bench.cli.app import app, err


@app.command("config-reference")
def config_reference_cmd(
    method: str | None = typer.Option(None, "--method", "-m",
                                      help="One method (a registered name or module:attribute):"
                                           " every group with the fields its components add. "
                                           "Default: the built-in groups and the fields of "
                                           "every registered method's components."),
    output: Path | None = typer.Option(None, "--out", "-o",
                                       help="Write the Markdown to this file instead of stdout."),
    overwrite: bool = typer.Option(False, "--overwrite",
                                   help="Replace an existing text file at --out."),
) -> None:
    """Print the configuration reference (Markdown): each field's type, default, preset
    values, range and documentation, as on the docs site's page."""
    from egs_bench.fileio import write_text_atomic
    from egs_bench.outputs import prepare_output
    from egs_bench.slam.config_reference import method_reference

    if output is not None:
        prepare_output(output, "text", overwrite=overwrite, option="--out")
    text = method_reference(method)
    if output is not None:
        write_text_atomic(output, text)
        err.print(f"wrote {output}")
    else:
        typer.echo(text)
