"""The typer application object and global options, shared by the command modules."""

from __future__ import annotations

from dataclasses import dataclass

import typer


@dataclass
class GlobalOptions:
    debug: bool = False


OPTIONS = GlobalOptions()

app = typer.Typer(
    name="egs-bench",
    help="Event + RGB-D Gaussian Splatting SLAM toolkit: make data, run methods, score them.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
    context_settings={"help_option_names": ["-h", "--help"]},
)


@app.callback()
def _global(
    debug: bool = typer.Option(
        False, "--debug", help="Show full Python tracebacks instead of one-line error messages."
    ),
) -> None:
    """Event + RGB-D Gaussian Splatting SLAM toolkit: make data, run methods, score them."""
    OPTIONS.debug = debug
