"""Portable maps: render a saved map as its run did, and export it for other 3DGS tools.

* :func:`open_map` reads a run folder (``map.ply`` + ``appearance.json`` + ``trajectory.txt``)
  or a ``.ply`` with an optional appearance file.
* :func:`render_map_view` renders it at a run's frame or any pose. With the run's appearance
  the colours go through the run's CRF exactly as the run rendered them, so at a run's own pose
  it reproduces the run's render (same map, pose, camera, near plane and CRF). Without one the
  colours are shown according to the file's colour space (linear: sRGB-encoded; display: as
  they are).
* :func:`export_display_ply` writes a display-space 3DGS ``.ply`` (SH degree 3 with zero
  ``f_rest_*``) for the INRIA loader, gsplat and viewers. A 3DGS renderer blends the Gaussians'
  colours linearly and clamps only the final pixel to [0, 1], while the run applies its CRF to
  the blended pixel. So each colour goes through :func:`blend_response`: the CRF's
  piecewise-linear curve, continued as a straight line below 0 and above 1, and never clamped
  per Gaussian. Where the curve is one straight line (the identity start of the learnable CRF,
  the ``identity`` response) blending and the curve commute: a bright HDR Gaussian still
  saturates the blended pixel, as in the run, and the export reproduces the run's renders up to
  float32 rounding. Where the curve bends (a learned or sRGB-shaped curve), Gaussians mixed in
  one pixel from different segments of the curve differ from the run; no per-Gaussian colour
  can avoid that. The INRIA renderer also clamps each Gaussian's colour at 0 (gsplat does not),
  so a map with negative linear colours loses a little there (BENCHMARKS.md, portable maps).
"""

from __future__ import annotations

import contextlib
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from egs_bench.errors import ConfigError, InputError
from egs_bench.geometry import Intrinsics
from egs_bench.render.gaussian_map import GaussianMap
from egs_bench.render.ply import PlyInfo, read_ply, save_ply
from egs_bench.slam.appearance import APPEARANCE_FILE, MAP_FILE, Appearance, ldr8, read_appearance
from egs_bench.slam.crf import (
    CameraResponse,
    FixedSRGBCRF,
    IdentityCRF,
    LeakyPiecewiseLinearCRF,
    crf_to_dict,
)

COLOR_MODES = ("auto", "linear", "display")
# derivatives of the IEC 61966-2-1 encoding: 12.92 on the linear toe, (1.055 / 2.4) at 1
SRGB_SLOPE_AT_0 = 12.92
SRGB_SLOPE_AT_1 = 1.055 / 2.4


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


# Peak memory of a render per output pixel (colour, depth, alpha, the tile lists and the
# 8-bit image): 63 bytes measured for a numba render of 3000 x 3000 pixels.
_RENDER_BYTES_PER_PIXEL = 64


def _available_memory_bytes() -> int:
    """The memory a new allocation can take without swapping (``MemAvailable`` of
    ``/proc/meminfo``; elsewhere the free physical pages)."""
    with contextlib.suppress(OSError, ValueError, StopIteration):
        with open("/proc/meminfo", encoding="ascii") as f:
            line = next(x for x in f if x.startswith("MemAvailable:"))
        return int(line.split()[1]) * 1024
    return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")


def _require_memory_for(width: int, height: int) -> None:
    """Refuse an image size whose render cannot fit in memory, before anything is allocated.

    Raises:
        ConfigError: naming ``--width`` and ``--height``, the memory needed and available.
    """
    need = width * height * _RENDER_BYTES_PER_PIXEL
    have = _available_memory_bytes()
    if need > have:
        raise ConfigError(f"--width {width} x --height {height}: rendering this image needs "
                          f"about {need / 2**30:.1f} GiB of memory, and "
                          f"{have / 2**30:.1f} GiB is available")


