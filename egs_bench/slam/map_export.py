"""Portable maps: render a saved map as its run did, and export it for other 3DGS tools.

* :func:`open_map` reads a run folder (``map.ply`` + ``appearance.json`` + ``trajectory.txt``)
  or a ``.ply`` with an optional appearance file.
* :func:`render_map_view` renders it at a run's frame or any pose. With the run's appearance
  the colours go through the run's CRF exactly as the run rendered them, so at a run's own pose
  it reproduces the run's render (same map, pose, camera, near plane and CRF). Without one the
  colours are shown according to the file's colour space (linear: sRGB-encoded; display: as
  they are).
* :func:`export_display_ply` writes a display-space 3DGS ``.ply`` (colours through the CRF,
  clamped to [0, 1]; SH degree 3 with zero ``f_rest_*``) for the INRIA loader, gsplat and
  viewers. The CRF is applied per Gaussian there, before alpha blending, while the run applies
  it to the blended pixel: the two agree where one Gaussian dominates a pixel and differ where
  Gaussians of different brightness mix (the CRF is not linear).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from egs_bench.errors import ConfigError, InputError
from egs_bench.geometry import Intrinsics
from egs_bench.render.gaussian_map import GaussianMap
from egs_bench.render.ply import PlyInfo, read_ply, save_ply
from egs_bench.slam.appearance import APPEARANCE_FILE, MAP_FILE, Appearance, ldr8, read_appearance
from egs_bench.slam.crf import crf_to_dict

COLOR_MODES = ("auto", "linear", "display")


@dataclass
class MapSource:
    """A map opened for rendering or export.

    Attributes:
        gmap: the Gaussians (float32, CPU).
        ply: the ``.ply`` read.
        info: what its header says.
        appearance: the run's appearance (CRF, camera, exposure), if available.
        run_dir: the run folder, when the source is one (its trajectory gives frame poses).
        notes: one-line remarks for the user (e.g. a run folder without an appearance file).
    """

    gmap: GaussianMap
    ply: Path
    info: PlyInfo
    appearance: Appearance | None = None
    run_dir: Path | None = None
    notes: list[str] = field(default_factory=list)


def open_map(source: str | Path, appearance: str | Path | None = None) -> MapSource:
    """Open a run folder (its ``map.ply`` and, if present, ``appearance.json``) or a ``.ply``.

    Args:
        source: a finished run folder, or a 3DGS ``.ply``.
        appearance: an ``appearance.json`` to use instead of the run folder's own (needed to
            apply a run's CRF to a bare ``.ply``).

    Raises:
        InputError: missing files, a run that is not done, or an appearance file given for a
            map whose colours are already display values.
    """
    from egs_bench.runs.folder import RunFolder

    source = Path(source)
    run_dir = None
    notes: list[str] = []
    if source.is_dir():
        run = RunFolder.open(source)
        status = run.read_status()
        if status.state != "done":
            raise InputError(source, f"run is {status.state!r}, not done: its map may be "
                                     "missing or stale")
        run_dir, ply = source, source / MAP_FILE
        if not ply.is_file():
            raise InputError(ply, "the run folder holds no map")
        if appearance is None:
            if (source / APPEARANCE_FILE).is_file():
                appearance = source / APPEARANCE_FILE
            else:
                notes.append(f"{source / APPEARANCE_FILE} not found (a run from before it "
                             "existed, or not an egs-bench SLAM run): colours are not passed "
                             "through the run's CRF and differ from its renders")
    else:
        ply = source
    gmap, info = read_ply(ply)
    app = read_appearance(appearance) if appearance is not None else None
    if app is not None and info.color_space == "display":
        raise InputError(ply, "its colours are display values already (an exported map); "
                              "an appearance file applies to a run's linear map.ply")
    return MapSource(gmap, ply, info, app, run_dir, notes)


def frame_pose(src: MapSource, frame: int) -> np.ndarray:
    """Estimated camera-to-world pose [4, 4] of frame ``frame`` of the source's run.

    The frame's exposure-end time (from the appearance file) picks the trajectory line; runs
    without an appearance file wrote one line per frame from frame 0.

    Raises:
        ConfigError: the source is not a run folder, or the run has no such frame.
    """
    from egs_bench.runs.folder import RunFolder

    if src.run_dir is None:
        raise ConfigError("--frame needs a run folder as the source (use --pose with a .ply)")
    traj = RunFolder.open(src.run_dir).read_trajectory()
    if src.appearance is not None:
        hit = np.flatnonzero(src.appearance.frames == int(frame))
        if len(hit) == 0:
            raise ConfigError(f"the run has no frame {frame}")
        t = src.appearance.timestamps_s[hit[0]]
        row = int(np.argmin(np.abs(traj.timestamps - t)))
        if abs(traj.timestamps[row] - t) > 1e-5:
            raise ConfigError(f"frame {frame} (t = {t:.6f} s) is not in the run's trajectory")
    else:
        row = int(frame)
        if not 0 <= row < len(traj):
            raise ConfigError(f"the run's trajectory has {len(traj)} poses, no frame {frame}")
    return traj.poses[row]


def color_space(src: MapSource, colors: str = "auto") -> str:
    """``"linear"`` or ``"display"``: how to show the source's colours without a CRF.

    ``auto`` takes the file's ``egs-bench colors=`` tag; untagged files with ``f_rest_*``
    properties come from 3DGS trainers (display), untagged files without them are egs-bench
    maps written before the tag existed (linear). MonoGS's SH-0 maps are untagged, have no
    ``f_rest_*`` and hold display colours: pass ``display`` for them.
    """
    if colors not in COLOR_MODES:
        raise ConfigError(f"unknown colour mode {colors!r}; choose one of "
                          f"{', '.join(COLOR_MODES)}")
    if colors != "auto":
        return colors
    if src.info.color_space is not None:
        return src.info.color_space
    return "display" if src.info.n_rest > 0 else "linear"


@torch.no_grad()
def render_map_view(src: MapSource, *, frame: int | None = None, pose: np.ndarray | None = None,
                    camera: Intrinsics | None = None, exposure: bool = False,
                    colors: str = "auto", backend: str = "auto") -> tuple[np.ndarray, str]:
    """Render the map from one camera into an 8-bit image.

    Args:
        src: from :func:`open_map`.
        frame: render at the estimated pose of this frame of the source's run.
        pose: camera-to-world pose [4, 4] (excludes ``frame``). Neither: a view framing the map.
        camera: intrinsics; default the run's camera from the appearance file (required when
            there is none).
        exposure: apply ``frame``'s exposure compensation (the observed frame's brightness;
            the run's own renders do not).
        colors: without an appearance: ``auto``, ``linear`` (sRGB-encode) or ``display``.
        backend: rasteriser backend.

    Returns:
        (uint8 image [H, W, 3], a one-line description of the colour path used).

    Raises:
        ConfigError: inconsistent options.
    """
    from egs_bench.render.demo import frame_map, srgb8

    app = src.appearance
    if frame is not None and pose is not None:
        raise ConfigError("give --frame or --pose, not both")
    if exposure and (app is None or frame is None):
        raise ConfigError("--exposure needs --frame and the run's appearance file")
    if app is not None and colors != "auto":
        raise ConfigError("--colors applies to maps rendered without an appearance file")
    if camera is None:
        if app is None:
            raise ConfigError("no camera: give the image size and field of view, or an "
                              "appearance file")
        camera = app.camera
    if frame is not None:
        pose = frame_pose(src, frame)
    if pose is None:
        pose = frame_map(src.gmap, camera.width, camera.height)[0]
    gmap = src.gmap
    view = torch.tensor(np.linalg.inv(np.asarray(pose, dtype=np.float64))[None],
                        dtype=gmap.dtype)
    K = torch.tensor(camera.K[None], dtype=gmap.dtype)  # noqa: N806
    kwargs = {"near_plane": app.near_plane} if app is not None else {}
    hdr = gmap.render(view, K, camera.width, camera.height, backend=backend, **kwargs).rgb[0]
    if app is not None:
        ab = app.exposure_of(frame) if exposure else None
        what = f"linear map through the run's {crf_to_dict(app.crf)['kind']} CRF"
        if ab is not None:
            what += f" and frame {frame}'s exposure (a={ab[0]:.4f}, b={ab[1]:.4f})"
        return ldr8(app.crf, hdr, ab), what
    space = color_space(src, colors)
    if space == "linear":
        return srgb8(hdr.cpu().numpy()), "linear colours, sRGB-encoded (no CRF)"
    img = (hdr.clamp(0, 1).cpu().numpy() * 255.0 + 0.5).astype(np.uint8)
    return img, "display colours, shown as they are"


def display_colors(gmap: GaussianMap, appearance: Appearance) -> torch.Tensor:
    """Per-Gaussian display colour [N, 3] in [0, 1]: the run's CRF of the linear colour."""
    with torch.no_grad():
        return appearance.crf(gmap.colors.detach()).clamp(0, 1)


def export_display_ply(src: MapSource, out: str | Path, *, overwrite: bool = False) -> Path:
    """Write the source's map as a display-space 3DGS ``.ply`` (SH degree 3, zero
    ``f_rest_*``; colours through the run's CRF; opacity logits, log scales and ``(w, x, y, z)``
    quaternions as in the map), atomically.

    Raises:
        InputError: no appearance file (the CRF is unknown), colours already display values,
            or ``out`` exists and ``overwrite`` is false.
    """
    out = Path(out)
    if src.appearance is None:
        raise InputError(src.ply, f"needs the run's {APPEARANCE_FILE} (its CRF) to export "
                                  "display colours: pass a run folder or --appearance")
    if out.exists() and not overwrite:
        raise InputError(out, "exists (pass --overwrite to replace it)")
    if out.resolve() == src.ply.resolve():
        raise InputError(out, "is the source map itself: choose another output path")
    gmap = src.gmap.clone()
    gmap.colors = display_colors(src.gmap, src.appearance).to(gmap.dtype)
    save_ply(gmap, out, sh_degree=3, color_space="display")
    return out
