"""Presets for recordings that come closest to the paper's (unpublished) DEVD rig.

A preset fills topic names and conventions (what a frame's stamp marks, where depth comes
from, which sensor the frames are on); calibration values stay in ``calib.yaml`` because they
differ per recording day. ``egs-bench recording-presets`` prints them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Literal

from egs_bench.errors import ConfigError

if TYPE_CHECKING:
    from egs_bench.recordings.streams import FrameStamp

#: Where a recording's depth comes from: an RGB-D camera or a LiDAR.
DepthSource = Literal["rgbd", "lidar"]


@dataclass(frozen=True)
class RecordingPreset:
    """Defaults of ``import-recording`` for one kind of recording.

    Attributes:
        name, description: shown by ``egs-bench recording-presets``.
        events_topic, frames_topic, exposure_topic, depth_topic, gt_topic: bag topics.
        frame_stamp: what a frame message's stamp marks (start, mid or end of the exposure).
        depth_source: ``rgbd`` (an RGB-D camera) or ``lidar`` (depth maps from a LiDAR).
        events_on_frame_sensor: whether frames and events come from one pixel grid.
        sensors: the rig's sensors, recorded as ``recording.preset_sensors`` in ``meta.yaml``
            (for reference only: ``sensors`` there come from the data or ``--sensor``).
        downloads: what a user downloads.
        notes: conventions and caveats (docs/guide/data.md).
    """

    name: str
    description: str
    events_topic: str | None = None
    frames_topic: str | None = None
    exposure_topic: str | None = None
    depth_topic: str | None = None
    gt_topic: str | None = None
    frame_stamp: FrameStamp = "mid"
    depth_source: DepthSource = "rgbd"
    events_on_frame_sensor: bool = True
    sensors: dict[str, str] = field(default_factory=dict)
    downloads: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()


PRESETS: dict[str, RecordingPreset] = {p.name: p for p in [
    RecordingPreset(
        "davis-realsense",
        "DEVD-style rig: DAVIS346 (events + APS frames, one pixel grid), RealSense D435i depth, "
        "mocap; AEDAT4 from DV or a ROS1 bag from rpg_dvs_ros + realsense2_camera",
        events_topic="/dvs/events", frames_topic="/dvs/image_raw", exposure_topic="/dvs/exposure",
        depth_topic="/camera/depth/image_rect_raw", frame_stamp="mid", depth_source="rgbd",
        events_on_frame_sensor=True,
        sensors={"events": "DAVIS346", "frames": "DAVIS346 APS", "depth": "RealSense D435i",
                 "groundtruth": "motion capture"},
        downloads=("your recording: events.aedat4 (DV) or a bag with /dvs/events, /dvs/image_raw, "
                   "/dvs/exposure, /camera/depth/image_rect_raw",
                   "mocap poses: a TUM file or a PoseStamped topic "
                   "(e.g. /vrpn_client_node/<body>/pose)",
                   "calib.yaml: DAVIS intrinsics (Kalibr), RealSense depth intrinsics "
                   "(camera_info), T_event_depth, hand-eye T_body_event, time offsets"),
        notes=("AEDAT4 frames carry exposure begin/end; rpg_dvs_ros stamps a frame at mid-exposure "
               "and publishes the exposure on /dvs/exposure.",
               "RealSense depth is 16UC1 millimetres (depth_scale 1000) and already rectified "
               "(distortion_model none)."),
    ),
    RecordingPreset(
        "mvsec-indoor",
        "MVSEC indoor_flying: left DAVIS 346 (events + grayscale APS frames), LiDAR depth maps "
        "on the DAVIS grid, mocap poses already in the left DAVIS frame",
        events_topic="/davis/left/events", frames_topic="/davis/left/image_raw",
        depth_topic="/davis/left/depth_image_raw", gt_topic="/davis/left/pose",
        frame_stamp="mid", depth_source="lidar", events_on_frame_sensor=True,
        sensors={"events": "DAVIS 346 (left)", "frames": "DAVIS 346 APS (left, grayscale)",
                 "depth": "Velodyne LiDAR depth maps projected to the left DAVIS",
                 "groundtruth": "Vicon motion capture, in the left DAVIS frame"},
        downloads=("indoor_flyingN_data.bag (events, frames)",
                   "indoor_flyingN_gt.bag (depth_image_raw, pose)",
                   "indoor_flying_calib.zip -> camchain-imucam-indoor_flying.yaml (Kalibr, "
                   "equidistant model)"),
        notes=("depth_image_raw is on the raw (distorted) DAVIS grid: calib.yaml says "
               "depth_camera: event, and the importer undistorts it with the event camera's "
               "equidistant model (egs-bench make-calib --preset mvsec-indoor writes that).",
               "The bags carry no exposure topic: give --exposure-us.",
               "The pose is the left DAVIS camera's (T_body_event = identity)."),
    ),
    RecordingPreset(
        "vector-small",
        "VECtor small-scale: left Prophesee event camera (640x480), left regular camera "
        "(grayscale, 1224x1024, another sensor), Azure Kinect depth, mocap",
        events_topic="/prophesee/left/events", frames_topic="/camera/left/image_mono",
        depth_topic="/kinect/depth_image", gt_topic="/gt/pose", frame_stamp="start",
        depth_source="rgbd", events_on_frame_sensor=False,
        sensors={"events": "Prophesee Gen3 (left)", "frames": "left regular camera (grayscale)",
                 "depth": "Azure Kinect (depth only)", "groundtruth": "motion capture"},
        downloads=("<sequence>.synced.left_event.bag, <sequence>.synced.left_camera.bag, "
                   "<sequence>.synced.kinect.bag, <sequence>.synced.gt.bag (merged with "
                   "mpl_dataset_toolbox's bag_merger, or passed one per option)",
                   "the calibration results: left_event_camera_intrinsic_results.yaml, "
                   "left_regular_camera_intrinsic_results.yaml, the Kinect depth intrinsics and "
                   "the camera-mocap hand-eye calibration"),
        notes=("Events and frames are on different sensors: the importer warps each frame into "
               "the event camera with the reprojected Kinect depth (pixels without depth stay "
               "black), and meta.yaml says events_on_frame_sensor: false.",
               "The bags carry no exposure time and the frame stamp convention is not documented: "
               "give --exposure-us and check --frame-stamp (default here: start).",
               "Kinect depth is 16UC1 millimetres (depth_scale 1000)."),
    ),
]}


def get_preset(name: str) -> RecordingPreset:
    try:
        return PRESETS[name]
    except KeyError:
        raise ConfigError(f"unknown recording preset {name!r} (choose from "
                          f"{', '.join(PRESETS)})") from None