def view_camera(base: Intrinsics | None, *, width: int | None = None,
                height: int | None = None, fov_deg: float | None = None,
                fx: float | None = None, fy: float | None = None, cx: float | None = None,
                cy: float | None = None) -> Intrinsics | None:
    """The camera of a view from the render options, or None to keep ``base`` as it is.

    Either a horizontal field of view (square pixels) or focal lengths in pixels; the
    principal point defaults to the image centre. The pixel convention is egs-bench's and
    gsplat's (pixel ``u`` covers ``[u, u + 1)``; an OpenCV calibration's ``cx`` is this
    ``cx - 0.5``, docs/design.md §2).

    Args:
        base: the run's camera (from its appearance file), or None.
        width, height: image size in pixels (default: ``base``'s, else 640 x 480).
        fov_deg: horizontal field of view, degrees (excludes ``fx`` / ``fy``).
        fx, fy: focal lengths in pixels (``fy`` defaults to ``fx`` and needs it).
        cx, cy: principal point in pixels (default: the image centre).

    Raises:
        ConfigError: both a field of view and focal lengths, ``fy`` without ``fx``, a value
            that is not a positive finite number, a principal point outside the image, or an
            image whose render cannot fit in the memory available.
    """
    given = {"--fx": fx, "--fy": fy, "--cx": cx, "--cy": cy, "--fov": fov_deg}
    if all(v is None for v in (width, height, *given.values())):
        return base
    for name, v in given.items():
        if v is not None and not np.isfinite(v):
            raise ConfigError(f"{name} must be a finite number, got {v}")
    if fov_deg is not None and (fx is not None or fy is not None):
        raise ConfigError("give --fov or --fx/--fy, not both")
    if fy is not None and fx is None:
        raise ConfigError("--fy needs --fx")
    for name, v in (("--fx", fx), ("--fy", fy)):
        if v is not None and v <= 0:
            raise ConfigError(f"{name} must be positive, got {v}")
    same_size = base is not None and width in (None, base.width) and height in (None,
                                                                                base.height)
    w = width or (base.width if base is not None else 640)
    h = height or (base.height if base is not None else 480)
    if fx is None:
        if fov_deg is None and same_size and base is not None:
            fx_, fy_ = base.fx, base.fy  # only the principal point changes
        else:
            fx_ = fy_ = 0.5 * w / np.tan(np.radians(fov_deg or 60.0) / 2)
    else:
        fx_, fy_ = fx, fy if fy is not None else fx
    keep_pp = base is not None and same_size and fx is None and fov_deg is None
    cx_ = cx if cx is not None else (base.cx if keep_pp and base is not None else w / 2)
    cy_ = cy if cy is not None else (base.cy if keep_pp and base is not None else h / 2)
    if not (0 <= cx_ <= w and 0 <= cy_ <= h):
        raise ConfigError(f"principal point ({cx_}, {cy_}) is outside the {w}x{h} image")
    _require_memory_for(w, h)
    return Intrinsics(float(fx_), float(fy_), float(cx_), float(cy_), int(w), int(h))


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
    from egs_bench.color import linear_to_srgb8
    from egs_bench.render.gaussian_map import frame_map

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
    K = torch.tensor(camera.K[None], dtype=gmap.dtype)
    kwargs = {"near_plane": app.near_plane} if app is not None else {}
    hdr = gmap.render(view, K, camera.width, camera.height, backend=backend, **kwargs).rgb[0]
    if app is not None:
        ab = app.exposure_of(frame) if exposure and frame is not None else None
        what = f"linear map through the run's {crf_to_dict(app.crf)['kind']} CRF"
        if ab is not None:
            what += f" and frame {frame}'s exposure (a={ab[0]:.4f}, b={ab[1]:.4f})"
        return ldr8(app.crf, hdr, ab), what
    space = color_space(src, colors)
    if space == "linear":
        return linear_to_srgb8(hdr.cpu().numpy()), "linear colours, sRGB-encoded (no CRF)"
    img = (hdr.clamp(0, 1).cpu().numpy() * 255.0 + 0.5).astype(np.uint8)
    return img, "display colours, shown as they are"


@torch.no_grad()
def blend_response(crf: CameraResponse, linear: torch.Tensor) -> torch.Tensor:
    """The curve applied to each Gaussian's linear colour in a display-space export, [...].

    The run's response inside [0, 1], continued as a straight line outside it (the learnable
    curve: its first and last segments; sRGB: its tangents at 0 and 1) instead of the leaky
    saturation, and not clamped. Blending weights sum to at most 1, so a blended pixel above 1
    (an HDR Gaussian) is clamped to white by the renderer, as the run's saturating curve
    followed by its 8-bit clamp does; a clamp per Gaussian would darken it instead.

    Args:
        crf: the run's camera response.
        linear: linear colours (any shape).

    Returns:
        display colours, same shape and dtype.
    """
    if isinstance(crf, IdentityCRF):
        return linear.clone()
    if isinstance(crf, LeakyPiecewiseLinearCRF):
        curve = crf.frozen()
        inner = curve.inner.to(linear.dtype)
        # bucketize without clamping the input: below the first node segment 0 is used, above
        # the last one the last segment, so both ends continue their segment's line
        idx = torch.bucketize(linear, inner, right=True)
        return linear * curve.slope.to(linear.dtype)[idx] + curve.intercept.to(linear.dtype)[idx]
    if isinstance(crf, FixedSRGBCRF):
        inside = crf(linear.clamp(0.0, 1.0))
        low = linear * SRGB_SLOPE_AT_0
        high = 1.0 + (linear - 1.0) * SRGB_SLOPE_AT_1
        return torch.where(linear < 0, low, torch.where(linear > 1, high, inside))
    raise ConfigError(f"cannot export colours through a CRF of type {type(crf).__name__}")


def display_colors(gmap: GaussianMap, appearance: Appearance) -> torch.Tensor:
    """Per-Gaussian display colour [N, 3] (unclamped): :func:`blend_response` of the linear
    colour."""
    return blend_response(appearance.crf, gmap.colors.detach())


def export_display_ply(src: MapSource, out: str | Path, *, overwrite: bool = False) -> Path:
    """Write the source's map as a display-space 3DGS ``.ply`` (SH degree 3, zero
    ``f_rest_*``; colours through :func:`blend_response` of the run's CRF, unclamped; opacity
    logits, log scales and ``(w, x, y, z)`` quaternions as in the map), atomically.

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
