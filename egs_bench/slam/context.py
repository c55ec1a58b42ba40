"""What every SLAM component needs to know about the run, built once per run.

The tracker, the mapper and the keyframe policy all work at the same internal resolution, with
the same intrinsics, device, rasteriser backend, event model and exposure times. They get them
from one :class:`SlamContext` instead of a dozen positional arguments each.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import torch

from egs_bench.datasets.sequence_view import SequenceView
from egs_bench.geometry import Intrinsics
from egs_bench.render import GaussianMap
from egs_bench.render.gaussian_map import FrozenGaussians
from egs_bench.render.rasterize import RasterResult
from egs_bench.render.work import counting
from egs_bench.slam.config import SlamConfig
from egs_bench.slam.frames import internal_intrinsics
from egs_bench.slam.levels import Level, level_edge_blocks, level_eps2d
from egs_bench.slam.loss_terms import LOSS_TERMS, LossTerm
from egs_bench.slam.render_model import render_views
from egs_bench.slam.work import Phase, WorkLedger


@dataclass(frozen=True)
class SlamContext:
    """The fixed facts of one SLAM run.

    Attributes:
        cfg: the validated configuration.
        cam: intrinsics at the internal processing resolution (``budget.resolution_scale``).
        K: ``cam``'s intrinsic matrix [3, 3], float32 on ``device``.
        device: where maps and images live.
        theta: event thresholds ``(C+, C-)`` of the event loss (log-intensity units): the
            method's ``theta`` when set, else the sequence's.
        eps: the log offset of the event model, ``log(luma + eps)`` (the sequence's).
        exposure_starts_us, exposure_ends_us: every frame's exposure window, int64 [N]
            microseconds.
        loss_terms: the terms of the tracking and mapping loss
            (:mod:`egs_bench.slam.loss_terms`).
        work: the rendering work of the run, by frame and phase (every :meth:`render`).
    """

    cfg: SlamConfig
    cam: Intrinsics
    K: torch.Tensor
    device: torch.device
    theta: tuple[float, float]
    eps: float
    exposure_starts_us: np.ndarray
    exposure_ends_us: np.ndarray
    loss_terms: tuple[LossTerm, ...] = LOSS_TERMS
    work: WorkLedger = field(default_factory=WorkLedger)
    _levels: dict[float, Level] = field(default_factory=dict)

    @classmethod
    def build(cls, seq: SequenceView, cfg: SlamConfig, device: str | torch.device = "cpu",
              loss_terms: tuple[LossTerm, ...] = LOSS_TERMS) -> SlamContext:
        """The context of running ``cfg`` on ``seq`` (an opened sequence, or a view of one)."""
        dev = torch.device(device)
        cam = internal_intrinsics(seq.intrinsics, cfg.budget.resolution_scale)
        if cfg.method.theta is not None:
            theta = (float(cfg.method.theta), float(cfg.method.theta))
        else:
            theta = (float(seq.pos_threshold), float(seq.neg_threshold))
        windows = np.array([seq.exposure(i) for i in range(len(seq))], dtype=np.int64)
        windows = windows.reshape(-1, 2)
        return cls(cfg, cam, torch.tensor(cam.K, dtype=torch.float32, device=dev), dev, theta,
                   float(seq.eps), windows[:, 0].copy(), windows[:, 1].copy(), loss_terms)

    @property
    def width(self) -> int:
        return self.cam.width

    @property
    def height(self) -> int:
        return self.cam.height

    def exposure(self, i: int) -> tuple[int, int]:
        """Frame ``i``'s exposure window ``(t_start_us, t_end_us)``."""
        return int(self.exposure_starts_us[i]), int(self.exposure_ends_us[i])

    def level(self, scale: float) -> Level:
        """The coarse-to-fine level at ``scale`` x the internal resolution (1.0: internal)."""
        if scale not in self._levels:
            if scale >= 1.0:
                cam, K = self.cam, self.K
            else:
                cam = internal_intrinsics(self.cam, scale)
                K = torch.tensor(cam.K, dtype=torch.float32, device=self.device)
            self._levels[scale] = Level(min(scale, 1.0), cam, K,
                                        level_eps2d(min(scale, 1.0)),
                                        level_edge_blocks(self.cfg.budget.edge_blocks, scale))
        return self._levels[scale]

    def render(self, gmap: GaussianMap | FrozenGaussians, viewmats: torch.Tensor | np.ndarray,
               *, phase: Phase, scale: float = 1.0, visibility: bool = False) -> RasterResult:
        """Render world-to-camera ``viewmats`` [C, 4, 4] at ``scale`` x the internal
        resolution (see :func:`~egs_bench.slam.render_model.render_views`), booking the work
        into ``phase`` of the current frame (:attr:`work`)."""
        lvl = self.level(scale)
        with counting(self.work.record(phase)):
            return render_views(gmap, viewmats, lvl.K, lvl.cam.width, lvl.cam.height,
                                self.cfg, visibility=visibility, eps2d=lvl.eps2d)
