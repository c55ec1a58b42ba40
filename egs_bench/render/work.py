"""Work accounting of the rasteriser: what a render cost, counted, not timed.

Wall time depends on the machine and on what else it runs; the counts here do not. A caller
opens :func:`counting` around the renders it wants booked, and every :func:`rasterize
<egs_bench.render.rasterize>` call inside books into that :class:`RenderWork`: cameras,
pixels, Gaussian-tile intersections and Gaussian-pixel blends, forward and backward. A blend
is one Gaussian composited into one pixel (``alpha >= 1/255`` and the pixel still open): the
inner loop of every tile rasteriser, whose count the CPU kernels report per tile. The
backward pass books when autograd runs it, into the record that was open at the forward.

gsplat reports its intersections but not its blends, so records that contain a gsplat render
say ``blends_counted = False`` and give no blend counts.
"""

from __future__ import annotations

import contextvars
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

_LOCK = threading.Lock()  # concurrent mapping books from a second thread
_CURRENT: contextvars.ContextVar[RenderWork | None] = contextvars.ContextVar(
    "egs_bench_render_work", default=None)


@dataclass
class RenderWork:
    """Counts of rendering work (all totals over the booked calls).

    Attributes:
        calls: rasteriser calls.
        cameras: cameras rendered (a blurred frame of K segments is K + 1 cameras).
        pixels: pixels rendered, cameras x width x height.
        isects: Gaussian-tile intersections (16 x 16 tiles).
        blends_fwd, blends_bwd: Gaussian-pixel blends of the forward pass and of the
            backward passes that ran (a render without backward books none).
        blends_counted: False once a call came from a backend that does not count blends.
    """

    calls: int = 0
    cameras: int = 0
    pixels: int = 0
    isects: int = 0
    blends_fwd: int = 0
    blends_bwd: int = 0
    blends_counted: bool = True

    def add(self, other: RenderWork) -> None:
        """Add ``other``'s counts to these."""
        with _LOCK:
            self.calls += other.calls
            self.cameras += other.cameras
            self.pixels += other.pixels
            self.isects += other.isects
            self.blends_fwd += other.blends_fwd
            self.blends_bwd += other.blends_bwd
            self.blends_counted = self.blends_counted and other.blends_counted

    def to_dict(self) -> dict[str, int | None]:
        """Plain counts; the blend counts are None where they were not counted."""
        return {"calls": self.calls, "cameras": self.cameras, "pixels": self.pixels,
                "isects": self.isects,
                "blends_fwd": self.blends_fwd if self.blends_counted else None,
                "blends_bwd": self.blends_bwd if self.blends_counted else None}

    @property
    def blends(self) -> int | None:
        """Forward plus backward blends (None when not counted)."""
        return self.blends_fwd + self.blends_bwd if self.blends_counted else None


@contextmanager
def counting(work: RenderWork) -> Iterator[RenderWork]:
    """Book every render inside the block (in this thread) into ``work``."""
    token = _CURRENT.set(work)
    try:
        yield work
    finally:
        _CURRENT.reset(token)


def active() -> RenderWork | None:
    """The record renders are booked into now (None: nobody is counting)."""
    return _CURRENT.get()


def book(work: RenderWork | None, *, calls: int = 0, cameras: int = 0, pixels: int = 0,
         isects: int = 0, blends_fwd: int = 0, blends_bwd: int = 0,
         blends_counted: bool = True) -> None:
    """Add counts to ``work`` (nothing when it is None)."""
    if work is None:
        return
    work.add(RenderWork(calls, cameras, pixels, isects, blends_fwd, blends_bwd, blends_counted))
