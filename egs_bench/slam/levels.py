"""Coarse-to-fine schedules: the first iterations of a tracking call or a mapping round run
at a lower resolution, the rest at the internal one.

A coarse level of scale ``s`` renders ``s^2`` of the pixels, so those iterations cost about
``s^2`` of the blends (each Gaussian covers ``s^2`` of the pixels it covered). Coarse images
are area averages of the internal ones, and the rasteriser's low-pass dilation is scaled to
``EPS2D s^2`` pixels^2 so that a Gaussian keeps its extent in the scene: with the dilation of
0.3 coarse pixels^2 every Gaussian looked wider at the coarse level than at the fine one.

A coarse level may also render fewer sub-poses of the blur model (``budget.*_coarse_segments``):
a blur of ``b`` pixels spans ``s b`` pixels there, so ``Kc < K`` segments describe it. The
level keeps ``Kc + 1`` of the ``K + 1`` sub-poses, the first and the last among them
(:func:`kept_subposes`), and each of its segments holds the events of the fine segments it
spans, so the event model stays exact: the log change over a merged segment is the sum of the
changes over its parts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from egs_bench.geometry import Intrinsics
from egs_bench.render import constants as RC


@dataclass(frozen=True)
class Level:
    """One resolution of a coarse-to-fine schedule.

    Attributes:
        scale: fraction of the internal resolution (1.0: the internal level itself).
        cam: intrinsics at this level.
        K: ``cam``'s [3, 3] float32 intrinsic matrix on the run's device.
        eps2d: the rasteriser's 2-D dilation at this level (pixels^2).
        edge_blocks: the edge mask's grid at this level (None: one global threshold).
    """

    scale: float
    cam: Intrinsics
    K: torch.Tensor
    eps2d: float
    edge_blocks: int | None


def level_eps2d(scale: float) -> float:
    """The dilation at ``scale`` that keeps the internal level's in scene units."""
    return RC.EPS2D * scale * scale


def level_edge_blocks(edge_blocks: int | None, scale: float) -> int | None:
    """Edge-mask blocks of the same size in the scene as ``edge_blocks`` at scale 1."""
    return None if edge_blocks is None else max(1, round(edge_blocks * scale))


def coarse_iterations(iterations: int, scale: float, fraction: float) -> int:
    """How many of ``iterations`` run at the coarse level: ``round(fraction x iterations)``,
    but never the last one, so every call and round ends at the internal resolution (0 when
    ``scale`` is 1)."""
    if scale >= 1.0 or fraction <= 0.0:
        return 0
    return max(0, min(iterations - 1, int(round(iterations * fraction))))


def kept_subposes(n_segments: int, coarse_segments: int | None) -> np.ndarray:
    """Indices [Kc + 1] into the ``K + 1 = n_segments + 1`` sub-poses that a coarse level with
    ``coarse_segments`` (Kc) segments renders: evenly spread, first and last always kept; every
    index when ``coarse_segments`` is None or not below ``n_segments``.

    >>> kept_subposes(3, 1).tolist(), kept_subposes(4, 2).tolist(), kept_subposes(3, 2).tolist()
    ([0, 3], [0, 2, 4], [0, 2, 3])
    """
    if coarse_segments is None or coarse_segments >= n_segments:
        return np.arange(n_segments + 1)
    return np.floor(np.arange(coarse_segments + 1) * n_segments / coarse_segments
                    + 0.5).astype(np.int64)
