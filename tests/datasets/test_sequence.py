"""Canonical sequence format: reading, event access, and one clear error per bad input."""

from __future__ import annotations

import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest

from egs_bench.datasets.events import Events, EventStream, accumulate_event_maps, write_events_h5
from egs_bench.datasets.sequence import Sequence
from egs_bench.errors import InputError


@pytest.fixture()
def seq_copy(tiny_sequence: Path, tmp_path: Path) -> Path:
    dst = tmp_path / "seq"
    shutil.copytree(tiny_sequence, dst)
    return dst


def _all_events(path: Path) -> Events:
    with h5py.File(path / "events.h5") as f:
        off = int(f["t_offset"][()])
        g = f["events"]
        return Events.from_arrays(g["x"][()], g["y"][()], g["t"][()] + off, g["p"][()])


def _rewrite_events(path: Path, **changes: np.ndarray) -> None:
    """Overwrite event datasets in place, bypassing the writer's checks."""
    with h5py.File(path / "events.h5", "r+") as f:
        for key, values in changes.items():
            del f["events"][key]
            f["events"].create_dataset(key, data=values)


def test_open_reads_everything(tiny_sequence: Path) -> None:
    seq = Sequence.open(tiny_sequence)
    assert len(seq) == 4 and (seq.width, seq.height) == (64, 48)
    assert seq.rgb(0).shape == (48, 64, 3) and seq.rgb(0).dtype == np.uint8
    sharp = seq.sharp(3)
    assert sharp is not None and sharp.shape == (48, 64, 3)
    np.testing.assert_allclose(seq.depth(2), 2.0, atol=1e-3)
    assert seq.poses.shape == (4, 4, 4)
    np.testing.assert_allclose(seq.timestamps_s, seq.t_end_us * 1e-6)
    assert seq.exposure_us == 15_000
    dense = seq.dense_trajectory
    assert dense is not None  # every latent sample, exposure boundaries included
    boundaries = np.concatenate([seq.t_start_us, seq.t_end_us]) * 1e-6
    assert np.isin(np.round(boundaries, 6), np.round(dense.timestamps, 6)).all()
    assert len(seq.events) > 0
    seq.validate_contents()


