"""CLI commands ``make-synthetic`` and ``list-scenes``: the built-in procedural scenes."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.table import Table

from egs_bench.cli.app import QUIET, SEED_MAX, app
from egs_bench.cli.app import out as _out


@app.command("make-synthetic")
def make_synthetic_cmd(
    scene: str = typer.Option(
        ..., "--scene", "-s", help="Scene name (see `egs-bench list-scenes`)."
    ),
    out: Path = typer.Option(..., "--out", "-o",
                             help="Sequence folder to create (an existing one is replaced only "
                                  "with --overwrite)."),
    frames: int = typer.Option(100, "--frames", "-n", help="Number of frames."),
    width: int = typer.Option(448, "--width", help="Image width in pixels."),
    height: int = typer.Option(256, "--height", help="Image height in pixels."),
    fps: float = typer.Option(30.0, "--fps", help="Frame rate (Hz)."),
    exposure_ms: float = typer.Option(
        20.0, "--exposure-ms",
        help="Exposure time per frame in ms (at most one frame period); longer = more blur.",
    ),
    speed: float = typer.Option(
        1.0, "--speed",
        help="Camera motion speed factor; blur grows with it (1: about 4 px mean motion per "
             "20 ms at 448 px width; 0: static camera).",
    ),
    seed: int = typer.Option(
        0, "--seed", min=0, max=SEED_MAX,
        help="Seed of the hand-held motion (and of the event simulator)."
    ),
    trajectory: Path | None = typer.Option(
        None, "--trajectory",
        help="TUM trajectory file (t tx ty tz qx qy qz qw) to replay instead of the hand-held "
             "motion; its motion relative to its first pose starts at the scene's camera anchor.",
    ),
    time_scale: float = typer.Option(
        1.0, "--time-scale",
        help="Stretch the trajectory file's time axis by this factor (>1 slower, <1 faster).",
    ),
    supersample: int = typer.Option(
        2, "--supersample", help="Anti-aliasing: NxN ray samples per pixel (1-8)."
    ),
    gain: float = typer.Option(
        1.0, "--gain", help="Camera response gain before clipping (higher saturates more)."
    ),
    overwrite: bool = typer.Option(False, "--overwrite", help="Replace an existing --out."),
    quiet: bool = QUIET,
) -> None:
    """Generate a blurred RGB-D + events sequence of a built-in procedural scene."""
    from egs_bench.datasets.synthetic import make_synthetic

    path = make_synthetic(
        scene, out, frames=frames, width=width, height=height, fps=fps, exposure_ms=exposure_ms,
        speed=speed, seed=seed, trajectory=trajectory, time_scale=time_scale,
        supersample=supersample, gain=gain, progress=not quiet, overwrite=overwrite,
    )  # fmt: skip
    _out.print(f"wrote {path}")


@app.command("list-scenes")
def list_scenes_cmd() -> None:
    """List the built-in procedural scenes for `make-synthetic` and the named built-in
    sequences (`--seq NAME`, generated on first use under $EGS_BENCH_DATA)."""
    from egs_bench.datasets.registry import BUILTIN_SEQUENCES, data_root
    from egs_bench.datasets.synthetic import list_scenes

    table = Table(title="built-in synthetic scenes")
    table.add_column("scene")
    table.add_column("description")
    for name, description in list_scenes().items():
        table.add_row(name, description)
    _out.print(table)
    seqs = Table(title=f"built-in sequences (--seq NAME; generated on first use in {data_root()})")
    for col in ("name", "scene", "frames", "size", "exposure ms", "speed", "here", "description"):
        seqs.add_column(col, no_wrap=col in ("name", "scene", "size"))
    for name, spec in BUILTIN_SEQUENCES.items():
        seqs.add_row(name, spec.scene, str(spec.frames), f"{spec.width}x{spec.height}",
                     f"{spec.exposure_ms:g}", f"{spec.speed:g}",
                     "yes" if (data_root() / name).is_dir() else "", spec.description)
    _out.print(seqs)
