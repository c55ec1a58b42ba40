"""CLI commands for real recordings: ``import-recording``, ``import-enslam``, ``make-calib``,
``recording-presets``."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import typer
from rich.text import Text

from egs_bench.cli.app import QUIET, app
from egs_bench.cli.app import out as _out
from egs_bench.cli.choices import EnslamFrames, FrameStamp, TimesUnit


def _topic(option: str, what: str) -> Any:
    """A topic-name option of ``import-recording``."""
    return typer.Option(None, option, help=f"{what}: topic name (default: the preset's).")


# Options the two import commands share, declared once.
_MAX_DEPTH_DT_MS = typer.Option(15.0, "--max-depth-dt-ms", min=0.0,
                                help="Largest time between an exposure end and the depth map "
                                     "used for it.")
_FIRST_FRAME = typer.Option(0, "--first-frame", min=0, help="Skip this many usable frames.")
_MAX_FRAMES = typer.Option(None, "--max-frames", min=1, help="Import at most this many frames.")
_NAME = typer.Option(None, "--name", help="Sequence name (default: folder name).")
_OVERWRITE_SEQUENCE = typer.Option(False, "--overwrite",
                                   help="Replace an existing sequence folder.")


@app.command("import-recording")
def import_recording_cmd(
    out: Path = typer.Option(..., "--out", "-o",
                             help="Sequence folder to create (an existing one is replaced only "
                                  "with --overwrite)."),
    events: Path = typer.Option(..., "--events", help="AEDAT4 file or ROS1 .bag with the events."),
    depth: Path = typer.Option(..., "--depth", help="ROS1 .bag with a depth topic, or a folder of "
                                                    "16-bit depth PNGs (with --depth-times)."),
    gt: Path = typer.Option(..., "--gt", help="Mocap poses: TUM file (t tx ty tz qx qy qz qw, "
                                              "seconds, body-to-world) or a .bag with a pose "
                                              "topic."),
    calib: Path = typer.Option(None, "--calib", help="calib.yaml: cameras, T_event_depth, "
                                                     "T_body_event, time offsets (template: "
                                                     "`egs-bench make-calib`)."),
    preset: str | None = typer.Option(None, "--preset", help="Topic names and conventions of a "
                                      "known rig or dataset (`egs-bench recording-presets`)."),
    frames: Path | None = typer.Option(None, "--frames", help="Frames: AEDAT4, .bag or image "
                                       "folder (default: the --events file)."),
    events_topic: str | None = _topic("--events-topic", "Events (EventArray) in the --events bag"),
    frames_topic: str | None = _topic("--frames-topic", "Frames (Image) in the --frames bag"),
    exposure_topic: str | None = typer.Option(None, "--exposure-topic",
                                              help="std_msgs/Int32 exposure in us per frame "
                                                   "(DAVIS driver: /dvs/exposure)."),
    depth_topic: str | None = _topic("--depth-topic", "Depth maps (Image) in the --depth bag"),
    gt_topic: str | None = _topic("--gt-topic", "Mocap poses in the --gt bag"),
    camera_info_topic: str | None = typer.Option(None, "--camera-info-topic",
                                                 help="Take the event camera's calibration from "
                                                      "this CameraInfo topic of the events bag."),
    frame_times: Path | None = typer.Option(None, "--frame-times",
                                            help="For an image folder: 't_start t_end' or one "
                                                 "stamp per line."),
    depth_times: Path | None = typer.Option(None, "--depth-times",
                                            help="For a depth folder: one stamp per line."),
    times_unit: TimesUnit = typer.Option("us", "--times-unit",
                                   help="Unit of times files: us, ms, s, ns."),
    frame_stamp: FrameStamp | None = typer.Option(None, "--frame-stamp",
                                           help="What a single frame stamp marks: start, mid or "
                                                "end of the exposure (default: the preset's, else "
                                                "mid)."),
    exposure_us: int | None = typer.Option(None, "--exposure-us", min=1,
                                           help="Constant exposure time when the source has none."),
    max_depth_dt_ms: float = _MAX_DEPTH_DT_MS,
    max_gt_gap_ms: float = typer.Option(50.0, "--max-gt-gap-ms", min=0.0,
                                        help="Largest gap between the mocap poses around an "
                                             "exposure end (mocap dropouts drop the frame)."),
    first_frame: int = _FIRST_FRAME,
    max_frames: int | None = _MAX_FRAMES,
    name: str | None = _NAME,
    sensor: list[str] = typer.Option([], "--sensor",
                                     help="STREAM=NAME for meta.yaml (events, frames, depth, "
                                          "groundtruth), e.g. depth='Azure Kinect'; repeatable."),
    overwrite: bool = _OVERWRITE_SEQUENCE,
    quiet: bool = QUIET,
) -> None:
    """Import a real event + RGB-D + mocap recording as a sequence folder (ATE-only scoring)."""
    from egs_bench.recordings import RecordingSpec, import_recording
    from egs_bench.recordings.importer import parse_sensor_names

    spec = RecordingSpec(
        events=events, depth=depth, gt=gt, calib=calib, frames=frames, events_topic=events_topic,
        frames_topic=frames_topic, exposure_topic=exposure_topic, depth_topic=depth_topic,
        gt_topic=gt_topic, camera_info_topic=camera_info_topic, frame_times=frame_times,
        depth_times=depth_times, frame_stamp=frame_stamp, exposure_us=exposure_us,
        times_unit=times_unit, max_depth_dt_us=int(round(max_depth_dt_ms * 1000)),
        max_gt_gap_us=int(round(max_gt_gap_ms * 1000)), first_frame=first_frame,
        max_frames=max_frames, name=name, preset=preset, sensors=parse_sensor_names(sensor),
    )  # fmt: skip
    path = import_recording(spec, out, overwrite=overwrite, progress=not quiet)
    _out.print(f"wrote {path}")


@app.command("make-calib")
def make_calib_cmd(
    out: Path = typer.Option(..., "--out", "-o", help="calib.yaml to write."),
    kalibr: Path | None = typer.Option(None, "--kalibr", help="Kalibr camchain.yaml holding the "
                                                             "event camera (e.g. MVSEC's)."),
    camera: str = typer.Option("cam0", "--camera", help="Camera entry in the Kalibr file."),
    ros_yaml: Path | None = typer.Option(None, "--ros-yaml",
                                         help="ROS camera calibration yaml of the event camera "
                                              "(e.g. VECtor's left_event_camera_intrinsic_results"
                                              ".yaml)."),
    depth_on_event: bool = typer.Option(False, "--depth-on-event",
                                        help="Depth maps are on the event camera's grid "
                                             "(MVSEC): depth_camera: event."),
    preset: str | None = typer.Option(None, "--preset", help="Fill what the preset implies "
                                                             "(mvsec-indoor: --depth-on-event)."),
    overwrite: bool = typer.Option(False, "--overwrite",
                                   help="Replace an existing text file at --out."),
) -> None:
    """Write a calib.yaml template (identity transforms, zero offsets) to edit."""
    from egs_bench.recordings.calib import write_calib_template

    path = write_calib_template(out, kalibr=kalibr, camera=camera, ros_yaml=ros_yaml,
                                depth_on_event=depth_on_event, preset=preset,
                                overwrite=overwrite)
    _out.print(f"wrote {path} (check every value before importing)")


@app.command("recording-presets")
def recording_presets_cmd() -> None:
    """List the recording presets of `import-recording` with their topics and downloads."""
    from egs_bench.recordings import PRESETS

    for p in PRESETS.values():
        _out.print(Text.assemble((p.name, "bold"), f": {p.description}"))
        topics = {"events": p.events_topic, "frames": p.frames_topic,
                  "exposure": p.exposure_topic, "depth": p.depth_topic, "gt": p.gt_topic}
        _out.print("  topics: " + ", ".join(f"{k} {v}" for k, v in topics.items() if v))
        _out.print(f"  frame stamp: {p.frame_stamp}; depth: {p.depth_source}; "
                      f"events_on_frame_sensor: {str(p.events_on_frame_sensor).lower()}")
        for d in p.downloads:
            _out.print(f"  download: {d}")
        for n in p.notes:
            _out.print(f"  note: {n}")


@app.command("import-enslam")
def import_enslam_cmd(
    input_dir: Path = typer.Option(..., "--input", help="A DEV-Reals sequence folder (rgbd/, "
                                   "davis346/, pose/), as EN-SLAM's toolkit extracts it."),
    out: Path = typer.Option(..., "--out", "-o",
                             help="Sequence folder to create (an existing one is replaced only "
                                  "with --overwrite)."),
    calib: Path = typer.Option(..., "--calib", help="calib.yaml: RealSense colour camera as "
                               "depth_camera (and frame_camera), depth_scale, extrinsics, "
                               "offsets; event_camera defaults to davis346/intrinsic."),
    exposure_us: int = typer.Option(..., "--exposure-us", min=1,
                                    help="Exposure time of the frames (the layout has none)."),
    frame_stamp: FrameStamp = typer.Option(..., "--frame-stamp",
                                           help="What a frame's stamp marks: start, mid or "
                                                "end."),
    frames: EnslamFrames = typer.Option("rgbd", "--frames",
                                        help="rgbd (RealSense colour, EN-SLAM's input) or "
                                             "davis (DAVIS346 APS frames)."),
    max_depth_dt_ms: float = _MAX_DEPTH_DT_MS,
    max_gt_gap_ms: float = typer.Option(50.0, "--max-gt-gap-ms", min=0.0,
                                        help="Largest gap between the poses around an "
                                             "exposure end."),
    first_frame: int = _FIRST_FRAME,
    max_frames: int | None = _MAX_FRAMES,
    name: str | None = _NAME,
    sensor: list[str] = typer.Option([], "--sensor", help="STREAM=NAME for meta.yaml; "
                                     "repeatable."),
    overwrite: bool = _OVERWRITE_SEQUENCE,
    quiet: bool = QUIET,
) -> None:
    """Import an EN-SLAM DEV-Reals sequence (events + RGB-D + poses) as a sequence folder."""
    from egs_bench.recordings.enslam import import_enslam
    from egs_bench.recordings.importer import parse_sensor_names

    path = import_enslam(
        input_dir, out, calib=calib, exposure_us=exposure_us, frame_stamp=frame_stamp,
        frames=frames, max_depth_dt_us=int(round(max_depth_dt_ms * 1000)),
        max_gt_gap_us=int(round(max_gt_gap_ms * 1000)), first_frame=first_frame,
        max_frames=max_frames, name=name, sensors=parse_sensor_names(sensor),
        overwrite=overwrite, progress=not quiet)
    _out.print(f"wrote {path}")
