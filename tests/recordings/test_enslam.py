"""``import-enslam``: a DEV-Reals sequence folder, written here in the layout of EN-SLAM's
extraction toolkit from the synthetic rig (events of the 64x48 event camera as events.csv, its
frames as DAVIS APS JPEGs, the offset depth camera's 16UC1 maps, the mocap poses as pose.txt),
imports with events, exposure windows, poses and depth as the rig's own bag import gives them."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

import egs_bench.cli.recording_cmds  # noqa: F401  (registers the commands)
from egs_bench.cli import main
from egs_bench.datasets.sequence import Sequence
from egs_bench.errors import InputError
from egs_bench.geometry import rotation_angle, write_tum
from egs_bench.images import read_ldr_image
from egs_bench.recordings import RecordingSpec, import_recording
from egs_bench.recordings.enslam import import_enslam, read_davis_intrinsics, stamp_us
from egs_bench.recordings.rosbag import BagFile
from tests.helpers.cli import assert_cli_error
from tests.helpers.rig import (
    T0_US,
    Rig,
    assert_events_match,
    calib_dict,
    event_camera_dict,
    make_rig,
)

DEPTH_TOPIC = "/camera/depth/image_rect_raw"


def _stamp(t_us: int) -> str:
    """The toolkit's image name: the ROS stamp in seconds, six decimals."""
    return f"{t_us // 1_000_000}.{t_us % 1_000_000:06d}"


def write_dev_reals(rig: Rig, root: Path) -> dict:
    """The rig as a DEV-Reals sequence folder; returns what the test compares against."""
    truth = rig.truth
    for sub in ("rgbd/rgb", "rgbd/depth", "davis346/rgb", "davis346/event", "davis346/intrinsic",
                "pose"):
        (root / sub).mkdir(parents=True)
    ev = truth.events.window(0, int(truth.t_end_us[-1]) + 1)
    rows = [f"{x},{y},{t // 1_000_000},{(t % 1_000_000) * 1000},{p > 0}"
            for x, y, t, p in zip(ev.x.tolist(), ev.y.tolist(), (ev.t + T0_US).tolist(),
                                  ev.p.tolist(), strict=True)]
    (root / "davis346/event/events.csv").write_text("x,y,ts_s,ts_n,polarity\n"
                                                     + "\n".join(rows) + "\n")
    fx, fy, cx, cy = event_camera_dict()["intrinsics"]
    (root / "davis346/intrinsic/intrinsic.yaml").write_text(yaml.safe_dump({"David346": {
        "image_width": truth.width, "image_height": truth.height,
        "intrinsics": {"rows": 3, "cols": 3, "data": [fx, 0, cx, 0, fy, cy, 0, 0, 1]},
        "distortion": {"rows": 1, "cols": 5, "data": []}}}))
    jpegs = []
    for i in range(len(truth)):  # DAVIS frames, named by their exposure start
        path = root / "davis346/rgb" / f"{_stamp(int(truth.t_start_us[i]) + T0_US)}.jpg"
        cv2.imwrite(str(path), cv2.cvtColor(truth.rgb(i), cv2.COLOR_RGB2BGR),
                    [cv2.IMWRITE_JPEG_QUALITY, 95])
        jpegs.append(read_ldr_image(path))
    bag = BagFile(rig.bag)
    depth = bag.depth_stream(DEPTH_TOPIC, 1000.0)
    for t, (_, d) in zip(depth.t_us.tolist(), depth.load(list(range(len(depth)))), strict=True):
        mm = np.round(d * 1000).astype(np.uint16)
        cv2.imwrite(str(root / "rgbd/depth" / f"{_stamp(t)}.png"), mm)
        # the RealSense colour image of the same instant (grey: only the warp is checked)
        cv2.imwrite(str(root / "rgbd/rgb" / f"{_stamp(t)}.jpg"),
                    np.full((depth.height, depth.width, 3), 128, np.uint8))
    mocap = bag.pose_track("/mocap/body/pose")
    write_tum(root / "pose/pose.txt", mocap.t_us * 1e-6, mocap.poses)
    return {"jpegs": jpegs}


