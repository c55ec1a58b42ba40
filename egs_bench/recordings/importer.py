"""``import_recording``: a real event + RGB-D + mocap recording -> a canonical sequence folder.

Every stream is moved into one camera, the event camera made distortion-free
(:meth:`CameraModel.pinhole`: same ``K`` and size, no distortion):

* events: each sensor pixel is moved to the undistorted pixel its centre maps to;
* frames from the event sensor (DAVIS APS): undistorted with the same model (bilinear);
  frames from another camera (``frame_camera`` in ``calib.yaml``): warped into the event camera
  through the reprojected depth (pixels without depth stay black);
* depth: back-projected through the depth camera's lens model, moved with ``T_event_depth``,
  projected, z-buffered (:func:`~egs_bench.recordings.depth.reproject_depth`); the depth map
  nearest in time to each exposure end is used (within ``max_depth_dt_us``);
* ground truth: mocap body poses interpolated (slerp/lerp) at each exposure end on the event
  clock, times ``T_body_event``.

The sequence has no ``sharp/`` (a real camera has no sharp ground truth): evaluation scores
ATE only. ``meta.yaml`` records ``source: real``, the sensors, ``events_on_frame_sensor``,
``depth_source`` and everything the import did (inputs, calibration, dropped frames).
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from egs_bench import __version__
from egs_bench.datasets.events import Events
from egs_bench.errors import ConfigError, InputError
from egs_bench.fileio import atomic_dir
from egs_bench.geometry import interpolate_trajectory, invert_pose
from egs_bench.outputs import prepare_output
from egs_bench.progress import ProgressBar
from egs_bench.recordings.calib import RecordingCalib, load_calib
from egs_bench.recordings.camera import CameraModel
from egs_bench.recordings.depth import reproject_depth, warp_to_depth_camera
from egs_bench.recordings.folders import TimesUnit
from egs_bench.recordings.presets import DepthSource, get_preset
from egs_bench.recordings.streams import (
    DepthStream,
    EventSource,
    FrameStamp,
    FrameStream,
    PoseTrack,
)

if TYPE_CHECKING:
    from egs_bench.recordings.aedat4 import Aedat4File
    from egs_bench.recordings.rosbag import BagFile

#: depth PNG units per metre in the written sequence (millimetres: 65 m range)
OUT_DEPTH_SCALE = 1000.0


@dataclass
class RecordingSpec:
    """What to import. Files are dispatched by type: ``.aedat4``, ``.bag`` (ROS1), a folder
    (images + a times file), ``.txt``/``.tum`` (TUM poses). ``None`` topics are taken from the
    preset or, when a bag has exactly one topic of the needed type, found automatically.

    Attributes:
        events: AEDAT4 file or ROS1 bag with the events.
        frames: file or image folder with the frames (default: the events file).
        depth: ROS1 bag or folder of 16-bit PNGs with the depth maps.
        gt: TUM file or ROS1 bag with the mocap poses.
        calib: ``calib.yaml`` (see :mod:`egs_bench.recordings.calib`).
        events_topic, frames_topic, exposure_topic, depth_topic, gt_topic: bag topics.
        camera_info_topic: fills a missing ``event_camera`` from a CameraInfo topic of the
            events bag.
        frame_times, depth_times: times files for image folders.
        frame_stamp: what a frame stamp marks when only one is given: start, mid, end.
        exposure_us: constant exposure when the source has none.
        times_unit: unit of times files: us, ms, s, ns.
        max_depth_dt_us: largest gap between an exposure end and its depth map.
        max_gt_gap_us: largest gap between the two mocap poses bracketing an exposure end.
        first_frame, max_frames: frame range to import (after dropping unusable frames).
        name: sequence name (default: the output folder's name).
        preset: name of a :class:`~egs_bench.recordings.presets.RecordingPreset`.
        depth_source: recorded in ``meta.yaml``.
        sensors: sensor names by stream (events, frames, depth, groundtruth) for
            ``meta.yaml``; a stream not named here gets the name the recording gives (AEDAT4)
            or its source file and topic.
    """

    events: Path
    depth: Path | None = None
    gt: Path | None = None
    calib: Path | None = None
    frames: Path | None = None
    events_topic: str | None = None
    frames_topic: str | None = None
    exposure_topic: str | None = None
    depth_topic: str | None = None
    gt_topic: str | None = None
    camera_info_topic: str | None = None
    frame_times: Path | None = None
    depth_times: Path | None = None
    frame_stamp: FrameStamp | None = None
    exposure_us: int | None = None
    times_unit: TimesUnit = "us"
    max_depth_dt_us: int = 15_000
    max_gt_gap_us: int = 50_000
    first_frame: int = 0
    max_frames: int | None = None
    name: str | None = None
    preset: str | None = None
    depth_source: DepthSource | None = None
    sensors: dict[str, str] = field(default_factory=dict)


SENSOR_KEYS = ("events", "frames", "depth", "groundtruth")


def parse_sensor_names(items: list[str]) -> dict[str, str]:
    """``["depth=Azure Kinect", ...]`` -> ``{"depth": "Azure Kinect"}`` (``--sensor``).

    Raises:
        ConfigError: an item without ``=``, an unknown stream or an empty name.
    """
    names: dict[str, str] = {}
    for item in items:
        key, sep, name = item.partition("=")
        key, name = key.strip(), name.strip()
        if not sep or key not in SENSOR_KEYS or not name:
            raise ConfigError(f"--sensor {item!r}: expected STREAM=NAME with STREAM one of "
                              f"{', '.join(SENSOR_KEYS)}")
        names[key] = name
    return names


def apply_preset(spec: RecordingSpec) -> RecordingSpec:
    """``spec`` with unset topics and conventions filled from ``spec.preset``."""
    if spec.preset is None:
        return replace(spec, frame_stamp=spec.frame_stamp or "mid",
                       depth_source=spec.depth_source or "rgbd")
    p = get_preset(spec.preset)

    def pick(value: Any, default: Any) -> Any:
        return default if value is None else value

    frames_file = spec.frames or spec.events
    # an AEDAT4 file has its own frame stream; bag topics apply to bags only
    exposure_topic = spec.exposure_topic
    if exposure_topic is None and spec.exposure_us is None and frames_file.suffix == ".bag":
        exposure_topic = p.exposure_topic
    return replace(
        spec,
        events_topic=pick(spec.events_topic, p.events_topic),
        frames_topic=pick(spec.frames_topic, p.frames_topic),
        exposure_topic=exposure_topic,
        depth_topic=pick(spec.depth_topic, p.depth_topic),
        gt_topic=pick(spec.gt_topic, p.gt_topic),
        frame_stamp=pick(spec.frame_stamp, p.frame_stamp),
        depth_source=pick(spec.depth_source, p.depth_source),
    )


# ------------------------------------------------------------------------------------------
# opening the inputs
# ------------------------------------------------------------------------------------------

@dataclass
class _Inputs:
    """The opened inputs; ``event_camera`` and ``depth_camera`` are the calibration's, resolved
    (a CameraInfo topic fills a missing event camera) and checked against the data."""

    calib: RecordingCalib
    event_camera: CameraModel
    depth_camera: CameraModel
    events: EventSource
    frames: FrameStream
    depth: DepthStream
    gt: PoseTrack


def _bag(path: Path, cache: dict[Path, Any]) -> BagFile:
    from egs_bench.recordings.rosbag import BagFile

    if path not in cache:
        cache[path] = BagFile(path)
    return cache[path]


def _aedat(path: Path, cache: dict[Path, Any]) -> Aedat4File:
    from egs_bench.recordings.aedat4 import Aedat4File

    if path not in cache:
        cache[path] = Aedat4File(path)
    return cache[path]


def _kind(path: Path, what: str) -> str:
    if path.is_dir():
        return "folder"
    if not path.exists():
        raise InputError(path, f"{what} not found")
    suffix = path.suffix.lower()
    if suffix == ".aedat4":
        return "aedat4"
    if suffix == ".bag":
        return "bag"
    if suffix in (".txt", ".tum", ".csv"):
        return "text"
    raise InputError(path, f"unsupported {what} file (expected .aedat4, a ROS1 .bag, a folder, "
                           "or a TUM .txt)")


def _open_inputs(spec: RecordingSpec) -> _Inputs:
    from egs_bench.recordings import folders

    cache: dict = {}
    if spec.depth is None:
        raise ConfigError("no depth given: the sequence format and the SLAM need depth "
                          "(--depth BAG or FOLDER)")
    if spec.gt is None:
        raise ConfigError("no ground truth given (--gt TUM_FILE or BAG with a pose topic)")
    if spec.calib is None:
        raise InputError(spec.depth, "depth needs a calibration to be moved into the event "
                                     "camera: give --calib calib.yaml (depth_camera, "
                                     "T_event_depth, ...; `egs-bench make-calib` writes a "
                                     "template)")
    calib = load_calib(spec.calib)
    # events
    kind = _kind(spec.events, "events file")
    if kind == "aedat4":
        events = _aedat(spec.events, cache).events()
    elif kind == "bag":
        events = _bag(spec.events, cache).event_source(spec.events_topic)
    else:
        raise InputError(spec.events, "events must come from an .aedat4 file or a ROS1 .bag")
    if calib.event_camera is None:
        if spec.camera_info_topic is None or kind != "bag":
            raise calib.error("no event_camera: give it, or a CameraInfo topic of the events bag")
        cam = _bag(spec.events, cache).camera_info(spec.camera_info_topic)
        on_event = calib.depth_on_event_grid
        calib = replace(calib, event_camera=cam, depth_camera=cam if on_event
                        else calib.depth_camera)
    # frames
    frames_path = spec.frames or spec.events
    kind = _kind(frames_path, "frames")
    if kind == "aedat4":
        frames = _aedat(frames_path, cache).frames()
    elif kind == "bag":
        frames = _bag(frames_path, cache).frame_stream(
            spec.frames_topic, spec.frame_stamp or "mid", spec.exposure_us, spec.exposure_topic)
    elif kind == "folder":
        if spec.frame_times is None:
            raise InputError(frames_path, "an image folder needs a times file (--frame-times)")
        frames = folders.frame_folder(frames_path, spec.frame_times, spec.times_unit,
                                      spec.frame_stamp or "mid", spec.exposure_us)
    else:
        raise InputError(frames_path, "frames must come from an .aedat4 file, a bag or a folder")
    # depth
    if calib.depth_camera is None:
        raise calib.error("no depth_camera (a camera, or `event` when depth is on the event "
                          "camera's grid)")
    kind = _kind(spec.depth, "depth")
    if kind == "bag":
        depth = _bag(spec.depth, cache).depth_stream(spec.depth_topic, calib.depth_scale)
    elif kind == "folder":
        if spec.depth_times is None:
            raise InputError(spec.depth, "a depth folder needs a times file (--depth-times)")
        depth = folders.depth_folder(spec.depth, spec.depth_times, spec.times_unit,
                                     require_depth_scale(calib, spec.depth))
    else:
        raise InputError(spec.depth, "depth must come from a ROS1 bag or a folder of PNGs")
    # ground truth
    kind = _kind(spec.gt, "ground truth")
    if kind == "bag":
        gt = _bag(spec.gt, cache).pose_track(spec.gt_topic)
    elif kind == "text":
        gt = folders.tum_track(spec.gt)
    else:
        raise InputError(spec.gt, "ground truth must be a TUM file or a ROS1 bag")
    return checked_inputs(calib, events, frames, depth, gt)


def checked_inputs(calib: RecordingCalib, events: EventSource, frames: FrameStream,
                   depth: DepthStream, gt: PoseTrack) -> _Inputs:
    """The opened streams with their calibration, once the sizes agree and the depth has
    the scale it needs.

    Raises:
        InputError: naming the calibration file (a missing camera or depth_scale, a camera
            whose size differs from its stream's).
    """
    cam = calib.event_camera
    if cam is None:
        raise calib.error("no event_camera")
    if (events.width, events.height) != (cam.width, cam.height):
        raise calib.error(f"event_camera is {cam.width}x{cam.height} but {events.label} "
                          f"declares a {events.width}x{events.height} sensor")
    frame_cam = calib.frame_camera or cam
    if (frames.width, frames.height) != (frame_cam.width, frame_cam.height):
        which = "frame_camera" if calib.frame_camera else "event_camera (frames come from the " \
                                                          "event sensor)"
        raise calib.error(f"{which} is {frame_cam.width}x{frame_cam.height} but the frames in "
                          f"{frames.label} are {frames.width}x{frames.height}")
    dcam = calib.depth_camera
    if dcam is None:
        raise calib.error("no depth_camera (a camera, or `event` when depth is on the event "
                          "camera's grid)")
    if depth.integer_units:
        require_depth_scale(calib, Path(depth.label))
    if (depth.width, depth.height) != (dcam.width, dcam.height):
        raise calib.error(f"depth_camera is {dcam.width}x{dcam.height} but the depth maps in "
                          f"{depth.label} are {depth.width}x{depth.height}")
    return _Inputs(calib, cam, dcam, events, frames, depth, gt)


def require_depth_scale(calib: RecordingCalib, source: Path) -> float:
    """``calib.depth_scale``, which 16-bit depth needs: a guessed scale (RealSense's 1000 is
    TUM's 5000 elsewhere) would scale the whole map without a word."""
    if calib.depth_scale is None:
        raise calib.error(f"missing depth_scale: the depth maps in {source} are 16-bit "
                          "integers (give units per metre, e.g. 1000 for millimetres)")
    return calib.depth_scale


# ------------------------------------------------------------------------------------------
# choosing frames
# ------------------------------------------------------------------------------------------

@dataclass
class _Plan:
    frames: np.ndarray        # [M] indices into the frame stream
    t_start: np.ndarray       # [M] event clock
    t_end: np.ndarray
    depth: np.ndarray         # [M] indices into the depth stream
    depth_dt: np.ndarray      # [M] depth time - exposure end (us)
    poses: np.ndarray         # [M, 4, 4] T_world_event
    dropped: dict[str, int]


def _span(t: np.ndarray) -> str:
    return f"[{t.min() * 1e-6:.3f}, {t.max() * 1e-6:.3f}] s"


def _plan(inp: _Inputs, spec: RecordingSpec) -> _Plan:
    off = inp.calib.time_offsets_us
    t0 = inp.frames.t_start_us + off["frames"]
    t1 = inp.frames.t_end_us + off["frames"]
    if (t1 <= t0).any():
        i = int(np.argmax(t1 <= t0))
        raise InputError(Path(inp.frames.label), f"frame {i}: empty exposure window")
    if (t0[1:] < t1[:-1]).any():
        i = int(np.argmax(t0[1:] < t1[:-1])) + 1
        raise InputError(Path(inp.frames.label), f"frame {i}'s exposure starts before frame "
                                                 f"{i - 1}'s ends (check the stamp convention "
                                                 "and the exposure time)")
    td = inp.depth.t_us + off["depth"]
    tg = inp.gt.t_us + off["mocap"]
    if (np.diff(tg) < 0).any():
        raise InputError(Path(inp.gt.label), "pose times are not sorted")
    keep_g = np.concatenate([[True], np.diff(tg) > 0])  # repeated stamps: keep the first
    tg, poses_body = tg[keep_g], inp.gt.poses[keep_g]
    if len(tg) < 2:
        raise InputError(Path(inp.gt.label), "needs at least two poses")
    for label, t, name in ((inp.depth.label, td, "depth"), (inp.gt.label, tg, "mocap")):
        if t.max() < t0.min() or t.min() > t1.max():
            raise InputError(Path(label), f"its times {_span(t)} (after the {name} offset of "
                                          f"{off[name]} us in {inp.calib.label}) do not overlap "
                                          f"the frames' {_span(t1)}: the clocks do not match")
    # depth: nearest in time to the exposure end
    order = np.argsort(td, kind="stable")
    idx = np.clip(np.searchsorted(td[order], t1), 1, max(1, len(td) - 1))
    cand = np.stack([np.clip(idx - 1, 0, len(td) - 1), np.clip(idx, 0, len(td) - 1)])
    gaps = np.abs(td[order][cand] - t1)
    best = order[cand[np.argmin(gaps, axis=0), np.arange(len(t1))]]
    depth_dt = td[best] - t1
    ok_depth = np.abs(depth_dt) <= spec.max_depth_dt_us
    # mocap: inside the track, bracketing poses close enough in time
    j = np.searchsorted(tg, t1, side="right")
    inside = (t1 >= tg[0]) & (t1 <= tg[-1])
    jj = np.clip(j, 1, len(tg) - 1)
    ok_gt = inside & (tg[jj] - tg[jj - 1] <= spec.max_gt_gap_us)
    usable = ok_depth & ok_gt
    dropped = {"no_depth_within_tolerance": int((~ok_depth).sum()),
               "no_mocap": int((ok_depth & ~ok_gt).sum())}
    idx_all = np.flatnonzero(usable)
    if len(idx_all) == 0:
        raise InputError(Path(inp.depth.label if not ok_depth.any() else inp.gt.label),
                         f"no frame has both a depth map within {spec.max_depth_dt_us / 1000:g} ms "
                         f"of its exposure end and mocap poses around it (frames {_span(t1)}, "
                         f"depth {_span(td)}, mocap {_span(tg)} on the event clock; check "
                         f"time_offsets_us in {inp.calib.label})")
    if spec.first_frame >= len(idx_all):
        raise ConfigError(f"--first-frame {spec.first_frame}: only {len(idx_all)} usable frames")
    sel = idx_all[spec.first_frame:]
    if spec.max_frames is not None:
        sel = sel[: spec.max_frames]
    poses = interpolate_trajectory(tg.astype(np.float64), poses_body,
                                   t1[sel].astype(np.float64)) @ inp.calib.T_body_event
    dropped["outside_requested_range"] = int(len(idx_all) - len(sel))
    return _Plan(sel, t0[sel], t1[sel], best[sel], depth_dt[sel], poses, dropped)


# ------------------------------------------------------------------------------------------
# writing
# ------------------------------------------------------------------------------------------

def _events_in(source: EventSource, lut: np.ndarray, width: int, height: int, t_lo: int,
               t_hi: int, stats: dict) -> Iterator[Events]:
    """Undistorted events with ``t_lo <= t <= t_hi``, checked against the sensor.

    Reads the whole source, so that ``stats`` counts every event: ``in_recording``,
    ``before_first_exposure`` / ``after_last_exposure`` (outside ``[t_lo, t_hi]``, not
    imported), ``read`` (inside) and ``outside_undistorted`` (inside, but no undistorted pixel).
    """
    last_t = None
    for ev in source.batches():
        if (ev.x >= width).any() or (ev.y >= height).any():
            bad = int(np.argmax((ev.x >= width) | (ev.y >= height)))
            raise InputError(Path(source.label),
                             f"event at x={int(ev.x[bad])}, y={int(ev.y[bad])} (t={int(ev.t[bad])} "
                             f"us) is outside the {width}x{height} sensor")
        if (last_t is not None and ev.t[0] < last_t) or (np.diff(ev.t) < 0).any():
            raise InputError(Path(source.label), f"event times go backwards near "
                                                 f"t={int(ev.t[0])} us (events must be sorted)")
        last_t = int(ev.t[-1])
        stats["first_us"] = stats.get("first_us", int(ev.t[0]))
        stats["last_us"] = last_t
        stats["in_recording"] += len(ev)
        before, after = int((ev.t < t_lo).sum()), int((ev.t > t_hi).sum())
        stats["before_first_exposure"] += before
        stats["after_last_exposure"] += after
        if before + after == len(ev):
            continue
        keep = (ev.t >= t_lo) & (ev.t <= t_hi)
        flat = lut[ev.y[keep].astype(np.int64) * width + ev.x[keep]]
        ok = flat >= 0
        stats["read"] += int(keep.sum())
        stats["outside_undistorted"] += int((~ok).sum())
        flat = flat[ok]
        yield Events((flat % width).astype(np.uint16), (flat // width).astype(np.uint16),
                     ev.t[keep][ok], ev.p[keep][ok])


def _sensor_names(spec: RecordingSpec, inp: _Inputs) -> dict[str, str]:
    """Each stream's sensor as the user names it (``spec.sensors``), else as the recording
    names it (an AEDAT4 file's camera, e.g. ``DAVIS346_00000104``), else its source
    (``file`` or ``file:topic``). A preset's sensor names are never used here: a preset fixes
    topics and conventions, and a Kinect bag read with the RealSense preset is still a Kinect."""
    from_data = {"events": (inp.events.sensor, inp.events.label),
                 "frames": (inp.frames.sensor, inp.frames.label),
                 "depth": (None, inp.depth.label), "groundtruth": (None, inp.gt.label)}
    return {key: spec.sensors.get(key) or named or label
            for key, (named, label) in from_data.items()}


def _lockstep(stream_load: Callable[[list[int]], Iterator[tuple[int, np.ndarray]]],
              wanted: np.ndarray) -> Iterator[np.ndarray]:
    """Yield the item for each of ``wanted`` (non-decreasing indices) from one ordered pass."""
    unique = sorted(set(int(i) for i in wanted))
    gen = stream_load(unique)
    current_i = -1  # indices are >= 0: the first wanted index always loads
    for i in wanted:
        while current_i != int(i):
            current_i, current = next(gen)
        yield current


def import_recording(spec: RecordingSpec, out: str | Path, *, overwrite: bool = False,
                     progress: bool = True) -> Path:
    """Import one real recording into a canonical sequence folder (written atomically).

    Args:
        spec: inputs, topics and conventions (a preset is applied first).
        out: the sequence folder to write.
        overwrite: replace an existing sequence folder at ``out``.
        progress: show a progress bar over the frames.

    Returns:
        ``out``.

    Raises:
        InputError: a missing topic (the message lists the bag's topics), clocks that do not
            overlap, a calibration whose sizes disagree with the data, depth without a
            calibration, events outside the sensor, a truncated bag or AEDAT4 file, ... Each
            names the file; nothing is written.
        ConfigError: inconsistent options.
    """
    out = Path(out)
    prepare_output(out, "sequence", overwrite=overwrite,
                   inputs=[spec.events, spec.frames, spec.depth, spec.gt, spec.calib,
                           spec.frame_times, spec.depth_times])
    spec = apply_preset(spec)
    return write_sequence(_open_inputs(spec), spec, out, overwrite=overwrite, progress=progress)


def write_sequence(inp: _Inputs, spec: RecordingSpec, out: Path, *, overwrite: bool,
                   progress: bool, generator: str = "egs-bench import-recording",
                   layout: dict[str, Any] | None = None) -> Path:
    """Write the opened inputs as the sequence folder ``out`` (atomically; ``out`` already
    cleared by ``prepare_output``). ``spec`` gives the frame range, tolerances, names and
    conventions; ``layout`` is recorded as ``recording.layout`` (a dataset importer's own
    conventions)."""
    from egs_bench.datasets.sequence import Sequence, SequenceWriter

    plan = _plan(inp, spec)
    calib = inp.calib
    cam = inp.event_camera
    pinhole = cam.pinhole()
    lut = cam.event_lookup()
    depth_rays = inp.depth_camera.pixel_rays()
    T_frame_event = invert_pose(calib.T_event_frame)
    frame_cam = calib.frame_camera
    on_frame_sensor = frame_cam is None
    name = spec.name or out.name
    meta: dict[str, Any] = {
        "name": name, "source": "real", "generator": generator,
        "generator_version": __version__,
        "width": pinhole.width, "height": pinhole.height, "fx": pinhole.fx, "fy": pinhole.fy,
        "cx": pinhole.cx, "cy": pinhole.cy,
        "distortion": "none (events, frames and depth undistorted at import with the event "
                      f"camera's {cam.model} model)",
        "depth_scale": OUT_DEPTH_SCALE, "eps": 1e-3,
        "exposure_us": int(np.median(plan.t_end - plan.t_start)),
        "frame_rate": float(1e6 / np.median(np.diff(plan.t_end))) if len(plan.t_end) > 1
        else None,
        "events_on_frame_sensor": on_frame_sensor,
        "depth_source": spec.depth_source,
        "sensors": _sensor_names(spec, inp),
        "crf": {"description": "unknown (a real camera; EGS-SLAM learns its response)"},
    }
    ev_stats = {"read": 0, "outside_undistorted": 0, "in_recording": 0,
                "before_first_exposure": 0, "after_last_exposure": 0}
    valid_frac: list[float] = []
    # the writer and the bar are closed on an error too: the bar before the error's line, the
    # event file before its staging folder goes
    with (atomic_dir(out, replace=overwrite) as tmp,
          SequenceWriter(tmp, meta, t_offset_us=int(plan.t_start[0]),
                         with_sharp=False) as writer,
          contextlib.ExitStack() as closing):
        events_out = writer.events
        assert events_out is not None  # t_offset_us given: the writer has an event file
        for batch in _events_in(inp.events, lut, cam.width, cam.height, int(plan.t_start[0]),
                                int(plan.t_end[-1]), ev_stats):
            events_out.append(batch)
        if ev_stats["read"] == 0:
            span = (f"[{ev_stats['first_us'] * 1e-6:.3f}, {ev_stats['last_us'] * 1e-6:.3f}] s"
                    if "first_us" in ev_stats else "none")
            raise InputError(Path(inp.events.label),
                             f"no event during the frames' {_span(plan.t_end)} (events: "
                             f"{span}): the clocks do not overlap")
        depths = _lockstep(inp.depth.load, plan.depth)
        images = _lockstep(inp.frames.load, plan.frames)
        bar = closing.enter_context(ProgressBar(len(plan.frames), f"import {name}",
                                                unit="frame", enabled=progress))
        for k in range(len(plan.frames)):
            depth = reproject_depth(next(depths), depth_rays, calib.T_event_depth, pinhole)
            image = next(images)
            if frame_cam is None:
                rgb = cam.undistort_image(image)
            else:
                rgb, _ = warp_to_depth_camera(image, frame_cam, depth, pinhole, T_frame_event)
            valid_frac.append(float((depth > 0).mean()))
            writer.add_frame(int(plan.t_start[k]), int(plan.t_end[k]), rgb, depth,
                             plan.poses[k])
            bar.update(1)
        bar.close()
        writer.meta["recording"] = {
            "preset": spec.preset,
            # the preset's rig, for reference: nothing in the data confirms it
            "preset_sensors": dict(get_preset(spec.preset).sensors) if spec.preset else None,
            "inputs": {"events": inp.events.label, "frames": inp.frames.label,
                       "depth": inp.depth.label, "groundtruth": inp.gt.label,
                       "calib": str(spec.calib)},
            "frame_stamp": spec.frame_stamp,
            **({"layout": layout} if layout is not None else {}),
            "calib": calib.to_dict(),
            "frames": {"in_recording": len(inp.frames), "imported": len(plan.frames),
                       "first_index": int(plan.frames[0]), "dropped": plan.dropped},
            "events": {"in_recording": ev_stats["in_recording"],
                       "imported": ev_stats["read"] - ev_stats["outside_undistorted"],
                       "dropped_before_first_exposure": ev_stats["before_first_exposure"],
                       "dropped_after_last_exposure": ev_stats["after_last_exposure"],
                       "dropped_outside_undistorted_image": ev_stats["outside_undistorted"],
                       "undistorted_pixels_reached": cam.event_coverage(lut)},
            "depth": {"max_abs_dt_us": int(np.abs(plan.depth_dt).max()),
                      "valid_fraction_mean": float(np.mean(valid_frac)),
                      "valid_fraction_min": float(np.min(valid_frac))},
            "groundtruth": {"interpolated_at": "exposure end, event clock",
                            "poses_in_track": len(inp.gt.t_us)},
        }
        writer.finish()
        Sequence.open(tmp)  # never publish a folder the reader rejects
    return out
