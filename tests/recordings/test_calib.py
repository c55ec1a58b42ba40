"""calib.yaml: round trip, validation messages, Kalibr and ROS camera files, presets."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from egs_bench.errors import ConfigError, InputError
from egs_bench.recordings import RecordingSpec, apply_preset, dump_calib, load_calib
from egs_bench.recordings.calib import camera_from_ros_yaml, write_calib_template

GOOD = {
    "event_camera": {"width": 346, "height": 260, "intrinsics": [250.0, 251.0, 172.0, 130.0],
                     "distortion_model": "radtan", "distortion": [-0.3, 0.1, 0.001, 0.0]},
    "depth_camera": {"width": 640, "height": 480, "intrinsics": [385.0, 385.0, 320.0, 240.0],
                     "depth_scale": 1000},
    "T_event_depth": [[1, 0, 0, 0.05], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]],
    "T_body_event": np.eye(4).tolist(),
    "time_offsets_us": {"depth": -1500, "mocap": 250},
}
FRAME_CAMERA = {"width": 640, "height": 480, "intrinsics": [500.0, 500.0, 320.0, 240.0]}


def _write(tmp_path: Path, data: dict[str, Any]) -> Path:
    path = tmp_path / "calib.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_round_trip(tmp_path: Path) -> None:
    calib = load_calib(_write(tmp_path, GOOD))
    assert calib.event_camera is not None and calib.depth_camera is not None
    assert calib.event_camera.model == "radtan" and calib.depth_camera.model == "none"
    assert calib.time_offsets_us == {"depth": -1500, "frames": 0, "mocap": 250}
    assert calib.T_event_depth[0, 3] == 0.05 and (calib.T_body_event == np.eye(4)).all()
    again = tmp_path / "again.yaml"
    again.write_text(dump_calib(calib))
    back = load_calib(again)
    assert back.event_camera == calib.event_camera and back.depth_camera == calib.depth_camera
    assert back.time_offsets_us == calib.time_offsets_us
    np.testing.assert_array_equal(back.T_event_depth, calib.T_event_depth)
    # egs-bench's pixel convention: + 0.5
    assert calib.event_camera is not None
    assert calib.event_camera.pinhole().cx == 172.5


@pytest.mark.parametrize("change, message", [
    ({"T_event_depth": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}, "T_event_depth must be a 4x4 matrix"),
    ({"T_body_event": [[2, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]},
     "T_body_event: the upper-left 3x3 block is not a rotation"),
    ({"event_camera": {"width": 346, "height": 260, "intrinsics": [250, 250, 172]}},
     r"event_camera.intrinsics must be \[fx, fy, cx, cy\]"),
    ({"event_camera": {"width": 346, "height": 260, "intrinsics": [1, 1, 1, 1],
                       "distortion_model": "radtan", "distortion": [0.1, 0.2, 0.3]}},
     "event_camera: radtan distortion needs 4, 5 or 8 coefficients"),
    ({"time_offsets_us": {"imu": 5}}, "time_offsets_us: unknown keys imu"),
    ({"T_event_rgb": None}, "unknown keys: T_event_rgb"),
])
def test_bad_calibration_names_file_and_problem(tmp_path: Path, change: dict[str, Any], message: str
                                                ) -> None:
    with pytest.raises(InputError, match=message) as info:
        load_calib(_write(tmp_path, {**GOOD, **change}))
    assert str(info.value).startswith(str(tmp_path / "calib.yaml"))


@pytest.mark.parametrize("drop, add, message", [
    ("T_body_event", {}, r"missing T_body_event \(event camera -> mocap body"),
    ("T_event_depth", {}, r"missing T_event_depth \(depth camera -> event camera"),
    ("time_offsets_us", {}, r"missing time_offsets_us.depth"),
    (None, {"time_offsets_us": {"depth": 0}}, r"missing time_offsets_us.mocap"),
    (None, {"frame_camera": FRAME_CAMERA, "time_offsets_us": {"depth": 0, "mocap": 0,
                                                              "frames": 0}},
     r"missing T_event_frame \(frame camera -> event camera"),
    (None, {"frame_camera": FRAME_CAMERA, "T_event_frame": np.eye(4).tolist()},
     r"missing time_offsets_us.frames"),
    ("depth_camera", {"depth_camera": "event"},
     "depth_camera: event .* T_event_depth must be absent or the identity"),
])
def test_missing_calibration_values_are_refused(tmp_path: Path, drop: str | None,
                                                add: dict[str, Any], message: str) -> None:
    """Values that move poses, depth or times have no silent default (identity, 0): the file
    and the key are named."""
    data = {k: v for k, v in GOOD.items() if k != drop}
    data.update(add)
    with pytest.raises(InputError, match=message) as info:
        load_calib(_write(tmp_path, data))
    assert str(info.value).startswith(str(tmp_path / "calib.yaml"))


def test_optional_calibration_values(tmp_path: Path) -> None:
    """Depth on the event grid needs no T_event_depth; frames from the event sensor no frames
    offset; depth_scale is left for the importer to require (float depth needs none)."""
    data = {k: v for k, v in GOOD.items() if k not in ("T_event_depth", "depth_camera")}
    calib = load_calib(_write(tmp_path, {**data, "depth_camera": "event"}))
    assert (calib.T_event_depth == np.eye(4)).all() and calib.depth_scale is None
    assert calib.time_offsets_us["frames"] == 0
    # make-calib's template holds every required key
    template = write_calib_template(tmp_path / "template.yaml")
    assert load_calib(template).depth_scale == 1000.0


def test_ros_camera_yaml(tmp_path: Path) -> None:
    """The format of VECtor's *_intrinsic_results.yaml (camera_calibration_parsers)."""
    path = tmp_path / "left_event_camera_intrinsic_results.yaml"
    path.write_text(yaml.safe_dump({
        "image_width": 640, "image_height": 480, "camera_name": "left_event_camera",
        "camera_matrix": {"rows": 3, "cols": 3,
                          "data": [327.3, 0, 305.0, 0, 327.5, 235.4, 0, 0, 1]},
        "camera_model": "plumb_bob",
        "distortion_coefficients": {"rows": 1, "cols": 5,
                                    "data": [-0.032, 0.042, -0.0005, -0.001, 0.0]}}))
    cam = camera_from_ros_yaml(path)
    assert (cam.width, cam.fx, cam.fy, cam.cx, cam.cy) == (640, 327.3, 327.5, 305.0, 235.4)
    assert cam.model == "radtan" and len(cam.coeffs) == 5
    out = write_calib_template(tmp_path / "calib.yaml", ros_yaml=path)
    assert load_calib(out).event_camera == cam


def test_presets_fill_only_what_is_unset() -> None:
    spec = apply_preset(RecordingSpec(events=Path("d.bag"), preset="mvsec-indoor",
                                      gt_topic="/my/pose"))
    assert spec.events_topic == "/davis/left/events"
    assert spec.depth_topic == "/davis/left/depth_image_raw"
    assert spec.gt_topic == "/my/pose" and spec.depth_source == "lidar"
    assert spec.exposure_topic is None  # MVSEC has none
    davis = apply_preset(RecordingSpec(events=Path("r.bag"), preset="davis-realsense"))
    assert davis.exposure_topic == "/dvs/exposure" and davis.frame_stamp == "mid"
    aedat = apply_preset(RecordingSpec(events=Path("r.aedat4"), preset="davis-realsense"))
    assert aedat.exposure_topic is None  # AEDAT4 frames carry their exposure
    with pytest.raises(ConfigError, match="unknown recording preset 'tum-vie'"):
        apply_preset(RecordingSpec(events=Path("x.bag"), preset="tum-vie"))