@pytest.fixture(scope="module")
def rig(tmp_path_factory: pytest.TempPathFactory) -> Rig:
    return make_rig(tmp_path_factory.mktemp("rig"))


@pytest.fixture(scope="module")
def dev_reals(rig: Rig, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict, Path]:
    root = tmp_path_factory.mktemp("devreals") / "dorm1"
    expected = write_dev_reals(rig, root)
    calib = root.parent / "calib.yaml"  # the rig's: no event_camera (from intrinsic.yaml)
    calib.write_text(yaml.safe_dump(calib_dict(with_event_camera=False)))
    return root, expected, calib


def test_dev_reals_davis_frames_import_like_the_bag(rig: Rig, dev_reals: tuple[Path, dict, Path],
                                                    tmp_path: Path) -> None:
    root, expected, calib = dev_reals
    truth = rig.truth
    exposure = int(truth.t_end_us[0] - truth.t_start_us[0])
    assert (truth.t_end_us - truth.t_start_us == exposure).all()
    out = import_enslam(root, tmp_path / "seq", calib=calib, exposure_us=exposure,
                        frame_stamp="start", frames="davis", max_gt_gap_us=200_000,
                        progress=False)
    seq = Sequence.open(out)
    assert len(seq) == len(truth) and seq.intrinsics == truth.intrinsics
    np.testing.assert_array_equal(seq.t_start_us, truth.t_start_us + T0_US)
    np.testing.assert_array_equal(seq.t_end_us, truth.t_end_us + T0_US)
    assert_events_match(seq, truth)
    for i in range(len(seq)):
        np.testing.assert_array_equal(seq.rgb(i), expected["jpegs"][i])
        assert np.abs(seq.poses[i][:3, 3] - truth.poses[i][:3, 3]).max() < 1e-5
        assert np.degrees(rotation_angle(seq.poses[i], truth.poses[i])) < 1e-3
    # depth: the same maps through the same calibration as the rig's bag import
    bag_seq = Sequence.open(import_recording(RecordingSpec(
        events=rig.bag, depth=rig.bag, gt=rig.bag, calib=calib, preset="davis-realsense",
        camera_info_topic="/dvs/camera_info"), tmp_path / "bag_seq", progress=False))
    for i in range(len(seq)):
        np.testing.assert_array_equal(seq.depth(i), bag_seq.depth(i))
    rec = seq.meta["recording"]
    assert seq.meta["generator"] == "egs-bench import-enslam"
    assert rec["layout"]["frames"] == "davis"
    assert rec["layout"]["event_camera_from"].endswith("davis346/intrinsic/intrinsic.yaml")
    assert rec["events"]["in_recording"] == len(truth.events.window(0, int(truth.t_end_us[-1])
                                                                    + 1))


def test_dev_reals_realsense_frames_are_warped(dev_reals: tuple[Path, dict, Path], tmp_path: Path
                                               ) -> None:
    """--frames rgbd: the RealSense colour images (80x60, the depth camera) are warped into the
    event camera through the depth; pixels with depth get the image's grey, the rest black."""
    root, _, calib_file = dev_reals
    data = calib_dict(with_event_camera=False)
    data["frame_camera"] = {k: v for k, v in data["depth_camera"].items() if k != "depth_scale"}
    data["T_event_frame"] = data["T_event_depth"]
    data["time_offsets_us"]["frames"] = data["time_offsets_us"]["depth"]
    calib = tmp_path / "calib.yaml"
    calib.write_text(yaml.safe_dump(data))
    out = import_enslam(root, tmp_path / "seq", calib=calib, exposure_us=5000,
                        frame_stamp="end", frames="rgbd", max_gt_gap_us=200_000,
                        max_frames=3, progress=False)
    seq = Sequence.open(out)
    assert len(seq) == 3 and seq.meta["events_on_frame_sensor"] is False
    for i in range(3):
        rgb, depth = seq.rgb(i), seq.depth(i)
        assert (np.abs(rgb[depth > 0].astype(int) - 128) <= 2).mean() > 0.95
        assert (rgb[depth == 0] == 0).all()


