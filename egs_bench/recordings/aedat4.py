"""AEDAT4 files (iniVation DV software, e.g. a DAVIS346): events and APS frames.

Decoded with the ``aedat`` package (Rust, MIT; optional extra ``pip install
egs-bench[davis]``). Frames carry their exposure window (``exposure_begin_t`` /
``exposure_end_t``, microseconds on the camera's clock), which is what a blurred frame needs.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from egs_bench.datasets.events import Events
from egs_bench.errors import ConfigError, InputError
from egs_bench.recordings.streams import EventSource, FrameStream, to_rgb8

MAGIC = b"#!AER-DAT4.0"


def _decoder(path: Path) -> Any:
    try:
        import aedat
    except ImportError:
        raise ConfigError("reading AEDAT4 files needs the `aedat` package: "
                          "pip install 'egs-bench[davis]' (or pip install aedat)") from None
    try:
        return aedat.Decoder(str(path))
    except RuntimeError as exc:
        raise InputError(path, f"cannot read the AEDAT4 file, truncated or corrupt ({exc})") \
            from None


def _packets(path: Path) -> Iterator[dict]:
    decoder = _decoder(path)
    try:
        yield from decoder
    except RuntimeError as exc:  # the Rust decoder reports short reads this way
        raise InputError(path, f"AEDAT4 file is truncated or corrupt ({exc})") from None


class Aedat4File:
    """One AEDAT4 recording: its first event stream and first frame stream.

    Raises:
        InputError: missing file, not an AEDAT4 file (magic), no event stream, truncated.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise InputError(self.path, "file not found")
        with self.path.open("rb") as handle:
            if handle.read(len(MAGIC)) != MAGIC:
                raise InputError(self.path, "not an AEDAT 4.0 file (no '#!AER-DAT4.0' header)")
        streams = _decoder(self.path).id_to_stream()
        events = [(i, s) for i, s in sorted(streams.items()) if s.get("type") == "events"]
        frames = [(i, s) for i, s in sorted(streams.items()) if s.get("type") == "frame"]
        if not events:
            kinds = ", ".join(str(s.get("type", "?")) for s in streams.values())
            raise InputError(self.path, f"holds no event stream (streams: {kinds})")
        self._event_id, info = events[0]
        self.width, self.height = int(info["width"]), int(info["height"])
        self._frame_id = frames[0][0] if frames else None
        self._sources = _stream_sources(self.path)

    # ------------------------------------------------------------------ events
    def _event_batches(self) -> Iterator[Events]:
        for packet in _packets(self.path):
            if packet.get("stream_id") != self._event_id or "events" not in packet:
                continue
            ev = packet["events"]
            if len(ev):
                yield Events.from_arrays(ev["x"], ev["y"], ev["t"].astype(np.int64), ev["on"])

    def events(self) -> EventSource:
        """The event stream (polarity ``on`` -> +1)."""
        return EventSource(str(self.path), self.width, self.height, self._event_batches,
                           sensor=self._sources.get(self._event_id))

    # ------------------------------------------------------------------ frames
    def _frame_packets(self) -> Iterator[dict]:
        for packet in _packets(self.path):
            if packet.get("stream_id") == self._frame_id and "frame" in packet:
                yield packet["frame"]

    def frames(self) -> FrameStream:
        """APS frames with their exposure windows (``exposure_begin_t`` -> ``exposure_end_t``)."""
        if self._frame_id is None:
            raise InputError(self.path, "holds no frame stream (record APS frames, or give "
                                        "--frames)")
        t0, t1, size = [], [], None
        for f in self._frame_packets():
            t0.append(int(f["exposure_begin_t"]))
            t1.append(int(f["exposure_end_t"]))
            size = (int(f["width"]), int(f["height"]))
        if size is None:
            raise InputError(self.path, "the frame stream holds no frame")

        def load(indices: list[int]) -> Iterator[tuple[int, np.ndarray]]:
            wanted = set(indices)
            for i, f in enumerate(self._frame_packets()):
                if i in wanted:
                    try:
                        yield i, to_rgb8(f["pixels"], str(f["format"]))
                    except ValueError as exc:
                        raise InputError(self.path, f"frame {i}: {exc}") from None

        return FrameStream(f"{self.path} (frames)", np.asarray(t0, np.int64),
                           np.asarray(t1, np.int64), size[0], size[1], load,
                           sensor=self._sources.get(self._frame_id))


#: the header's XML ends within this many bytes in DV's files (a few kB); read no further
HEADER_SCAN_BYTES = 1 << 20


def _stream_sources(path: Path) -> dict[int, str]:
    """Stream id -> the ``source`` the DV header names for it (camera model and serial, e.g.
    ``DAVIS346_00000104``). The ``aedat`` decoder does not expose it; the header's info node
    is plain XML (``<dv>`` ... ``</dv>``) inside the IOHeader. ``{}`` when absent."""
    import xml.etree.ElementTree as ET

    with path.open("rb") as handle:
        head = handle.read(HEADER_SCAN_BYTES)
    start, end = head.find(b"<dv"), head.find(b"</dv>")
    if start < 0 or end < 0:
        return {}
    try:
        root = ET.fromstring(head[start:end + len(b"</dv>")].decode("utf-8"))
    except (ET.ParseError, UnicodeDecodeError):
        return {}  # the name is a label only: a header the decoder accepted still imports
    sources = {}
    for out in root.iter("node"):
        if out.get("name") != "outInfo":
            continue
        for stream in out.findall("node"):
            name = stream.get("name", "")
            attr = stream.find(".//attr[@key='source']")
            if name.isdigit() and attr is not None and attr.text:
                sources[int(name)] = attr.text.strip()
    return sources
