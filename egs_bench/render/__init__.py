"""Gaussian map and differentiable Gaussian rasteriser (docs/design.md §5).

* :func:`rasterize` renders N Gaussians into C pinhole cameras (gsplat 1.5.3-style API) with
  gradients to every Gaussian parameter and to the world-to-camera matrices; backends
  "numba" (CPU tile kernels), "gsplat" (CUDA) and "reference" (dense PyTorch oracle).
* :class:`GaussianMap` holds the optimisable parameters, inserts Gaussians from depth
  images and prunes; :mod:`egs_bench.render.ply` saves and loads it as a standard 3DGS
  ``.ply`` file.
* :mod:`egs_bench.render.constants` is the per-pixel rule shared by all backends.
"""

from egs_bench.render import constants
from egs_bench.render.gaussian_map import GaussianMap
from egs_bench.render.projection import Projected, project_gaussians, quat_to_rotmat
from egs_bench.render.rasterize import RasterResult, rasterize, resolve_backend

__all__ = [
    "GaussianMap",
    "Projected",
    "RasterResult",
    "constants",
    "project_gaussians",
    "quat_to_rotmat",
    "rasterize",
    "resolve_backend",
]
