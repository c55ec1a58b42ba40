"""``appearance.json``: what a run folder needs, besides ``map.ply`` and ``trajectory.txt``, to
reproduce its renders from the map.

The map holds linear (HDR) radiance. A run's render of frame ``i`` is
``round(255 * clamp(CRF(R(T_i)), 0, 1))`` where ``R(T_i)`` is the rasterised map at the frame's
estimated pose ``T_i`` (exposure end) with the run's camera and near plane, and ``CRF`` the
run's camera response. Tracking and mapping also fit per-frame exposure compensation
``exp(a_i) * CRF(R) + b_i`` (MonoGS): it models the brightness of the *observed* frame, so it is
stored but not part of the renders (they are compared with the sharp ground truth).

File content (JSON, written atomically)::

    {"format": "egs-bench-appearance", "version": 1,
     "map": "map.ply", "map_colors": "linear",
     "crf": {"kind": "learnable", "alpha": 0.01, "gap_logits": [...],
             "nodes_hdr": [...], "levels_ldr": [...]}        (or {"kind": "srgb" | "identity"})
     "camera": {"fx", "fy", "cx", "cy", "width", "height"},  (the renders' camera, pixels)
     "near_plane": 0.2,
     "render": "ldr = clamp(crf(hdr), 0, 1); png = floor(255 ldr + 0.5)",
     "renders_apply_exposure": false,
     "exposure": {"model": "exp(a) * crf(hdr) + b",
                  "frame": [0, 1, ...], "timestamp_s": [...], "a": [...], "b": [...]}}

``crf`` is described in :func:`egs_bench.slam.crf.crf_to_dict`.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from egs_bench.errors import ConfigError, InputError
from egs_bench.fileio import write_text_atomic
from egs_bench.geometry import Intrinsics
from egs_bench.slam.crf import CameraResponse, crf_from_dict, crf_to_dict

APPEARANCE_FILE = "appearance.json"
MAP_FILE = "map.ply"
FORMAT = "egs-bench-appearance"
VERSION = 1


@dataclass
class Appearance:
    """Content of ``appearance.json`` (see the module docstring).

    Attributes:
        crf: the run's camera response (HDR -> LDR).
        camera: intrinsics of the run's renders (the sequence's full resolution).
        near_plane: rasteriser near plane, metres.
        frames: frame indices with exposure parameters, [N] int64.
        timestamps_s: their exposure-end times, [N] seconds.
        exposure_a, exposure_b: per-frame exposure compensation ``exp(a) ldr + b``, [N].
        renders_apply_exposure: whether the run's renders include the exposure compensation.
    """

    crf: CameraResponse
    camera: Intrinsics
    near_plane: float
    frames: np.ndarray
    timestamps_s: np.ndarray
    exposure_a: np.ndarray
    exposure_b: np.ndarray
    renders_apply_exposure: bool = False

    def exposure_of(self, frame: int) -> tuple[float, float]:
        """``(a, b)`` of frame ``frame``; raises :class:`ConfigError` if the run has none."""
        hit = np.flatnonzero(self.frames == int(frame))
        if len(hit) == 0:
            raise ConfigError(f"frame {frame} has no exposure parameters (the run has frames "
                              f"{int(self.frames.min())}..{int(self.frames.max())})")
        return float(self.exposure_a[hit[0]]), float(self.exposure_b[hit[0]])

    def to_dict(self) -> dict[str, Any]:
        """The JSON content."""
        return {
            "format": FORMAT, "version": VERSION, "map": MAP_FILE, "map_colors": "linear",
            "crf": crf_to_dict(self.crf), "camera": self.camera.to_dict(),
            "near_plane": float(self.near_plane),
            "render": "ldr = clamp(crf(hdr), 0, 1); png = floor(255 ldr + 0.5)",
            "renders_apply_exposure": bool(self.renders_apply_exposure),
            "exposure": {"model": "exp(a) * crf(hdr) + b",
                         "frame": [int(v) for v in self.frames],
                         "timestamp_s": [float(v) for v in self.timestamps_s],
                         "a": [float(v) for v in self.exposure_a],
                         "b": [float(v) for v in self.exposure_b]},
        }


def write_appearance(path: str | Path, appearance: Appearance) -> None:
    """Write ``appearance`` to ``path`` as JSON, atomically."""
    write_text_atomic(path, json.dumps(appearance.to_dict(), indent=1) + "\n")


def read_appearance(path: str | Path) -> Appearance:
    """Read an ``appearance.json``.

    Raises:
        InputError: missing, not JSON, not this format, or malformed fields (names the file).
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "appearance file not found")
    try:
        data = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(path, f"not valid JSON ({exc})") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise InputError(path, f"not an egs-bench appearance file (no 'format: {FORMAT}')")
    if data.get("version") != VERSION:
        raise InputError(path, f"appearance version {data.get('version')!r} is not supported "
                               f"(this egs-bench reads version {VERSION})")
    try:
        crf = crf_from_dict(data["crf"])
        cam = data["camera"]
        camera = Intrinsics(float(cam["fx"]), float(cam["fy"]), float(cam["cx"]),
                            float(cam["cy"]), int(cam["width"]), int(cam["height"]))
        exp = data["exposure"]
        frames = np.asarray(exp["frame"], dtype=np.int64)
        arrays = [np.asarray(exp[k], dtype=np.float64) for k in ("timestamp_s", "a", "b")]
        near = float(data["near_plane"])
    except ConfigError as exc:
        raise InputError(path, f"bad 'crf': {exc}") from None
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(path, f"malformed field ({type(exc).__name__}: {exc})") from None
    if any(a.shape != frames.shape for a in arrays) or frames.ndim != 1:
        raise InputError(path, "'exposure' lists must have one entry per frame")
    if camera.width < 1 or camera.height < 1:
        raise InputError(path, f"bad camera size {camera.width}x{camera.height}")
    return Appearance(crf, camera, near, frames, arrays[0], arrays[1], arrays[2],
                      bool(data.get("renders_apply_exposure", False)))


@torch.no_grad()
def ldr8(crf: CameraResponse, hdr: torch.Tensor,
         exposure: tuple[float, float] | None = None) -> np.ndarray:
    """8-bit render of linear radiance: ``round(255 clamp(CRF(hdr), 0, 1))``.

    Args:
        crf: camera response.
        hdr: rendered linear RGB [H, W, 3].
        exposure: optional ``(a, b)``: ``exp(a) CRF(hdr) + b`` before the clamp (the observed
            frame's brightness).

    Returns:
        uint8 [H, W, 3].
    """
    ldr = crf(hdr)
    if exposure is not None:
        a, b = exposure
        ldr = torch.exp(torch.tensor(a, dtype=ldr.dtype, device=ldr.device)) * ldr + b
    ldr = ldr.clamp(0, 1)
    return (ldr.cpu().numpy() * 255.0 + 0.5).astype(np.uint8)
