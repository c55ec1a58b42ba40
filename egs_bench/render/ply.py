"""Save/load a :class:`GaussianMap` as a ``.ply`` in the 3DGS property layout (binary little
endian).

Vertex properties, in the order the 3DGS reference code writes them: ``x y z
nx ny nz f_dc_0 f_dc_1 f_dc_2 [f_rest_0 .. f_rest_{3((d+1)^2-1)-1}] opacity scale_0 scale_1
scale_2 rot_0 rot_1 rot_2 rot_3``, all float32.

* ``opacity`` is the logit, ``scale_*`` the log standard deviations, ``rot_*`` the quaternion
  ``(w, x, y, z)``: the same raw parameters as the map.
* Colour is the degree-0 spherical-harmonic coefficient with the standard convention
  ``rgb = 0.5 + C0 * f_dc``, ``C0 = 0.28209479177387814``. A header comment
  ``egs-bench colors=linear|display`` says what the colours are: ``linear`` (the SLAM map's HDR
  radiance, may exceed 1; a run's ``map.ply``) or ``display`` (LDR values in [0, 1] that viewers
  show as they are; :func:`egs_bench.slam.map_export.export_display_ply`). Maps written before
  the comment existed are linear.
* ``sh_degree`` 0 (the SLAM map, a run's ``map.ply``) writes no ``f_rest_*``; degree ``d > 0``
  writes ``3((d+1)^2 - 1)`` zero coefficients in the INRIA channel-major order. The INRIA loader
  asserts exactly 45 (degree 3), so it opens only degree-3 files; with linear colours viewers
  also show a map too dark. A file for other 3DGS tools is therefore the display-space degree-3
  export (:func:`egs_bench.slam.map_export.export_display_ply`, ``egs-bench export-map``),
  which the INRIA loader, gsplat's ``load_ply_to_splats`` and viewers such as SuperSplat open.
  On load, higher-order SH are ignored.
* ``keyframe_ids`` are not stored (they are -1 after loading).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from plyfile import PlyData, PlyElement

from egs_bench.errors import InputError
from egs_bench.fileio import atomic_path
from egs_bench.render.gaussian_map import GaussianMap

SH_C0 = 0.28209479177387814
"""The degree-0 real spherical-harmonic basis constant, 1 / (2 sqrt(pi))."""

_FIELDS = (["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2", "opacity"]
           + [f"scale_{i}" for i in range(3)] + [f"rot_{i}" for i in range(4)])
COLOR_SPACES = ("linear", "display")
_COLOR_TAG = "egs-bench colors="


@dataclass(frozen=True)
class PlyInfo:
    """What a 3DGS ``.ply`` says about itself besides the Gaussians.

    Attributes:
        color_space: ``"linear"`` or ``"display"`` from the ``egs-bench colors=`` header
            comment, or ``None`` when the file has none (older egs-bench maps: linear; files
            from other 3DGS code: display).
        n_rest: number of ``f_rest_*`` properties (ignored on load).
        sh_degree: SH degree ``d`` with ``3((d+1)^2 - 1) = n_rest``, or ``None`` if none fits.
    """

    color_space: str | None
    n_rest: int
    sh_degree: int | None


def field_names(sh_degree: int = 0) -> list[str]:
    """Vertex property names of a 3DGS ``.ply`` of SH degree ``sh_degree``, in file order."""
    n_rest = 3 * ((sh_degree + 1) ** 2 - 1)
    return _FIELDS[:9] + [f"f_rest_{i}" for i in range(n_rest)] + _FIELDS[9:]


def rgb_to_sh0(rgb: np.ndarray) -> np.ndarray:
    """Degree-0 SH coefficient for colour ``rgb`` (any shape)."""
    return (rgb - 0.5) / SH_C0


def sh0_to_rgb(f_dc: np.ndarray) -> np.ndarray:
    """Colour of degree-0 SH coefficient ``f_dc`` (any shape)."""
    return f_dc * SH_C0 + 0.5


def save_ply(gmap: GaussianMap, path: str | Path, *, sh_degree: int = 0,
             color_space: str = "linear") -> None:
    """Write ``gmap`` to ``path`` atomically as a float32 ``.ply`` in the 3DGS layout.

    Args:
        sh_degree: SH degree of the file; the ``f_rest_*`` coefficients are zero (the map's
            colour does not depend on the viewing direction).
        color_space: what ``gmap.colors`` hold, ``"linear"`` or ``"display"`` (written as a
            header comment, see the module docstring).
    """
    if color_space not in COLOR_SPACES:
        raise ValueError(f"color_space must be one of {COLOR_SPACES}, got {color_space!r}")
    if sh_degree < 0:
        raise ValueError(f"sh_degree must be >= 0, got {sh_degree}")
    n = len(gmap)
    names = field_names(sh_degree)

    def a(t: torch.Tensor) -> np.ndarray:
        return t.detach().cpu().to(torch.float64).numpy().reshape(n, -1)

    n_rest = len(names) - len(_FIELDS)
    cols = np.concatenate(
        [a(gmap.means), np.zeros((n, 3)), rgb_to_sh0(a(gmap.colors)), np.zeros((n, n_rest)),
         a(gmap.opacity_logits), a(gmap.log_scales), a(gmap.quats)], axis=1,
    ).astype(np.float32)
    vertex = np.empty(n, dtype=[(f, "<f4") for f in names])
    for i, f in enumerate(names):
        vertex[f] = cols[:, i]
    ply = PlyData([PlyElement.describe(vertex, "vertex")], byte_order="<",
                  comments=[f"{_COLOR_TAG}{color_space}"])
    with atomic_path(path) as tmp:
        ply.write(str(tmp))


def load_ply(path: str | Path, dtype: torch.dtype = torch.float32) -> GaussianMap:
    """Read a ``.ply`` in the 3DGS layout; raises :class:`InputError` naming the file if it is
    not one."""
    return read_ply(path, dtype)[0]


def read_ply(path: str | Path, dtype: torch.dtype = torch.float32
             ) -> tuple[GaussianMap, PlyInfo]:
    """Read a 3DGS ``.ply`` and what its header says (:class:`PlyInfo`).

    Raises:
        InputError: missing or unreadable file, no ``vertex`` element, missing properties,
            non-finite values, or an unknown ``egs-bench colors=`` tag.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "no such file")
    try:
        ply = PlyData.read(str(path))
    except Exception as exc:  # plyfile raises several types for malformed headers/bodies
        raise InputError(path, f"not a readable PLY file ({exc})") from exc
    if "vertex" not in ply:
        raise InputError(path, "no 'vertex' element")
    v = ply["vertex"].data
    names = set(v.dtype.names or ())
    missing = [f for f in _FIELDS if f not in names and f not in ("nx", "ny", "nz")]
    if missing:
        raise InputError(path, f"not a 3DGS Gaussian PLY: missing properties {missing}")

    def col(*fs: str) -> torch.Tensor:
        arr = np.stack([np.asarray(v[f], dtype=np.float64) for f in fs], axis=-1)
        return torch.as_tensor(arr, dtype=dtype)

    gmap = GaussianMap(
        means=col("x", "y", "z"),
        quats=col("rot_0", "rot_1", "rot_2", "rot_3"),
        log_scales=col("scale_0", "scale_1", "scale_2"),
        opacity_logits=col("opacity")[:, 0],
        colors=torch.as_tensor(sh0_to_rgb(col("f_dc_0", "f_dc_1", "f_dc_2").numpy()),
                               dtype=dtype),
    )
    if not all(torch.isfinite(t).all() for t in gmap.parameters().values()):
        raise InputError(path, "non-finite values in Gaussian parameters")
    space = None
    for comment in ply.comments:
        if comment.startswith(_COLOR_TAG):
            space = comment[len(_COLOR_TAG):].strip()
            if space not in COLOR_SPACES:
                raise InputError(path, f"unknown colour space {space!r} in the header comment "
                                       f"(expected one of {', '.join(COLOR_SPACES)})")
    n_rest = sum(1 for f in names if f.startswith("f_rest_"))
    degree = next((d for d in range(8) if 3 * ((d + 1) ** 2 - 1) == n_rest), None)
    return gmap, PlyInfo(space, n_rest, degree)
