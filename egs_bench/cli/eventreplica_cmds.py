"""CLI command ``make-eventreplica``: blurred E-RGB-D sequences from RGB-D + pose data."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

import typer

from egs_bench.cli.app import QUIET, SEED_MAX, app
from egs_bench.cli.app import out as _out
from egs_bench.cli.choices import Interpolator, RgbdLayout


@app.command("make-eventreplica")
def make_eventreplica_cmd(
    out: Path = typer.Option(
        ..., "--out", "-o",
        help="Output sequence folder (with --replica-root: a parent folder, one sub-folder per "
             "scene).",
    ),
    input: Path | None = typer.Option(
        None, "--input", "-i",
        help="One scene: with --layout replica (default) results/frameNNNNNN.jpg, "
             "results/depthNNNNNN.png (scale 6553.5), traj.txt (16 numbers per line, c2w); "
             "with --layout tum-rgbd a TUM RGB-D folder.",
    ),
    layout: RgbdLayout = typer.Option(
        "replica", "--layout",
        help="Input layout: 'replica' (NICE-SLAM), 'tum-rgbd' (--input with rgb.txt, depth.txt, "
             "groundtruth.txt; depth scale 5000) or 'generic' (--rgb-dir, --depth-dir, "
             "--trajectory, --intrinsics).",
    ),
    intrinsics: Path | None = typer.Option(
        None, "--intrinsics",
        help="Camera yaml for tum-rgbd / generic: fx, fy, cx, cy (OpenCV convention), optional "
             "width, height, distortion [k1 k2 p1 p2 k3], depth_scale (required for generic).",
    ),
    tum_camera: str | None = typer.Option(
        None, "--tum-camera",
        help="tum-rgbd: use the TUM calibration of fr1, fr2 or fr3 (default: egs_export.yaml "
             "in the folder, else the freiburgN in the folder name).",
    ),
    max_dt: float = typer.Option(
        0.02, "--max-dt",
        help="tum-rgbd: largest time difference (s) when associating colour, depth and poses.",
    ),
    rgb_dir: Path | None = typer.Option(
        None, "--rgb-dir", help="generic: folder of colour images (natural name order)."),
    depth_dir: Path | None = typer.Option(
        None, "--depth-dir", help="generic: folder of 16-bit depth PNGs (same order and count)."),
    trajectory: Path | None = typer.Option(
        None, "--trajectory",
        help="generic: TUM trajectory (t tx ty tz qx qy qz qw, camera-to-world), one pose per "
             "image.",
    ),
    replica_root: Path | None = typer.Option(
        None, "--replica-root",
        help="Folder holding several Replica scenes (use with --scene; instead of --input).",
    ),
    scene: list[str] | None = typer.Option(
        None, "--scene",
        help="Scene name under --replica-root, e.g. office0; repeat for several scenes.",
    ),
    stride: int = typer.Option(
        1, "--stride", min=1,
        help="Use every S-th original frame; larger strides mean faster motion and more blur.",
    ),
    fps: float = typer.Option(30.0, "--fps", help="Frame rate of the strided frames (Hz)."),
    exposure_ms: float = typer.Option(
        20.0, "--exposure-ms",
        help="Exposure of each output frame in ms, ending at the original frame (at most one "
             "frame period).",
    ),
    upsample: str = typer.Option(
        "auto", "--upsample",
        help="Temporal sampling: 'auto' (adaptive: about 1 px motion and a bounded log-brightness "
             "change between samples) or N (exactly N equal sub-steps between consecutive "
             "exposure boundaries).",
    ),
    interpolator: Interpolator = typer.Option(
        "depth", "--interpolator",
        help="In-between frames: 'depth' (pose-aware depth-based view synthesis) or 'flow' "
             "(OpenCV DIS optical flow; needs no depth).",
    ),
    width: int = typer.Option(448, "--width", help="Output width after the centre crop (px)."),
    height: int = typer.Option(256, "--height", help="Output height after the centre crop (px)."),
    resize: str = typer.Option(
        "auto", "--resize",
        help="Resize to WxH before the centre crop, 'none' to crop only, or 'auto': the "
             "paper's 459x260 for Replica's 1200x680 frames, otherwise the smallest size with "
             "the input's aspect ratio that covers the crop.",
    ),
    first: int = typer.Option(0, "--first", min=0, help="First original frame to use."),
    max_frames: int | None = typer.Option(
        None, "--max-frames", min=2,
        help="Use at most this many strided frames (the output has one frame fewer).",
    ),
    cam_params: Path | None = typer.Option(
        None, "--cam-params",
        help="cam_params.json with w, h, fx, fy, cx, cy, scale (Replica convention). Default: "
             "<scene>/cam_params.json or its parent's, else 1200x680, f=600, c=(599.5, 339.5).",
    ),
    threshold: float = typer.Option(
        0.25, "--threshold", help="Event contrast threshold (log units), both polarities."
    ),
    eps: float = typer.Option(1e-3, "--eps", help="Offset in log(luma + eps) for events."),
    gain: float = typer.Option(
        1.0, "--gain", help="Camera response gain before sRGB encoding (> 1 saturates)."
    ),
    seed: int = typer.Option(0, "--seed", min=0, max=SEED_MAX,
                             help="Seed for event noise/threshold mismatch."),
    overwrite: bool = typer.Option(False, "--overwrite", help="Replace existing outputs."),
    quiet: bool = QUIET,
) -> None:
    """Make EventReplica-style sequences from RGB-D + pose data (Replica, TUM RGB-D or generic
    layout): resize + crop, temporal upsampling, events, blur."""
    from egs_bench.color import LdrResponse
    from egs_bench.datasets.esim import EventSimConfig
    from egs_bench.datasets.eventreplica import make_eventreplica, make_eventreplica_scenes
    from egs_bench.datasets.rgbd_layouts import RGBDInput
    from egs_bench.errors import ConfigError

    if layout != "replica":
        if replica_root is not None or scene:
            raise ConfigError("--replica-root and --scene only work with --layout replica")
        if cam_params is not None:
            raise ConfigError("--cam-params is the Replica layout's camera file; use "
                              "--intrinsics with --layout tum-rgbd or generic")
        spec = RGBDInput(layout=layout, path=input, rgb_dir=rgb_dir, depth_dir=depth_dir,
                         trajectory=trajectory, camera=intrinsics, tum_camera=tum_camera,
                         max_dt_s=max_dt)
    elif intrinsics is not None or tum_camera is not None or any(
            p is not None for p in (rgb_dir, depth_dir, trajectory)):
        raise ConfigError("--intrinsics, --tum-camera, --rgb-dir, --depth-dir and --trajectory "
                          "need --layout tum-rgbd or generic")
    elif (input is None) == (replica_root is None):
        raise ConfigError("give exactly one of --input DIR or --replica-root ROOT --scene NAME")
    elif replica_root is not None and not scene:
        raise ConfigError("--replica-root needs at least one --scene NAME")
    elif input is not None and scene:
        raise ConfigError("--scene only works with --replica-root")
    kwargs: dict[str, Any] = dict(
        stride=stride, fps=fps, exposure_ms=exposure_ms, upsample=upsample,
        interpolator=interpolator, width=width, height=height, resize=_parse_size(resize),
        first=first, max_frames=max_frames,
        sim=EventSimConfig(pos_threshold=threshold, neg_threshold=threshold, eps=eps, seed=seed),
        response=LdrResponse(gain=gain), progress=not quiet, overwrite=overwrite,
    )
    if layout != "replica":
        outputs = [make_eventreplica(spec, out, **kwargs)]
    elif input is not None:
        outputs = [make_eventreplica(input, out, cam_params=cam_params, **kwargs)]
    else:
        assert replica_root is not None  # exactly one of --input / --replica-root, checked above
        outputs = make_eventreplica_scenes(replica_root, scene or [], out,
                                           cam_params=cam_params, **kwargs)
    for path in outputs:
        _out.print(f"wrote {path}")


def _parse_size(text: str) -> tuple[int, int] | Literal["auto"] | None:
    from egs_bench.errors import ConfigError

    word = text.strip().lower()
    if word in ("none", "auto"):
        return None if word == "none" else "auto"
    try:
        w, h = (int(v) for v in word.split("x"))
    except ValueError:
        raise ConfigError(f"--resize must look like 459x260, 'auto' or 'none', not {text!r}") \
            from None
    if w <= 0 or h <= 0:
        raise ConfigError(f"--resize must be a positive size, not {text!r}")
    return w, h