def test_event_window_and_maps_match_brute_force(tiny_sequence: Path) -> None:
    seq = Sequence.open(tiny_sequence)
    ev = _all_events(tiny_sequence)
    rng = np.random.default_rng(0)
    for _ in range(20):
        t0, t1 = np.sort(rng.integers(ev.t[0] - 2000, ev.t[-1] + 2000, 2))
        win = seq.events.window(int(t0), int(t1))
        mask = (ev.t >= t0) & (ev.t < t1)
        np.testing.assert_array_equal(win.t, ev.t[mask])
        np.testing.assert_array_equal(win.x, ev.x[mask])
        np.testing.assert_array_equal(win.p, ev.p[mask])
    # exact window edges on event times (half-open)
    t_mid = int(ev.t[len(ev) // 2])
    win = seq.events.window(t_mid, t_mid + 1)
    assert len(win) == int((ev.t == t_mid).sum())
    # event maps over K sub-windows of an exposure, (a, b] semantics
    edges = np.linspace(*seq.exposure(1), 4).astype(np.int64)
    maps = seq.event_maps(1, edges)
    expected = np.zeros((3, 48, 64), np.int64)
    for k in range(3):
        sel = (ev.t > edges[k]) & (ev.t <= edges[k + 1])
        np.add.at(expected[k], (ev.y[sel], ev.x[sel]), ev.p[sel])
    np.testing.assert_array_equal(maps, expected)
    assert np.abs(maps).sum() > 0


def test_ms_to_idx_definition(tiny_sequence: Path) -> None:
    ev = _all_events(tiny_sequence)
    stream = EventStream(tiny_sequence / "events.h5", 64, 48)
    for ms, idx in enumerate(stream.ms_to_idx):
        assert idx == np.searchsorted(ev.t - stream.t_offset_us, 1000 * ms, side="left")


def test_accumulate_event_maps_half_open() -> None:
    ev = Events.from_arrays(np.array([1, 1, 1]), np.array([0, 0, 0]), np.array([10, 20, 21]),
                            np.array([1, 1, -1]))
    maps = accumulate_event_maps(ev, np.array([10, 20, 30]), 2, 3)
    assert maps[0, 0, 1] == 1  # t=20 in (10, 20]; t=10 excluded
    assert maps[1, 0, 1] == -1


# ---------------------------------------------------------------- bad input, one message each
def _expect(path: Path, fragment: str, culprit: str) -> None:
    with pytest.raises(InputError) as info:
        Sequence.open(path).validate_contents()
    message = str(info.value)
    assert fragment in message, message
    assert culprit in message, message


@pytest.mark.parametrize("name", ["meta.yaml", "frames.csv", "groundtruth.txt", "events.h5",
                                  "rgb/000002.png", "depth/000001.png", "sharp/000000.png"])
def test_missing_file(seq_copy: Path, name: str) -> None:
    (seq_copy / name).unlink()
    _expect(seq_copy, "not found", name)


def test_missing_folder(tmp_path: Path) -> None:
    _expect(tmp_path / "nope", "not found", "nope")


def test_unsorted_event_times(seq_copy: Path) -> None:
    ev = _all_events(seq_copy)
    t = ev.t.copy()
    t[10], t[11] = t[11] + 5, t[10]
    _rewrite_events(seq_copy, t=t - ev.t[0] + (ev.t[0] - 5000))
    _expect(seq_copy, "not sorted", "events.h5")


def test_event_time_out_of_range(seq_copy: Path) -> None:
    ev = _all_events(seq_copy)
    t = ev.t - 5000
    t[-1] = t[-1] + 10_000_000
    _rewrite_events(seq_copy, t=t)
    _expect(seq_copy, "after the end of the sequence", "events.h5")


def test_event_coordinates_outside_sensor(seq_copy: Path) -> None:
    x = _all_events(seq_copy).x.copy()
    x[3] = 64
    _rewrite_events(seq_copy, x=x)
    _expect(seq_copy, "outside the 64x48 sensor", "events.h5")


def test_pose_count_mismatch(seq_copy: Path) -> None:
    gt = seq_copy / "groundtruth.txt"
    gt.write_text("".join(gt.read_text().splitlines(keepends=True)[:-1]))
    _expect(seq_copy, "3 poses for 4 frames", "groundtruth.txt")


def test_frame_depth_mismatch(seq_copy: Path) -> None:
    csv = seq_copy / "frames.csv"
    lines = csv.read_text().splitlines()
    lines[2] = lines[2].replace("depth/000001.png", "")
    csv.write_text("\n".join(lines) + "\n")
    _expect(seq_copy, "empty rgb or depth", "frames.csv")


def test_empty_exposure(seq_copy: Path) -> None:
    csv = seq_copy / "frames.csv"
    lines = csv.read_text().splitlines()
    lines[1] = lines[1].replace("5000,20000", "20000,20000")
    csv.write_text("\n".join(lines) + "\n")
    _expect(seq_copy, "empty exposure window", "frames.csv")


def test_overlapping_exposure(seq_copy: Path) -> None:
    csv = seq_copy / "frames.csv"
    lines = csv.read_text().splitlines()
    lines[2] = lines[2].replace("38333,", "10000,")
    csv.write_text("\n".join(lines) + "\n")
    _expect(seq_copy, "before frame 0's exposure ends", "frames.csv")


def test_unreadable_image(seq_copy: Path) -> None:
    (seq_copy / "rgb/000001.png").write_bytes(b"not a png at all")
    _expect(seq_copy, "unreadable image", "rgb/000001.png")


def test_wrong_size_image(seq_copy: Path) -> None:
    import cv2

    cv2.imwrite(str(seq_copy / "sharp/000002.png"), np.zeros((10, 12, 3), np.uint8))
    _expect(seq_copy, "expected 64x48", "sharp/000002.png")


@pytest.mark.parametrize(("value", "fragment"), [(np.nan, "NaN"), (-1.0, "negative")])
def test_bad_depth_values(seq_copy: Path, value: float, fragment: str) -> None:
    depth = np.full((48, 64), 2.0, np.float32)
    depth[5, 7] = value
    np.save(seq_copy / "depth/000003.npy", depth)
    csv = seq_copy / "frames.csv"
    csv.write_text(csv.read_text().replace("depth/000003.png", "depth/000003.npy"))
    with pytest.raises(InputError, match=fragment) as info:
        Sequence.open(seq_copy, check_images=False).depth(3)
    assert "000003.npy" in str(info.value)


def test_truncated_hdf5(seq_copy: Path) -> None:
    path = seq_copy / "events.h5"
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    _expect(seq_copy, "truncated or corrupt", "events.h5")


def test_corrupt_hdf5(seq_copy: Path) -> None:
    (seq_copy / "events.h5").write_bytes(b"\x89HDF\r\n\x1a\n" + b"\x00" * 200)
    _expect(seq_copy, "truncated or corrupt", "events.h5")


def test_missing_hdf5_dataset(tmp_path: Path) -> None:
    with h5py.File(tmp_path / "e.h5", "w") as f:
        f.create_dataset("events/x", data=np.zeros(3, np.uint16))
    with pytest.raises(InputError, match="missing HDF5 dataset"):
        EventStream(tmp_path / "e.h5", 10, 10)


def test_bad_meta(seq_copy: Path) -> None:
    meta = seq_copy / "meta.yaml"
    meta.write_text(meta.read_text().replace("fx: 57.6", "fx: -3"))
    _expect(seq_copy, "fx must be a positive number", "meta.yaml")


def test_write_events_rejects_unsorted(tmp_path: Path) -> None:
    ev = Events.from_arrays(np.array([0, 1]), np.array([0, 0]), np.array([5, 3]),
                            np.array([1, -1]))
    with pytest.raises(ValueError, match="not sorted"):
        write_events_h5(tmp_path / "e.h5", ev)
