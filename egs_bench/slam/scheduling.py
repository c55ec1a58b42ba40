"""When mapping runs: after each keyframe (``sequential``) or beside the tracking of the frames
that follow it (``concurrent``), the ``mapping.mapping_mode`` setting.

Concurrent mapping is deterministic by schedule, not by timing. A keyframe's mapping round is
queued at the end of its frame; every later frame then runs a fixed slice of that round's
iterations (``budget.mapping_iters_per_frame``) in a worker thread, while the frame is tracked
against a snapshot of the map and the response curve taken when the slice started. The frame
waits for its slice before keyframe selection: a sync point per frame, so what is computed
never depends on which thread is faster. On CUDA the worker has its own stream, which waits
for the frame's work before it starts and is waited on at the sync point.

A keyframe that arrives while earlier rounds are still queued first finishes them (new
Gaussians must not be inserted into a map that an open round optimises); the last frame
finishes what is left.
"""

from __future__ import annotations

import copy
import math
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import ClassVar, Protocol

import torch

from egs_bench.render import GaussianMap
from egs_bench.slam.config import ScheduleConfig
from egs_bench.slam.crf import CameraResponse


@dataclass
class MapSnapshot:
    """What tracking reads while mapping changes the live map: copies of the map [N] and of
    the response curve."""

    gmap: GaussianMap
    crf: CameraResponse


class MapRound(Protocol):
    """A mapping round run in slices (:meth:`~egs_bench.slam.components.MapOptimiser.begin_round`):
    the map must not be edited from outside while it is open.

    Attributes:
        window: the keyframe window it optimises, newest first.
    """

    window: list[int]

    @property
    def remaining(self) -> int:
        """Iterations left (0 once it has run them all or stopped on a non-finite loss)."""
        ...

    def advance(self, n: int) -> None:
        """Run up to ``n`` more iterations."""
        ...

    def close(self) -> float:
        """End the round (the built-in mapper prunes here); returns its last loss."""
        ...


def iterations_per_frame(mapping_iters: int, keyframe_interval: int,
                         per_frame: int | None) -> int:
    """The slice of a round run beside one frame: ``per_frame`` when set, else the round
    spread over the fewest frames that can separate two keyframes (``keyframe_interval``), so
    that a round ends before the next keyframe can arrive."""
    if per_frame is not None:
        return per_frame
    return max(1, math.ceil(mapping_iters / keyframe_interval))


class ConcurrentMapping:
    """Runs queued mapping rounds in slices beside tracking (see the module docstring).

    Args:
        per_frame: mapping iterations run beside each frame.
        device: the map's device (a CUDA device gets a side stream).
        on_round_closed: called at the sync point with each round that ended in the slice
            (the system recomputes the window's visibility there).
    """

    #: the settings it reads (``mapping.mapping_mode``; :meth:`scheduled`)
    Config: ClassVar[type[ScheduleConfig]] = ScheduleConfig

    def __init__(self, per_frame: int, device: torch.device,
                 on_round_closed: Callable[[MapRound], None]) -> None:
        self.per_frame = per_frame
        self.queue: list[MapRound] = []  # oldest first
        self.on_round_closed = on_round_closed
        self.stream = torch.cuda.Stream(device) if device.type == "cuda" else None
        self._thread: threading.Thread | None = None
        self._error: BaseException | None = None
        self._stop = threading.Event()

    @classmethod
    def scheduled(cls, schedule: ScheduleConfig, per_frame: int, device: torch.device,
                  on_round_closed: Callable[[MapRound], None]) -> ConcurrentMapping | None:
        """The concurrent schedule when ``schedule`` (the ``mapping`` group) asks for it;
        None for ``sequential`` (each round then runs at its keyframe)."""
        if schedule.mapping_mode != "concurrent":
            return None
        return cls(per_frame, device, on_round_closed)

    @property
    def pending(self) -> bool:
        return bool(self.queue)

    def submit(self, round_: MapRound) -> None:
        """Queue a keyframe's round (begun after the keyframe's Gaussians were inserted, with
        :meth:`finish_queued` called before that insertion)."""
        self.queue.append(round_)

    def finish_queued(self) -> None:
        """Run every queued round to its end now (before an insertion, at the last frame)."""
        while self.queue:
            self.queue[0].advance(self.queue[0].remaining)
            self._close_front()

    def start_slice(self, snapshot_from: tuple[GaussianMap, CameraResponse]
                    ) -> MapSnapshot | None:
        """At the start of a frame: copy the map and curve for tracking, then start this
        frame's slice of mapping in the worker. None (and nothing started) when no round is
        queued: tracking then reads the live map, which nothing else changes."""
        if not self.queue:
            return None
        gmap, crf = snapshot_from
        with torch.no_grad():
            snapshot = MapSnapshot(gmap.clone(), copy.deepcopy(crf))
        if self.stream is not None:
            self.stream.wait_stream(torch.cuda.current_stream(gmap.device))
        self._error = None
        self._thread = threading.Thread(target=self._run_slice, name="egs-bench mapping",
                                        daemon=True)
        self._thread.start()
        return snapshot

    def _run_slice(self) -> None:
        try:
            if self.stream is not None:
                with torch.cuda.stream(self.stream):
                    self._advance(self.per_frame)
            else:
                self._advance(self.per_frame)
        except BaseException as exc:  # re-raised in the frame's thread
            self._error = exc

    def _advance(self, budget: int) -> None:
        """Up to ``budget`` iterations of the queued rounds, oldest first (a round that ends
        leaves the rest of the slice to the next one), one at a time so that :meth:`cancel`
        stops it within an iteration."""
        for round_ in self.queue:
            while budget > 0 and round_.remaining > 0:
                if self._stop.is_set():
                    return
                round_.advance(1)
                budget -= 1

    def cancel(self) -> None:
        """Stop the worker after its current iteration and wait for it (a frame that fails or
        is interrupted must not leave mapping running on the map)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None

    def end_slice(self) -> None:
        """The frame's sync point: wait for its slice; close the rounds that ended in it."""
        if self._thread is None:
            return
        self._thread.join()
        self._thread = None
        if self.stream is not None:
            torch.cuda.current_stream(self.stream.device).wait_stream(self.stream)
        if self._error is not None:
            error, self._error = self._error, None
            raise error
        while self.queue and self.queue[0].remaining == 0:
            self._close_front()

    def _close_front(self) -> None:
        round_ = self.queue.pop(0)
        round_.close()
        self.on_round_closed(round_)
