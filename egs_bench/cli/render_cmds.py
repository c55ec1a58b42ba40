"""CLI commands of the render area: render or export a saved Gaussian map, make the demo
render."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import typer

from egs_bench.cli.app import app
from egs_bench.cli.choices import MapBackend, MapColors
from egs_bench.errors import ConfigError


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
    source: Path = typer.Argument(..., help="A run folder (map.ply + appearance.json + "
                                            "trajectory) or a 3DGS .ply."),
    out: Path = typer.Option(..., "--out", "-o", help="Output PNG (8-bit)."),
    frame: int = typer.Option(None, "--frame", "-f",
                              help="Render at the run's estimated pose of this frame."),
    pose: str = typer.Option(
        None, "--pose",
        help="Camera-to-world pose 'tx ty tz qx qy qz qw' (TUM order). Default: frame the map.",
    ),
    appearance: Path = typer.Option(None, "--appearance",
                                    help="appearance.json of a run (CRF, camera, exposure) "
                                         "for a .ply source; default: the run folder's own."),
    exposure: bool = typer.Option(False, "--exposure",
                                  help="Apply the frame's exposure compensation (brightness "
                                       "of the observed frame; the run's renders do not)."),
    colors: MapColors = typer.Option("auto", "--colors",
                               help="Without an appearance file: auto (from the file), linear "
                                    "(sRGB-encode) or display (as stored)."),
    width: int = typer.Option(None, min=1, help="Image width in pixels [default: the run's "
                                                "camera, else 640]."),
    height: int = typer.Option(None, min=1, help="Image height in pixels [default: the run's "
                                                 "camera, else 480]."),
    fov: float = typer.Option(None, min=1.0, max=170.0,
                              help="Horizontal field of view in degrees, square pixels "
                                   "[default: the run's camera, else 60]."),
    fx: float = typer.Option(None, "--fx", help="Focal length in pixels (instead of --fov)."),
    fy: float = typer.Option(None, "--fy", help="Vertical focal length [default: --fx]."),
    cx: float = typer.Option(None, "--cx", help="Principal point x in pixels, pixel u "
                                                "covering [u, u+1) (OpenCV cx + 0.5) "
                                                "[default: the image centre]."),
    cy: float = typer.Option(None, "--cy", help="Principal point y, as --cx."),
    backend: MapBackend = typer.Option("auto", help="Rasteriser backend: auto, numba, gsplat."),
    overwrite: bool = typer.Option(False, "--overwrite",
                                   help="Replace an existing PNG at --out."),
) -> None:
    """Render a saved Gaussian map from one camera into a PNG (a run's map as the run did)."""
    from egs_bench.images import write_ldr_image
    from egs_bench.outputs import prepare_output
    from egs_bench.slam.map_export import open_map, render_map_view, view_camera

    pose_wc = _parse_pose(pose) if pose else None
    prepare_output(out, "png", overwrite=overwrite, inputs=[source, appearance])
    src = open_map(source, appearance)
    base = src.appearance.camera if src.appearance is not None else None
    camera = view_camera(base, width=width, height=height, fov_deg=fov, fx=fx, fy=fy, cx=cx,
                         cy=cy) or view_camera(None, fov_deg=60.0)
    img, what = render_map_view(src, frame=frame, pose=pose_wc, camera=camera,
                                exposure=exposure, colors=colors, backend=backend)
    write_ldr_image(out, img)
    for note in src.notes:
        typer.echo(f"note: {note}")
    typer.echo(f"rendered {len(src.gmap)} Gaussians ({what}) -> {out}")


@app.command("export-map")
def export_map(
    source: Path = typer.Argument(..., help="A run folder, or a run's map.ply with "
                                            "--appearance."),
    out: Path = typer.Option(..., "--out", "-o", help="Output .ply (display-space 3DGS)."),
    appearance: Path = typer.Option(None, "--appearance",
                                    help="The run's appearance.json (for a .ply source)."),
    overwrite: bool = typer.Option(False, "--overwrite", help="Replace an existing OUT."),
) -> None:
    """Export a run's map as a standard display-space 3DGS .ply (INRIA loader, gsplat,
    viewers): colours through the run's CRF, SH degree 3 with zero f_rest_*."""
    from egs_bench.outputs import prepare_output
    from egs_bench.slam.map_export import export_display_ply, open_map

    prepare_output(out, "ply", overwrite=overwrite, inputs=[source, appearance])
    src = open_map(source, appearance)
    export_display_ply(src, out, overwrite=overwrite)
    typer.echo(f"exported {len(src.gmap)} Gaussians (display colours, SH degree 3) -> {out}")


@app.command("render-demo")
def render_demo_cmd(
    out: Path = typer.Option(Path("render_demo.png"), "--out", "-o",
                             help="Output PNG: input view | render | depth | novel view."),
    ply: Path = typer.Option(None, "--ply", help="Also save the demo Gaussian map here."),
    overwrite: bool = typer.Option(False, "--overwrite",
                                   help="Replace an existing PNG at --out (and PLY at --ply)."),
) -> None:
    """Build a Gaussian map from a synthetic RGB-D view and render it (a visual self-check)."""
    from egs_bench.demo import render_demo
    from egs_bench.outputs import prepare_output
    from egs_bench.render.ply import save_ply

    prepare_output(out, "png", overwrite=overwrite)
    if ply:
        prepare_output(ply, "ply", overwrite=overwrite, option="--ply")
    gmap = render_demo(out)
    if ply:
        save_ply(gmap, ply)
    typer.echo(f"{len(gmap)} Gaussians rendered -> {out}")
