"""The work a SLAM run did, by frame and by phase, in the rasteriser's counts.

:class:`WorkLedger` holds one :class:`~egs_bench.render.work.RenderWork` per frame and phase;
:meth:`SlamContext.render <egs_bench.slam.context.SlamContext.render>` books every render into
the current frame's record of the phase it names. The run writes :meth:`WorkLedger.summary`
into ``slam_stats.json`` as its ``work`` section: a yardstick of cost that does not depend on
the machine (wall time does), which the frontier benchmark and the GPU cost model read.
"""

from __future__ import annotations

from typing import Any, Literal

from egs_bench.render.work import RenderWork

Phase = Literal["init", "tracking", "mapping", "selection", "refinement"]
#: init: frame 0's map building; tracking: pose estimation; mapping: keyframe rounds;
#: selection: the renders that decide keyframes and windows; refinement: after the last frame
PHASES: tuple[Phase, ...] = ("init", "tracking", "mapping", "selection", "refinement")


class WorkLedger:
    """Rendering work per frame and phase (``frames[i][phase]``) and after the last frame."""

    def __init__(self) -> None:
        self.frames: list[dict[str, RenderWork]] = []
        self.after_frames: dict[str, RenderWork] = {}
        self._current: dict[str, RenderWork] | None = None

    def begin_frame(self, index: int) -> None:
        """Book what follows into frame ``index`` (frames start at 0, one after another)."""
        while len(self.frames) <= index:
            self.frames.append({})
        self._current = self.frames[index]

    def end_frames(self) -> None:
        """Book what follows (the final refinement) after the frames."""
        self._current = self.after_frames

    def record(self, phase: Phase) -> RenderWork:
        """The record of ``phase`` in the current frame (before any frame: frame 0)."""
        if self._current is None:
            self.begin_frame(0)
        assert self._current is not None
        return self._current.setdefault(phase, RenderWork())

    def summary(self) -> dict[str, Any]:
        """``slam_stats.json``'s ``work`` section: per frame and phase, the totals by phase,
        and the mean per frame after frame 0 (the steady state: tracking and mapping)."""
        def total(records: list[dict[str, RenderWork]], phase: str | None = None) -> RenderWork:
            out = RenderWork()
            for rec in records:
                for name, work in rec.items():
                    if phase is None or name == phase:
                        out.add(work)
            return out

        everything = self.frames + [self.after_frames]
        later = self.frames[1:]
        mean = total(later).to_dict()
        per_frame_after_init = {k: (v / len(later) if v is not None and later else None)
                                for k, v in mean.items()}
        return {
            "unit": "counts of the rasteriser's work (egs_bench.render.work)",
            "per_frame": [{p: rec[p].to_dict() for p in PHASES if p in rec}
                          for rec in self.frames],
            "after_frames": {p: w.to_dict() for p, w in self.after_frames.items()},
            "by_phase": {p: total(everything, p).to_dict() for p in PHASES},
            "total": total(everything).to_dict(),
            "per_frame_after_init": per_frame_after_init,
        }
