"""Event arrays in memory, DSEC-style HDF5 storage, time-window slicing and event maps.

In memory (docs/design.md §2): ``x, y`` uint16 (column, row), ``t`` int64 microseconds, ``p``
int8 in {+1, -1}. On disk (§3): ``events/{x,y,t,p}`` with ``p`` in {0, 1} and ``t`` relative to
``t_offset``, plus ``ms_to_idx`` (index of the first event with ``t >= t_offset + 1000 * i``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np

from egs_bench.errors import InputError
from egs_bench.fileio import HDF5Output


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


# --------------------------------------------------------------------------------------------
# DSEC-style HDF5 storage
# --------------------------------------------------------------------------------------------

#: Events per HDF5 chunk; gzip level 1 + shuffle keeps files readable by plain h5py.
CHUNK_EVENTS = 1 << 16
_COMPRESSION = {"compression": "gzip", "compression_opts": 1, "shuffle": True}
_VALIDATE_BLOCK = 1 << 22


class EventWriter:
    """Stream sorted event batches into a DSEC-style HDF5 file.

    ``t`` is stored relative to ``t_offset_us`` (int64), ``p`` as {0, 1}; ``ms_to_idx`` is
    written on :meth:`close`. Use as a context manager; the caller makes the file atomic (the
    sequence writer builds the whole folder under a temporary name).
    """

    def __init__(self, path: str | Path, t_offset_us: int = 0) -> None:
        self.path = Path(path)
        self.t_offset_us = int(t_offset_us)
        self._output = HDF5Output(self.path)
        self._file = self._output.file
        group = self._file.create_group("events")
        specs = {"x": np.uint16, "y": np.uint16, "t": np.int64, "p": np.uint8}
        self._datasets = {
            key: group.create_dataset(
                key, shape=(0,), maxshape=(None,), dtype=dtype, chunks=(CHUNK_EVENTS,),
                **_COMPRESSION,
            )
            for key, dtype in specs.items()
        }
        self._count = 0
        self._last_t: int | None = None  # relative time of the last event written
        self._ms_to_idx: list[int] = [0]

    def append(self, events: Events) -> None:
        """Append a batch; batches must be sorted and not go back in time."""
        n = len(events)
        if n == 0:
            return
        self._output.check()
        t_rel = events.t - self.t_offset_us
        if t_rel[0] < 0:
            raise ValueError("event before t_offset")
        if self._last_t is not None and t_rel[0] < self._last_t:
            raise ValueError("event batches must be appended in time order")
        if n > 1 and (np.diff(t_rel) < 0).any():
            raise ValueError("events within a batch are not sorted by time")
        # ms_to_idx entries for every millisecond boundary up to this batch's last event
        last_ms = int(t_rel[-1] // 1000)
        new_ms = np.arange(len(self._ms_to_idx), last_ms + 1, dtype=np.int64)
        if len(new_ms):
            idx = np.searchsorted(t_rel, new_ms * 1000, side="left") + self._count
            self._ms_to_idx.extend(int(i) for i in idx)
        values = {"x": events.x, "y": events.y, "t": t_rel, "p": (events.p > 0).astype(np.uint8)}
        for key, dset in self._datasets.items():
            dset.resize((self._count + n,))
            dset[self._count :] = values[key]
        self._count += n
        self._last_t = int(t_rel[-1])

    def close(self) -> None:
        """Write ``ms_to_idx`` (one entry past the last event's millisecond) and close."""
        ms_to_idx = np.asarray([*self._ms_to_idx, self._count], dtype=np.int64)
        self._file.create_dataset("ms_to_idx", data=ms_to_idx, **_COMPRESSION)
        self._file.create_dataset("t_offset", data=np.int64(self.t_offset_us))
        self._output.close()

    def abort(self) -> None:
        """Close without finishing the file (it is being discarded after an error)."""
        self._output.abort()

    def __enter__(self) -> EventWriter:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()


def write_events_h5(path: str | Path, events: Events, t_offset_us: int = 0) -> None:
    """Write one batch of sorted events to a DSEC-style HDF5 file."""
    with EventWriter(path, t_offset_us) as writer:
        writer.append(events)


class EventStream:
    """Read access to a DSEC-style HDF5 event file (time windows via ``ms_to_idx``).

    Args:
        path: the ``events.h5`` file.
        width, height: sensor size, for validation of coordinates.
        t_max_us: latest plausible absolute event time (e.g. the last exposure end plus a
            margin); events after it are reported as out of range.
        validate: check sortedness, ranges and ``ms_to_idx`` on open (reads the file once).

    Raises:
        InputError: missing, truncated or corrupt file; missing datasets; unsorted or
            out-of-range times; coordinates outside the sensor; bad polarity values.
    """

    def __init__(
        self, path: str | Path, width: int, height: int, t_max_us: int | None = None,
        validate: bool = True,
    ) -> None:
        import h5py

        try:  # registers Blosc, Zstd, LZ4, ...: DSEC-style files use them
            import hdf5plugin  # noqa: F401
        except ImportError:  # gzip files (ours) still read; others fail naming the filter
            pass

        self.path = Path(path)
        self.width, self.height = int(width), int(height)
        if not self.path.is_file():
            raise InputError(self.path, "event file not found")
        try:
            self._file = h5py.File(self.path, "r")
            group = self._file["events"]
            self._x, self._y, self._t, self._p = (group[k] for k in "xytp")
            self.ms_to_idx = np.asarray(self._file["ms_to_idx"][()], dtype=np.int64)
            self.t_offset_us = int(np.asarray(self._file["t_offset"][()]))
        except KeyError as exc:
            raise InputError(self.path, f"missing HDF5 dataset ({exc})") from None
        except OSError as exc:
            raise _read_error(self.path, getattr(self, "_file", None), exc) from None
        n = len(self._t)
        if not (len(self._x) == len(self._y) == len(self._p) == n):
            raise InputError(self.path, "events/x, y, t, p have different lengths")
        self._n = n
        if validate:
            self._validate(t_max_us)

    def __len__(self) -> int:
        return self._n

    def _validate(self, t_max_us: int | None) -> None:
        prev_t = None
        m = self.ms_to_idx
        if m.ndim != 1 or len(m) == 0:
            raise InputError(self.path, "ms_to_idx must be a non-empty 1-D index")
        # events per millisecond, accumulated block by block, give the exact ms_to_idx
        per_ms = np.zeros(len(m), dtype=np.int64)
        try:
            for start in range(0, self._n, _VALIDATE_BLOCK):
                stop = min(start + _VALIDATE_BLOCK, self._n)
                t = np.asarray(self._t[start:stop], dtype=np.int64)
                x, y, p = self._x[start:stop], self._y[start:stop], self._p[start:stop]
                if (np.diff(t) < 0).any() or (prev_t is not None and t[0] < prev_t):
                    bad = start + int(np.argmax(np.diff(t) < 0)) + 1
                    raise InputError(self.path, f"event times are not sorted (event {bad})")
                if t[0] < 0:
                    raise InputError(self.path, "event time before t_offset (negative time)")
                if t_max_us is not None and t[-1] + self.t_offset_us > t_max_us:
                    raise InputError(
                        self.path,
                        f"event time {int(t[-1]) + self.t_offset_us} us is after the end of the "
                        f"sequence ({t_max_us} us)",
                    )
                if (x >= self.width).any() or (y >= self.height).any():
                    raise InputError(
                        self.path,
                        f"event coordinates outside the {self.width}x{self.height} sensor "
                        f"(max x {int(x.max())}, max y {int(y.max())})",
                    )
                if (p > 1).any():
                    raise InputError(self.path, "polarity values other than 0/1")
                ms = t // 1000
                if int(ms[-1]) >= len(m):
                    raise InputError(self.path, "ms_to_idx does not cover the last event")
                first = int(ms[0])
                counts = np.bincount(ms - first)
                per_ms[first:first + len(counts)] += counts
                prev_t = t[-1]
        except OSError as exc:
            raise _read_error(self.path, self._file, exc) from None
        expected = np.concatenate([[0], np.cumsum(per_ms)[:-1]])
        wrong = np.nonzero(m != expected)[0]
        if len(wrong):
            i = int(wrong[0])
            raise InputError(self.path, f"ms_to_idx[{i}] = {int(m[i])}, but {int(expected[i])} "
                                        f"events come before {i} ms (events/t): the index would "
                                        "cut time windows at the wrong events")

    @property
    def t_first(self) -> int | None:
        """Absolute time of the first event (us), or None when empty."""
        return int(self._t[0]) + self.t_offset_us if self._n else None

    @property
    def t_last(self) -> int | None:
        """Absolute time of the last event (us), or None when empty."""
        return int(self._t[self._n - 1]) + self.t_offset_us if self._n else None

    def _index(self, t_abs_us: int) -> int:
        """Index of the first event with ``t >= t_abs_us``: ``ms_to_idx`` brackets the answer
        within one millisecond, then a binary search inside that block."""
        t_rel = int(t_abs_us) - self.t_offset_us
        if t_rel <= 0:
            return 0
        ms = t_rel // 1000
        if ms + 1 >= len(self.ms_to_idx):  # after the last event's millisecond
            return self._n
        lo, hi = int(self.ms_to_idx[ms]), int(self.ms_to_idx[ms + 1])
        return lo + int(np.searchsorted(self._t[lo:hi], t_rel, side="left"))

    def window(self, t_start_us: int, t_end_us: int) -> Events:
        """Events with ``t_start_us <= t < t_end_us`` (absolute microseconds)."""
        i0, i1 = self._index(t_start_us), self._index(t_end_us)
        return self._read(i0, i1)

    def _read(self, i0: int, i1: int) -> Events:
        if i1 <= i0:
            return Events.empty()
        return Events(
            self._x[i0:i1].astype(np.uint16),
            self._y[i0:i1].astype(np.uint16),
            self._t[i0:i1].astype(np.int64) + self.t_offset_us,
            np.where(self._p[i0:i1] > 0, 1, -1).astype(np.int8),
        )

    def event_maps(self, edges_us: np.ndarray) -> np.ndarray:
        """Signed event counts per sub-window: ``E_k`` = sum of polarities in
        ``(edges[k], edges[k+1]]``.

        Args:
            edges_us: increasing absolute times, shape [K+1] (microseconds).

        Returns:
            int32 array [K, H, W].
        """
        edges = np.asarray(edges_us, dtype=np.int64)
        if edges.ndim != 1 or len(edges) < 2 or (np.diff(edges) < 0).any():
            raise ValueError("edges_us must be a non-decreasing 1-D array of length >= 2")
        # integer microseconds: t > a  <=>  t >= a + 1
        i0, i1 = self._index(int(edges[0]) + 1), self._index(int(edges[-1]) + 1)
        ev = self._read(i0, i1)
        return accumulate_event_maps(ev, edges, self.height, self.width)

    def close(self) -> None:
        self._file.close()


#: HDF5 filter ids of the compressors event files use (registered ids, hdfgroup.org)
_FILTER_NAMES = {32001: "Blosc", 32004: "LZ4", 32008: "Bitshuffle", 32015: "Zstd",
                 32026: "Blosc2", 307: "bzip2"}


def _read_error(path: Path, file: Any, exc: OSError) -> InputError:
    """The one-line error for an HDF5 read failure: a compression filter this installation
    lacks is named as such (HDF5 itself only says it cannot open its plugin directory)."""
    import h5py

    missing: set[str] = set()
    if file is not None:
        def visit(_name: str, obj: object) -> None:
            if isinstance(obj, h5py.Dataset):
                plist = obj.id.get_create_plist()
                for i in range(plist.get_nfilters()):
                    fid = int(plist.get_filter(i)[0])
                    if not h5py.h5z.filter_avail(fid):
                        missing.add(f"{_FILTER_NAMES.get(fid, 'unregistered')} (id {fid})")
        try:
            file.visititems(visit)
        except (OSError, RuntimeError):
            pass
    if missing:
        return InputError(path, f"needs the HDF5 compression filter {', '.join(sorted(missing))}, "
                                "which this installation lacks: pip install "
                                "'egs-bench[hdf5]' (hdf5plugin: Blosc, Blosc2, Zstd, LZ4, "
                                "Bitshuffle and bzip2)")
    return InputError(path, f"cannot read HDF5 data, truncated or corrupt ({exc})")


def accumulate_event_maps(events: Events, edges_us: np.ndarray, height: int, width: int
                          ) -> np.ndarray:
    """Sum polarities per pixel in the half-open windows ``(edges[k], edges[k+1]]``.

    Returns:
        int32 array [K, H, W] with ``K = len(edges_us) - 1``.
    """
    edges = np.asarray(edges_us, dtype=np.int64)
    k = len(edges) - 1
    bins = np.searchsorted(edges, events.t, side="left") - 1  # t in (e[b], e[b+1]] -> b
    keep = (bins >= 0) & (bins < k)
    flat = (bins[keep].astype(np.int64) * height + events.y[keep]) * width + events.x[keep]
    maps = np.bincount(flat, weights=events.p[keep], minlength=k * height * width)
    return maps.reshape(k, height, width).astype(np.int32)
