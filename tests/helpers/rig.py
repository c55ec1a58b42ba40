"""A synthetic recording rig: a built-in scene seen by an event camera (events, blurred frames,
exact depth and poses from ``make_synthetic``) plus a second, offset depth camera rendered from
``T_w_event @ T_event_depth`` on its own clock, and mocap poses of a rigid body on a third clock.

Written as a ROS1 bag the way a DAVIS + RealSense + mocap rig records it; the imported sequence
must reproduce the event camera's own depth and poses.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from egs_bench.datasets.sequence import Sequence
from egs_bench.datasets.synthetic import make_synthetic
from egs_bench.datasets.synthetic.raycast import Renderer
from egs_bench.datasets.synthetic.scene import pack_scene
from egs_bench.datasets.synthetic.scenes import build_scene
from egs_bench.datasets.synthetic.trajectory import HandheldTrajectory
from egs_bench.geometry import Intrinsics, invert_pose, pose_from_tq
from tests.helpers.bags import BagBuilder

#: the DAVIS clock of the recording = the synthetic sequence's clock + this
T0_US = 1_700_000_000_000_000
#: t_davis = t_depth + DEPTH_OFFSET_US = t_mocap + MOCAP_OFFSET_US
DEPTH_OFFSET_US = 500_000
MOCAP_OFFSET_US = -3_000_000
MOCAP_RATE_HZ = 200.0
SCENE, SPEED, SEED = "office", 0.4, 1
WIDTH, HEIGHT = 64, 48
#: the depth camera: wider field of view and more pixels than the event camera
DEPTH_CAM = Intrinsics(42.0, 42.0, 40.0, 30.0, 80, 60)


def _rot(axis: str, deg: float) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return Rotation.from_euler(axis, deg, degrees=True).as_matrix()


T_EVENT_DEPTH = np.eye(4)
T_EVENT_DEPTH[:3, :3] = _rot("y", 3.0) @ _rot("x", -2.0)
T_EVENT_DEPTH[:3, 3] = [0.05, -0.01, 0.005]
T_BODY_EVENT = pose_from_tq(np.array([0.03, 0.1, -0.02]), np.array([0.1, -0.2, 0.05, 0.97]))


@dataclass
class Rig:
    truth: Sequence          # the event camera's ground truth (synthetic clock)
    bag: Path                # events, frames, exposure, camera info, depth, mocap
    calib: Path


def calib_dict(with_event_camera: bool = True) -> dict:
    """calib.yaml content of the rig (OpenCV pixel convention: cx - 0.5)."""
    d = DEPTH_CAM
    out = {
        "depth_camera": {"width": d.width, "height": d.height,
                         "intrinsics": [d.fx, d.fy, d.cx - 0.5, d.cy - 0.5],
                         "distortion_model": "none", "distortion": [], "depth_scale": 1000},
        "T_event_depth": T_EVENT_DEPTH.tolist(),
        "T_body_event": T_BODY_EVENT.tolist(),
        "time_offsets_us": {"depth": DEPTH_OFFSET_US, "frames": 0, "mocap": MOCAP_OFFSET_US},
    }
    if with_event_camera:
        out["event_camera"] = event_camera_dict()
    return out


def event_camera_dict() -> dict:
    from egs_bench.datasets.synthetic.source import default_intrinsics

    k = default_intrinsics(WIDTH, HEIGHT)
    return {"width": WIDTH, "height": HEIGHT, "intrinsics": [k.fx, k.fy, k.cx - 0.5, k.cy - 0.5],
            "distortion_model": "none", "distortion": []}


def make_rig(root: Path, frames: int = 6) -> Rig:
    root.mkdir(parents=True, exist_ok=True)
    truth = Sequence.open(make_synthetic(SCENE, root / "truth", frames=frames, width=WIDTH,
                                         height=HEIGHT, speed=SPEED, seed=SEED, progress=False))
    scene = build_scene(SCENE)
    path = HandheldTrajectory(scene.camera_box, scene.target_box, speed=SPEED, seed=SEED)
    assert np.allclose(path.poses(truth.timestamps_s), truth.poses, atol=1e-9)
    b = BagBuilder()
    # events and frames: one DAVIS clock
    ev = truth.events.window(0, int(truth.t_end_us[-1]) + 1)
    b.events("/dvs/events", ev.x, ev.y, ev.t + T0_US, ev.p, WIDTH, HEIGHT)
    cam = event_camera_dict()
    b.camera_info("/dvs/camera_info", T0_US, WIDTH, HEIGHT, cam["intrinsics"], [])
    for i in range(len(truth)):
        t0, t1 = truth.exposure(i)
        b.image("/dvs/image_raw", T0_US + (t0 + t1) // 2, truth.rgb(i), "rgb8")
        b.exposure("/dvs/exposure", T0_US + (t0 + t1) // 2, t1 - t0)
    # depth camera: at every exposure end, and a decoy 12 ms later, on its own clock
    # samples at pixel centres: the importer back-projects through pixel centres
    renderer = Renderer(pack_scene(scene), DEPTH_CAM, supersample=1, jitter=False)
    for t_end in truth.t_end_us:
        for dt in (0, 12_000):
            t = int(t_end) + dt
            _, depth = renderer.render(path.poses(np.array([t * 1e-6]))[0] @ T_EVENT_DEPTH)
            mm = np.round(depth * 1000).astype(np.uint16)
            b.image("/camera/depth/image_rect_raw", T0_US + t - DEPTH_OFFSET_US, mm, "16UC1")
    # mocap: the rigid body, on its own clock
    t_s = np.arange(-0.05, truth.t_end_us[-1] * 1e-6 + 0.05, 1.0 / MOCAP_RATE_HZ)
    body = path.poses(t_s) @ invert_pose(T_BODY_EVENT)
    for t, T in zip(t_s, body, strict=True):
        b.pose("/mocap/body/pose", T0_US + int(round(t * 1e6)) - MOCAP_OFFSET_US, T)
    bag = b.write(root / "rig.bag")
    calib = root / "calib.yaml"
    calib.write_text(yaml.safe_dump(calib_dict(with_event_camera=False)))
    return Rig(truth, bag, calib)


def assert_events_match(seq: Sequence, truth: Sequence) -> None:
    """The imported sequence's events over its frames are the rig's, bit for bit, on the DAVIS
    clock (``T0_US`` later)."""
    a = seq.events.window(int(seq.t_start_us[0]), int(seq.t_end_us[-1]) + 1)
    b = truth.events.window(int(truth.t_start_us[0]), int(truth.t_end_us[-1]) + 1)
    assert len(a) == len(b) > 1000
    np.testing.assert_array_equal(a.t, b.t + T0_US)
    for k in "xyp":
        np.testing.assert_array_equal(getattr(a, k), getattr(b, k))
