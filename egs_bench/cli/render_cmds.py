"""CLI commands of the render area: render a saved Gaussian map, make the demo render."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import typer

from egs_bench.cli.app import app
from egs_bench.errors import ConfigError

BACKENDS = ("auto", "numba", "gsplat")


def _parse_pose(text: str) -> np.ndarray:
    from egs_bench.geometry import pose_from_tq

    vals = text.replace(",", " ").split()
    if len(vals) != 7:
        raise ConfigError(f"--pose needs 7 numbers 'tx ty tz qx qy qz qw', got {text!r}")
    try:
        v = np.array([float(x) for x in vals])
    except ValueError:
        raise ConfigError(f"--pose needs 7 numbers 'tx ty tz qx qy qz qw', got {text!r}") \
            from None
    if not np.isfinite(v).all() or np.linalg.norm(v[3:]) < 1e-9:
        raise ConfigError(f"--pose needs finite numbers and a non-zero quaternion, got {text!r}")
    return pose_from_tq(v[:3], v[3:])


@app.command("render-map")
def render_map(
    ply: Path = typer.Argument(..., help="Gaussian map as a 3DGS .ply (e.g. saved by a run)."),
    out: Path = typer.Option(..., "--out", "-o", help="Output PNG (8-bit sRGB)."),
    pose: str = typer.Option(
        None, "--pose",
        help="Camera-to-world pose 'tx ty tz qx qy qz qw' (TUM order). Default: frame the map.",
    ),
    width: int = typer.Option(640, min=1, help="Image width in pixels."),
    height: int = typer.Option(480, min=1, help="Image height in pixels."),
    fov: float = typer.Option(60.0, min=1.0, max=170.0,
                              help="Horizontal field of view in degrees (square pixels)."),
    backend: str = typer.Option("auto", help="Rasteriser backend: auto, numba, gsplat."),
    overwrite: bool = typer.Option(False, "--overwrite",
                                   help="Replace an existing PNG at --out."),
) -> None:
    """Render a saved Gaussian map from one camera into a PNG."""
    from egs_bench.geometry import Intrinsics
    from egs_bench.outputs import prepare_output
    from egs_bench.render.demo import render_map_png
    from egs_bench.render.gaussian_map import GaussianMap

    if backend not in BACKENDS:
        raise ConfigError(f"--backend must be one of {', '.join(BACKENDS)}, not {backend!r}")
    T_wc = _parse_pose(pose) if pose else None  # noqa: N806
    prepare_output(out, "png", overwrite=overwrite, inputs=[ply])
    gmap = GaussianMap.load_ply(ply)
    f = 0.5 * width / np.tan(np.radians(fov) / 2)
    intr = Intrinsics(f, f, width / 2, height / 2, width, height)
    render_map_png(gmap, out, T_wc, intr if pose else None, width, height, backend)
    typer.echo(f"rendered {len(gmap)} Gaussians -> {out}")


@app.command("render-demo")
def render_demo_cmd(
    out: Path = typer.Option(Path("render_demo.png"), "--out", "-o",
                             help="Output PNG: input view | render | depth | novel view."),
    ply: Path = typer.Option(None, "--ply", help="Also save the demo Gaussian map here."),
    overwrite: bool = typer.Option(False, "--overwrite",
                                   help="Replace an existing PNG at --out (and PLY at --ply)."),
) -> None:
    """Build a Gaussian map from a synthetic RGB-D view and render it (a visual self-check)."""
    from egs_bench.outputs import prepare_output
    from egs_bench.render.demo import render_demo

    prepare_output(out, "png", overwrite=overwrite)
    if ply:
        prepare_output(ply, "ply", overwrite=overwrite, option="--ply")
    gmap = render_demo(out)
    if ply:
        gmap.save_ply(ply)
    typer.echo(f"{len(gmap)} Gaussians rendered -> {out}")
