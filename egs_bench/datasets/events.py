"""Event arrays in memory, DSEC-style HDF5 storage, time-window slicing and event maps.

In memory (DESIGN §2): ``x, y`` uint16 (column, row), ``t`` int64 microseconds, ``p`` int8 in
{+1, -1}. On disk: ``events/{x,y,t,p}`` with ``p`` in {0, 1} and ``t`` relative to ``t_offset``,
plus ``ms_to_idx`` (index of the first event with ``t >= t_offset + 1000 * i``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Events:
    """A batch of events, sorted by time.

    Attributes:
        x: column of each event, shape [N], uint16.
        y: row of each event, shape [N], uint16.
        t: timestamp in microseconds, shape [N], int64.
        p: polarity, shape [N], int8, +1 (brighter) or -1 (darker).
    """

    x: np.ndarray
    y: np.ndarray
    t: np.ndarray
    p: np.ndarray

    def __post_init__(self) -> None:
        n = len(self.t)
        if not (len(self.x) == len(self.y) == len(self.p) == n):
            raise ValueError("x, y, t, p must have the same length")

    def __len__(self) -> int:
        return len(self.t)

    @staticmethod
    def empty() -> Events:
        return Events(
            np.zeros(0, np.uint16), np.zeros(0, np.uint16), np.zeros(0, np.int64),
            np.zeros(0, np.int8),
        )

    @staticmethod
    def from_arrays(x: np.ndarray, y: np.ndarray, t: np.ndarray, p: np.ndarray) -> Events:
        """Build events with the canonical dtypes (``p`` may be ±1, {0,1} or bool)."""
        p = np.asarray(p)
        p = np.where(p > 0, 1, -1).astype(np.int8)
        return Events(
            np.asarray(x, np.uint16), np.asarray(y, np.uint16), np.asarray(t, np.int64), p
        )

    @staticmethod
    def concatenate(batches: list[Events]) -> Events:
        """Concatenate batches that are each sorted and follow each other in time."""
        if not batches:
            return Events.empty()
        return Events(*(np.concatenate([getattr(b, k) for b in batches]) for k in "xytp"))

    def slice_time(self, t_start_us: int, t_end_us: int) -> Events:
        """Events with ``t_start_us <= t < t_end_us`` (binary search; requires sorted ``t``)."""
        i0, i1 = np.searchsorted(self.t, [t_start_us, t_end_us], side="left")
        return Events(self.x[i0:i1], self.y[i0:i1], self.t[i0:i1], self.p[i0:i1])
