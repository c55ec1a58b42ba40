"""CLI command of the report area: report."""

from __future__ import annotations

from pathlib import Path

import typer

from egs_bench.cli.app import app, comma_list, counted
from egs_bench.cli.app import out as _out


@app.command("report")
def report_cmd(
    source: Path = typer.Argument(..., help="A run folder, a folder of runs or a sweep's output "
                                            "folder."),
    output: Path = typer.Option(..., "--out", "-o", "--output", help="Report folder to create."),
    protocols: str | None = typer.Option(None, "--protocol", "-p",
                                         help="Comma-separated protocols with a leaderboard "
                                              "(default: those the runs were evaluated under)."),
    frames: str | None = typer.Option(None, "--frames",
                                      help="Comma-separated frame indices of the image strips."),
    no_eval: bool = typer.Option(False, "--no-eval",
                                 help="Do not evaluate runs that lack metrics.json."),
    overwrite: bool = typer.Option(False, "--overwrite",
                                   help="Replace an existing report folder (never anything "
                                        "else)."),
) -> None:
    """Self-contained HTML report (open OUT/index.html, works offline): leaderboards,
    flagged runs, provenance, per-sequence trajectories and image strips, per-run pages."""
    from egs_bench.errors import ConfigError
    from egs_bench.report import build_report

    picked = None
    if frames:
        try:
            picked = [int(f) for f in comma_list(frames, "--frames")]
        except ValueError:
            raise ConfigError(f"--frames must be comma-separated integers, got {frames!r}") \
                from None
    result = build_report(source, output, overwrite=overwrite,
                          protocols=comma_list(protocols, "--protocol") if protocols else None,
                          evaluate_missing=not no_eval, frames=picked)
    _out.print(f"wrote {result.index}: {counted(result.runs, 'run')} ({result.flagged} "
               f"flagged), {counted(result.sequences, 'sequence')}, "
               f"{result.size_bytes / 1e6:.1f} MB")
