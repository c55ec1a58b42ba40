"""CLI commands to look at sequences and runs: ``info`` and ``show``."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.table import Table

from egs_bench.cli.app import QUIET, SEED_MAX, app
from egs_bench.cli.app import out as _out
from egs_bench.cli.choices import SlamPreset


@app.command("info")
def info(
    seq: str = typer.Argument(..., help="Sequence folder (canonical format: meta.yaml, ...), "
                                        "a name under $EGS_BENCH_DATA (built-in names are "
                                        "generated on first use), or a run folder."),
    check: bool = typer.Option(
        True, "--check/--no-check", help="Decode every image and depth map to validate them."
    ),
) -> None:
    """Print a summary of a sequence (frames, duration, resolution, intrinsics, events, blur)
    or of a run folder (method, state, map, speed, rendering work)."""
    from egs_bench.datasets.inspect import sequence_summary
    from egs_bench.datasets.registry import load_sequence
    from egs_bench.runs.folder import RunFolder

    if RunFolder.is_run_folder(seq):
        from egs_bench.runs.summary import run_summary

        _print_table(f"run {seq}", run_summary(seq))
        return

    sequence = load_sequence(seq)
    if check:
        sequence.validate_contents()
    _print_table(f"sequence {sequence.name}", sequence_summary(sequence))


def _print_table(title: str, rows: dict) -> None:
    table = Table(title=title, show_header=False)
    for key, value in rows.items():
        if isinstance(value, dict):
            value = ", ".join(f"{k}={v}" for k, v in value.items())
        table.add_row(key, str(value))
    _out.print(table)


@app.command("show")
def show(
    seq: str = typer.Argument(..., help="Sequence folder or name (as for `info`)."),
    frame: int = typer.Option(0, "--frame", "-f", help="Frame index to show."),
    out: Path = typer.Option(..., "--out", "-o", help="PNG file to write."),
    overwrite: bool = typer.Option(False, "--overwrite",
                                   help="Replace an existing PNG at --out."),
) -> None:
    """Write a PNG panel of one frame: observed, sharp GT, depth and the exposure's event map."""
    from egs_bench.datasets.inspect import save_frame_panel
    from egs_bench.datasets.registry import load_sequence
    from egs_bench.errors import ConfigError
    from egs_bench.outputs import prepare_output

    sequence = load_sequence(seq)
    if not 0 <= frame < len(sequence):
        raise ConfigError(f"--frame {frame} out of range: {seq} has {len(sequence)} frames")
    prepare_output(out, "png", overwrite=overwrite, inputs=[sequence.path])
    save_frame_panel(sequence, frame, out)
    _out.print(f"wrote {out}")


@app.command("demo")
def demo(
    out: Path = typer.Option(Path("demo_out"), "--out", "-o",
                             help="Folder for the demo's runs, plots and frame panel."),
    sequence: str = typer.Option("demo-blur", "--seq", "-s",
                                 help="Sequence name or folder (built-in names are generated "
                                      "under $EGS_BENCH_DATA, default ./data, on first use)."),
    preset: SlamPreset = typer.Option("cpu", "--preset", help="SLAM configuration preset."),
    seed: int = typer.Option(0, "--seed", min=0, max=SEED_MAX,
                             help="Seed of the SLAM runs (the sequence stays the same)."),
    quiet: bool = QUIET,
) -> None:
    """End-to-end demo: blurred synthetic sequence -> egs and monogs -> metrics -> leaderboard."""
    from egs_bench.demo import run_demo

    run_demo(out, sequence=sequence, preset=preset, seed=seed, say=_out.print,
             progress=not quiet)
