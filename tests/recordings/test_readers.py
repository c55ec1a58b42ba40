"""Readers on real bytes (the shared DAVIS346 AEDAT4 file, a real Azure Kinect depth bag) and on
bags written here with rosbags; DSEC-style HDF5 with Blosc/Zstd through hdf5plugin."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import h5py
import hdf5plugin
import numpy as np
import pytest

from egs_bench.datasets.events import EventStream
from egs_bench.errors import InputError
from egs_bench.recordings.rosbag import BagFile, _decode_event_array, _events_from_msg
from tests.helpers.bags import BagBuilder

AEDAT = "events/davis346_aestream.aedat4"


# ------------------------------------------------------------------ AEDAT4 (real bytes)
def test_aedat4_events_and_frames_match_reference_decode(shared_data: Path) -> None:
    pytest.importorskip("aedat")
    from egs_bench.recordings.aedat4 import Aedat4File

    ref = np.load(shared_data / "events/davis346_aestream_decoded.npz")
    rec = Aedat4File(shared_data / AEDAT)
    assert (rec.width, rec.height) == (346, 260)
    src = rec.events()
    ev = [b for b in src.batches()]
    t = np.concatenate([b.t for b in ev])
    np.testing.assert_array_equal(t, ref["events_t"])
    np.testing.assert_array_equal(np.concatenate([b.x for b in ev]), ref["events_x"])
    np.testing.assert_array_equal(np.concatenate([b.y for b in ev]), ref["events_y"])
    p = np.concatenate([b.p for b in ev])
    np.testing.assert_array_equal(p, np.where(ref["events_p"] == 1, 1, -1))
    frames = rec.frames()
    np.testing.assert_array_equal(frames.t_start_us, ref["frames_t_expbegin_expend"][:, 1])
    np.testing.assert_array_equal(frames.t_end_us, ref["frames_t_expbegin_expend"][:, 2])
    images = dict(frames.load([0, 2]))
    assert set(images) == {0, 2}
    for i, img in images.items():  # grey frames replicated to RGB
        assert img.shape == (260, 346, 3)
        np.testing.assert_array_equal(img[..., 1], ref["frames"][i])
        np.testing.assert_array_equal(img[..., 0], img[..., 2])


def test_truncated_aedat4_is_reported(shared_data: Path, tmp_path: Path) -> None:
    pytest.importorskip("aedat")
    from egs_bench.recordings.aedat4 import Aedat4File

    data = (shared_data / AEDAT).read_bytes()
    cut = tmp_path / "cut.aedat4"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(InputError, match=r"cut\.aedat4: .*truncated or corrupt"):
        rec = Aedat4File(cut)
        list(rec.events().batches())


def _aedat4_packets(data: bytes) -> list[tuple[int, int, int]]:
    """``(stream_id, payload_offset, payload_size)`` of each packet: after the 14-byte magic
    and the IOHeader (a little-endian uint32 size, then its bytes), packets are an int32
    stream id, a uint32 size and the (here LZ4-framed) FlatBuffer, until the data table."""
    import struct

    off = 14 + 4 + struct.unpack_from("<I", data, 14)[0]
    packets = []
    while off + 8 <= len(data):
        sid, size = struct.unpack_from("<iI", data, off)
        if sid not in (0, 1, 2, 3) or off + 8 + size > len(data):
            break  # the file data table
        packets.append((sid, off + 8, size))
        off += 8 + size
    return packets


def test_aedat4_integrity_is_what_the_format_gives(shared_data: Path, tmp_path: Path) -> None:
    """What docs/notes/recordings.md says AEDAT4 can and cannot detect, on the real file:
    DV writes LZ4 frames without block or content checksums (FLG byte 0x40 in every packet),
    so 4 KiB of zeros inside an event packet breaks its LZ4/FlatBuffer structure and is
    refused, while the same damage inside an APS frame (stored as LZ4 literals) decodes into a
    wrong frame that no reader can tell from a good one."""
    pytest.importorskip("aedat")
    from egs_bench.recordings.aedat4 import Aedat4File

    data = (shared_data / AEDAT).read_bytes()
    ref = np.load(shared_data / "events/davis346_aestream_decoded.npz")
    packets = _aedat4_packets(data)
    assert len(packets) == 40
    assert {data[off:off + 4] for _, off, _ in packets} == {bytes.fromhex("04224d18")}
    assert {data[off + 4] for _, off, _ in packets} == {0x40}  # no block/content checksum

    def damaged(stream: int) -> Path:
        _, off, size = [p for p in packets if p[0] == stream][1]
        bad = bytearray(data)
        start = off + size // 2 - 2048
        bad[start:start + 4096] = bytes(4096)
        path = tmp_path / f"damaged{stream}.aedat4"
        path.write_bytes(bytes(bad))
        return path

    with pytest.raises(InputError, match=r"damaged0\.aedat4: .*truncated or corrupt"):
        list(Aedat4File(damaged(0)).events().batches())
    frames = dict(Aedat4File(damaged(1)).frames().load([0, 1, 2]))
    assert (frames[0][..., 0] == ref["frames"][0]).all()
    assert (frames[1][..., 0] != ref["frames"][1]).sum() > 3000  # silently wrong


def test_not_an_aedat4_file(tmp_path: Path) -> None:
    from egs_bench.recordings.aedat4 import Aedat4File

    bad = tmp_path / "x.aedat4"
    bad.write_bytes(b"#!AER-DAT2.0\r\n" + bytes(100))
    with pytest.raises(InputError, match=r"x\.aedat4: not an AEDAT 4\.0 file"):
        Aedat4File(bad)


# ------------------------------------------------------------------ ROS1 bags
def test_real_16uc1_depth_message_in_metres(shared_data: Path) -> None:
    """Azure Kinect depth (VECtor, reprojected to a 640x480 frame): millimetres -> metres."""
    bag = BagFile(shared_data / "bags/k4a_reprojection.bag")
    assert bag.topics["/rgb/depth_repj"][0] == "sensor_msgs/msg/Image"
    depth = bag.depth_stream("/rgb/depth_repj", depth_scale=1000.0)
    assert (depth.width, depth.height) == (640, 480)
    assert depth.t_us[0] == 1642325459233220  # header stamp, microseconds
    [(i, d)] = list(depth.load([0]))
    valid = d > 0
    assert d.dtype == np.float32 and d.shape == (480, 640)
    assert 0.45 < valid.mean() < 0.50                    # 47 % valid (README of the file)
    assert d[valid].min() == pytest.approx(0.457, abs=1e-6)
    assert d[valid].max() == pytest.approx(5.827, abs=1e-6)
    # the same bytes read independently: little-endian uint16 millimetres
    from rosbags.highlevel import AnyReader

    with AnyReader([shared_data / "bags/k4a_reprojection.bag"]) as reader:
        conn = [c for c in reader.connections if c.topic == "/rgb/depth_repj"]
        _, _, raw = next(reader.messages(connections=conn))
        msg = reader.deserialize(raw, conn[0].msgtype)
    mm = np.frombuffer(bytes(msg.data), "<u2").reshape(480, 640)  # type: ignore[attr-defined]
    np.testing.assert_array_equal(d, (mm / 1000.0).astype(np.float32))


def _event_bag(tmp_path: Path, n: int = 3000) -> tuple[Path, dict]:
    rng = np.random.default_rng(1)
    ev = {"x": rng.integers(0, 40, n), "y": rng.integers(0, 30, n),
          "t": np.sort(rng.integers(5_000_000, 5_100_000, n)), "p": rng.integers(0, 2, n)}
    b = BagBuilder()
    b.events("/dvs/events", ev["x"], ev["y"], ev["t"], ev["p"], 40, 30)
    b.camera_info("/dvs/camera_info", 5_000_000, 40, 30, (35.0, 36.0, 19.5, 14.5),
                  [-0.1, 0.02, 0.0, 0.0, 0.0])
    b.image("/dvs/image_raw", 5_010_000, np.zeros((30, 40), np.uint8), "mono8")
    return b.write(tmp_path / "ev.bag"), ev


def test_event_array_fast_path_matches_deserialiser(tmp_path: Path) -> None:
    path, ev = _event_bag(tmp_path)
    bag = BagFile(path)
    src = bag.event_source(None)  # the only EventArray topic
    assert (src.width, src.height) == (40, 30)
    got = [b for b in src.batches()]
    np.testing.assert_array_equal(np.concatenate([b.t for b in got]), ev["t"])
    np.testing.assert_array_equal(np.concatenate([b.x for b in got]), ev["x"])
    np.testing.assert_array_equal(np.concatenate([b.y for b in got]), ev["y"])
    np.testing.assert_array_equal(np.concatenate([b.p for b in got]),
                                  np.where(ev["p"] > 0, 1, -1))
    # message by message, the raw-bytes decoder equals rosbags' own deserialiser
    from rosbags.highlevel import AnyReader

    with AnyReader([path]) as reader:
        conn = [c for c in reader.connections if c.topic == "/dvs/events"]
        for _, _, raw in reader.messages(connections=conn):
            fast = _decode_event_array(raw, "x")
            slow = _events_from_msg(reader.deserialize(raw, conn[0].msgtype))
            for k in "xytp":
                np.testing.assert_array_equal(getattr(fast, k), getattr(slow, k))


def test_camera_info_topic(tmp_path: Path) -> None:
    path, _ = _event_bag(tmp_path)
    cam = BagFile(path).camera_info("/dvs/camera_info")
    assert (cam.width, cam.height, cam.fx, cam.fy, cam.cx, cam.cy) == (40, 30, 35, 36, 19.5, 14.5)
    assert cam.model == "radtan" and cam.coeffs == (-0.1, 0.02, 0.0, 0.0, 0.0)


def test_missing_topic_lists_the_topics(tmp_path: Path) -> None:
    path, _ = _event_bag(tmp_path)
    with pytest.raises(InputError) as info:
        BagFile(path).event_source("/davis/left/events")
    msg = str(info.value)
    assert msg.startswith(f"{path}: no topic '/davis/left/events'")
    for topic in ("/dvs/events (dvs_msgs/EventArray", "/dvs/camera_info", "/dvs/image_raw"):
        assert topic in msg


def test_truncated_bag_is_reported(tmp_path: Path) -> None:
    path, _ = _event_bag(tmp_path)
    cut = tmp_path / "cut.bag"
    cut.write_bytes(path.read_bytes()[: path.stat().st_size * 2 // 3])
    with pytest.raises(InputError, match=r"cut\.bag: .*truncated"):
        bag = BagFile(cut)
        list(bag.event_source("/dvs/events").batches())


# ------------------------------------------------------------------ DSEC-style HDF5
@pytest.mark.parametrize("compression", [hdf5plugin.Blosc(cname="zstd"), hdf5plugin.Zstd()],
                         ids=["blosc", "zstd"])
def test_dsec_events_h5_with_compression_filter(tmp_path: Path, compression: Any) -> None:
    """DSEC layout: t uint32 us relative to t_offset, p uint8, ms_to_idx; Blosc/Zstd filters."""
    rng = np.random.default_rng(2)
    n = 20_000
    t = np.sort(rng.integers(0, 50_000, n)).astype(np.uint32)
    path = tmp_path / "events.h5"
    with h5py.File(path, "w") as f:
        g = f.create_group("events")
        g.create_dataset("x", data=rng.integers(0, 640, n).astype(np.uint16), **compression)
        g.create_dataset("y", data=rng.integers(0, 480, n).astype(np.uint16), **compression)
        g.create_dataset("t", data=t, **compression)
        g.create_dataset("p", data=rng.integers(0, 2, n).astype(np.uint8), **compression)
        f.create_dataset("ms_to_idx", data=np.searchsorted(t, np.arange(0, 51) * 1000)
                         .astype(np.uint64))
        f.create_dataset("t_offset", data=np.int64(1_000_000))
    stream = EventStream(path, 640, 480)
    ev = stream.window(1_010_000, 1_020_000)
    expected = (t >= 10_000) & (t < 20_000)
    assert len(ev) == expected.sum()
    np.testing.assert_array_equal(ev.t, t[expected].astype(np.int64) + 1_000_000)


def test_missing_hdf5_filter_is_named(tmp_path: Path) -> None:
    """A filter no installed plugin provides: reported as a missing filter, not corruption."""
    path = tmp_path / "events.h5"
    with h5py.File(path, "w") as f:
        g = f.create_group("events")
        for key, dtype in zip("xytp", ["u2", "u2", "u4", "u1"], strict=True):
            d = g.create_dataset(key, shape=(10,), dtype=dtype, chunks=(10,), compression=32123,
                                 allow_unknown_filter=True)
            d.id.write_direct_chunk((0,), np.arange(10, dtype=dtype).tobytes())
        f["ms_to_idx"] = np.array([0, 10])
        f["t_offset"] = np.int64(0)
    with pytest.raises(InputError, match=r"events\.h5: needs the HDF5 compression filter "
                                         r"unregistered \(id 32123\)") as info:
        EventStream(path, 64, 48)
    assert "corrupt" not in str(info.value)


def test_a_bag_without_rosbags_installed_is_one_line_naming_the_extra(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import sys

    from egs_bench.errors import ConfigError
    from egs_bench.recordings.rosbag import BagFile

    bag = tmp_path / "x.bag"
    bag.write_bytes(b"#ROSBAG V2.0\n")
    monkeypatch.setitem(sys.modules, "rosbags.highlevel", None)  # import raises ImportError
    with pytest.raises(ConfigError, match=r"pip install 'egs-bench\[ros\]'"):
        BagFile(bag)


def test_a_filter_hdf5plugin_provides_names_the_extra(tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    from egs_bench.datasets.events import _read_error

    path = tmp_path / "events.h5"
    with h5py.File(path, "w") as f:
        f.create_dataset("events/t", data=np.zeros(4, "i8"), chunks=(4,), **hdf5plugin.Zstd())
    # as without hdf5plugin: HDF5 has no Zstd filter, and the read fails
    monkeypatch.setattr(h5py.h5z, "filter_avail", lambda fid: fid != 32015)
    with h5py.File(path, "r") as f:
        error = _read_error(path, f, OSError("Can't open directory or file"))
    assert "Zstd (id 32015)" in str(error) and "pip install 'egs-bench[hdf5]'" in str(error)
