"""Save/load a :class:`GaussianMap` as a standard 3DGS ``.ply`` (binary little endian).

Vertex properties, in the order the 3DGS reference code writes them (so common viewers such as
SuperSplat or the antimatter15 web viewer open the file): ``x y z nx ny nz f_dc_0 f_dc_1 f_dc_2
opacity scale_0 scale_1 scale_2 rot_0 rot_1 rot_2 rot_3``.

* ``opacity`` is the logit, ``scale_*`` the log standard deviations, ``rot_*`` the quaternion
  ``(w, x, y, z)``: the same raw parameters as the map.
* Colour: the map's **linear** RGB is stored as the degree-0 spherical-harmonic coefficient with
  the standard convention ``rgb = 0.5 + C0 * f_dc``, ``C0 = 0.28209479177387814``. Viewers show
  those values as display RGB, so an HDR/linear map looks darker than an sRGB one; values above
  1 are kept in the file and clipped by viewers.
* There are no ``f_rest_*`` properties (SH degree 0). On load, higher-order SH are ignored.
* ``keyframe_ids`` are not stored (they are -1 after loading).
"""

from __future__ import annotations

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


def rgb_to_sh0(rgb: np.ndarray) -> np.ndarray:
    """Degree-0 SH coefficient for colour ``rgb`` (any shape)."""
    return (rgb - 0.5) / SH_C0


def sh0_to_rgb(f_dc: np.ndarray) -> np.ndarray:
    """Colour of degree-0 SH coefficient ``f_dc`` (any shape)."""
    return f_dc * SH_C0 + 0.5


def save_ply(gmap: GaussianMap, path: str | Path) -> None:
    """Write ``gmap`` to ``path`` atomically as a float32 3DGS ``.ply``."""
    n = len(gmap)

    def a(t: torch.Tensor) -> np.ndarray:
        return t.detach().cpu().to(torch.float64).numpy().reshape(n, -1)

    cols = np.concatenate(
        [a(gmap.means), np.zeros((n, 3)), rgb_to_sh0(a(gmap.colors)), a(gmap.opacity_logits),
         a(gmap.log_scales), a(gmap.quats)], axis=1,
    ).astype(np.float32)
    vertex = np.empty(n, dtype=[(f, "<f4") for f in _FIELDS])
    for i, f in enumerate(_FIELDS):
        vertex[f] = cols[:, i]
    with atomic_path(path) as tmp:
        PlyData([PlyElement.describe(vertex, "vertex")], byte_order="<").write(str(tmp))


def load_ply(path: str | Path, dtype: torch.dtype = torch.float32) -> GaussianMap:
    """Read a 3DGS ``.ply``; raises :class:`InputError` naming the file if it is not one."""
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
    return gmap
