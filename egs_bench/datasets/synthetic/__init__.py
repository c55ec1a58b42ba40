"""Built-in procedural indoor scenes, ray-cast analytically, as a latent source for the
generation pipeline (:mod:`egs_bench.datasets.pipeline`).

Public API: :func:`list_scenes`, :func:`build_scene`, :class:`SyntheticSource`,
:func:`make_synthetic`, :class:`HandheldTrajectory`, :class:`TumTrajectoryInRoom`,
:class:`Renderer`.
"""

from egs_bench.datasets.synthetic.raycast import Renderer
from egs_bench.datasets.synthetic.scene import Scene, pack_scene
from egs_bench.datasets.synthetic.scenes import SCENES, build_scene, list_scenes
from egs_bench.datasets.synthetic.source import (
    SyntheticSource,
    default_intrinsics,
    exposure_windows,
    make_synthetic,
)
from egs_bench.datasets.synthetic.trajectory import (
    HandheldTrajectory,
    TumTrajectoryInRoom,
    look_at,
)

__all__ = [
    "SCENES",
    "HandheldTrajectory",
    "Renderer",
    "Scene",
    "SyntheticSource",
    "TumTrajectoryInRoom",
    "build_scene",
    "default_intrinsics",
    "exposure_windows",
    "list_scenes",
    "look_at",
    "make_synthetic",
    "pack_scene",
]