def test_stamps_and_intrinsics(tmp_path: Path) -> None:
    assert stamp_us(Path("1700000000.123456.jpg")) == 1_700_000_000_123_456
    assert stamp_us(Path("12.5.png")) == 12_500_000
    with pytest.raises(InputError, match=r"frame_0001\.jpg: the name is not a time stamp"):
        stamp_us(tmp_path / "frame_0001.jpg")
    path = tmp_path / "intrinsic.yaml"
    path.write_text(yaml.safe_dump({"David346": {
        "image_width": 346, "image_height": 260,
        "intrinsics": {"data": [250.0, 0, 172.0, 0, 251.0, 130.0, 0, 0, 1]},
        "distortion": {"data": [-0.3, 0.1, 0.001, 0.0, 0.0]}}}))
    cam = read_davis_intrinsics(path)
    assert (cam.width, cam.height, cam.fx, cam.fy, cam.cx, cam.cy) == (346, 260, 250.0, 251.0,
                                                                       172.0, 130.0)
    assert cam.model == "radtan" and len(cam.coeffs) == 5
    path.write_text(yaml.safe_dump({"camera": {}}))
    with pytest.raises(InputError, match="intrinsic.yaml: no 'David346' camera"):
        read_davis_intrinsics(path)


def _run(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    code = main(["import-enslam", *args])
    return code, capsys.readouterr().err


def test_bad_dev_reals_input_is_one_line(dev_reals: tuple[Path, dict, Path], tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    root, _, calib = dev_reals
    base = ["--out", str(tmp_path / "o"), "--calib", str(calib), "--exposure-us", "5000",
            "--frame-stamp", "end"]
    # not the layout
    empty = tmp_path / "empty"
    empty.mkdir()
    code, err = _run(["--input", str(empty), *base], capsys)
    assert_cli_error(code, err, 3, f"error: {empty / 'rgbd/depth'}: missing: not a DEV-Reals "
                     "sequence")
    # an events.csv of another format
    other = tmp_path / "other"
    for sub in ("rgbd", "pose", "davis346"):
        (other / sub).mkdir(parents=True)
    for rel in ("rgbd/rgb", "rgbd/depth", "pose/pose.txt", "davis346/intrinsic", "davis346/rgb"):
        src, dst = root / rel, other / rel
        dst.symlink_to(src, target_is_directory=src.is_dir())
    (other / "davis346/event").mkdir()
    (other / "davis346/event/events.csv").write_text("t,x,y,p\n1,2,3,1\n")
    code, err = _run(["--input", str(other), *base], capsys)
    assert_cli_error(code, err, 3, f"error: {other / 'davis346/event/events.csv'}: header is "
                     "'t,x,y,p'")
    # a bad option
    code, err = _run(["--input", str(root), *base, "--frames", "kinect"], capsys)
    assert_cli_error(code, err, 2, "error: Invalid value for '--frames'",
                     "'kinect' is not one of 'rgbd', 'davis'")
    # a row that is not an event
    (other / "davis346/event/events.csv").write_text(
        "x,y,ts_s,ts_n,polarity\n1,2,1700000000,0,True\n3,-4,1700000000,5,False\n")
    code, err = _run(["--input", str(other), *base, "--frames", "davis", "--max-gt-gap-ms", "200"],
                     capsys)
    assert_cli_error(code, err, 3, f"{other / 'davis346/event/events.csv'}: line 3: y '-4' is not "
                     "a non-negative integer")
    assert not (tmp_path / "o").exists()
