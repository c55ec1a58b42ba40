"""What the SLAM reads of a sequence: :class:`SequenceView`.

The SLAM system (:mod:`egs_bench.slam.system`, its frame loader, its context and the runner
that writes the run folder) is handed either an opened
:class:`~egs_bench.datasets.sequence.Sequence` or a view of one that replaces some of its
data, such as :class:`~egs_bench.baselines.monogs_edi.EdiSequence` (EDI-deblurred frames).
Both satisfy this protocol, which names exactly what those consumers use. Conventions are the
sequence folder's (docs/design.md §2-3): times int64 microseconds, poses ``T_wc`` [4, 4]
float64.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:
    import numpy as np

    from egs_bench.datasets.events import EventStream
    from egs_bench.geometry import Intrinsics


class SequenceView(Protocol):
    """A sequence as the SLAM reads it (see the module docstring)."""

    @property
    def path(self) -> Path:
        """The sequence folder (error messages name files inside it)."""
        ...

    @property
    def name(self) -> str:
        """The sequence's name, recorded in the run folder."""
        ...

    @property
    def width(self) -> int:
        """Image width [px]."""
        ...

    @property
    def height(self) -> int:
        """Image height [px]."""
        ...

    @property
    def intrinsics(self) -> Intrinsics:
        """The camera at the sequence's resolution."""
        ...

    @property
    def eps(self) -> float:
        """Log offset of the event model, ``log(luma + eps)``."""
        ...

    @property
    def pos_threshold(self) -> float:
        """Positive contrast threshold C+ (log units)."""
        ...

    @property
    def neg_threshold(self) -> float:
        """Negative contrast threshold C- (log units)."""
        ...

    @property
    def timestamps_s(self) -> np.ndarray:
        """Exposure ends in seconds, [N] float64."""
        ...

    @property
    def poses(self) -> np.ndarray:
        """Ground-truth ``T_wc`` at each exposure end, [N, 4, 4] float64."""
        ...

    @property
    def has_events(self) -> bool:
        """Whether the sequence has an event stream (``meta.yaml`` ``has_events``)."""
        ...

    @property
    def events(self) -> EventStream:
        """The event stream (raises :class:`~egs_bench.errors.InputError` without one)."""
        ...

    def __len__(self) -> int:
        """Number of frames."""
        ...

    def rgb(self, i: int) -> np.ndarray:
        """Observed LDR frame ``i``: uint8 [H, W, 3], sRGB."""
        ...

    def depth(self, i: int) -> np.ndarray:
        """Depth at the exposure end of frame ``i``: float32 [H, W] metres, 0 = invalid."""
        ...

    def exposure(self, i: int) -> tuple[int, int]:
        """Exposure window ``(t_start_us, t_end_us)`` of frame ``i``."""
        ...

    def event_maps(self, i: int, edges_us: np.ndarray | None = None, k: int = 1) -> np.ndarray:
        """Signed event counts over sub-windows of frame ``i``'s exposure: int32 [K, H, W]."""
        ...
