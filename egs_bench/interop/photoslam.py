"""Photo-SLAM (Huang et al., CVPR 2024): ORB-SLAM3 tracking with a Gaussian map, RGB-D.

**Export.** ``tum_rgbd`` reads the ``tum-rgbd`` layout with ORB-SLAM3's ``File.version:
"1.0"`` settings (``photoslam_rgbd.yaml``: ``Camera1.fx ...``, ``RGBD.DepthMapFactor``), read
by ``ORB-SLAM3/src/Settings.cc``, which aborts unless reals are written as reals (with a
decimal point) and integers as integers.

**Import** (``--from photoslam``). The output folder: ``CameraTrajectory_TUM.txt``,
``KeyFrameTrajectory_TUM.txt`` (ORB-SLAM3's TUM writers) and keyframe renders
``<iter>_shutdown/image/<iter>_<keyframe id>.jpg`` with ``<iter>_shutdown/ply/cameras.json``
(``id`` -> ``img_name``, the colour file the keyframe came from)
(``GaussianMapper::renderAndRecordAllKeyframes``).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

from egs_bench.errors import InputError
from egs_bench.geometry import Intrinsics
from egs_bench.interop.camera_files import (
    ORB_BASELINE_M,
    ORB_TH_DEPTH,
    file_header,
    opencv_real,
    orb_settings_file,
    orb_settings_text,
)
from egs_bench.interop.orbslam2 import read_orbslam2
from egs_bench.interop.systems import (
    CameraFile,
    ExternalEstimate,
    ExternalSystem,
    ImportOptions,
)


def orbslam3_settings(cam: Intrinsics, *, fps: float, depth_scale: float, name: str) -> str:
    """ORB-SLAM3 ``File.version "1.0"`` RGB-D settings, as Photo-SLAM's ``tum_rgbd`` reads
    them (``Camera.RGB: 1``: Photo-SLAM converts the BGR image to RGB before tracking; no
    distortion keys, so ORB-SLAM3 does not undistort)."""
    lines = ["%YAML:1.0", file_header(cam, name).rstrip("\n"),
             'File.version: "1.0"', 'Camera.type: "PinHole"',
             f"Camera1.fx: {opencv_real(cam.fx)}", f"Camera1.fy: {opencv_real(cam.fy)}",
             f"Camera1.cx: {opencv_real(cam.cx)}", f"Camera1.cy: {opencv_real(cam.cy)}",
             f"Camera.width: {cam.width}", f"Camera.height: {cam.height}",
             f"Camera.fps: {max(1, round(fps))}",
             "Camera.RGB: 1",
             f"Stereo.ThDepth: {opencv_real(ORB_TH_DEPTH)}",
             f"Stereo.b: {opencv_real(ORB_BASELINE_M)}",
             f"RGBD.DepthMapFactor: {opencv_real(depth_scale)}", ""]
    return orb_settings_text(lines)


_SHUTDOWN = re.compile(r"^(\d+)_shutdown$")
_PHOTO_RENDER = re.compile(r"^(\d+)_(\d+)\.jpg$")


def read_photoslam(source: str | Path) -> ExternalEstimate:
    """Photo-SLAM's output folder: trajectories plus keyframe renders of the last
    ``<iter>_shutdown`` folder, keyed by the image file the keyframe came from."""
    source = Path(source)
    if not source.is_dir():
        raise InputError(source, "Photo-SLAM output folder not found")
    est = read_orbslam2(source, camera_file="CameraTrajectory_TUM.txt",
                        keyframe_file="KeyFrameTrajectory_TUM.txt")
    shutdowns = sorted((int(m.group(1)), p) for p in source.iterdir()
                       if p.is_dir() and (m := _SHUTDOWN.match(p.name)))
    if not shutdowns:
        return est
    it, folder = shutdowns[-1]
    cameras = folder / "ply" / "cameras.json"
    images = folder / "image"
    if not images.is_dir():
        return est
    if not cameras.is_file():
        raise InputError(cameras, "not found: it maps the keyframe ids of the renders in "
                                  f"{images} to image files")
    try:
        entries = json.loads(cameras.read_text())
        names = {int(e["id"]): str(e["img_name"]) for e in entries}
    except (json.JSONDecodeError, KeyError, TypeError, ValueError) as exc:
        raise InputError(cameras, f"not a Photo-SLAM cameras.json ({exc})") from None
    for f in sorted(images.iterdir()):
        m = _PHOTO_RENDER.match(f.name)
        if not m or int(m.group(1)) != it:
            continue
        kfid = int(m.group(2))
        if kfid not in names:
            raise InputError(f, f"keyframe id {kfid} is not in {cameras}")
        est.renders[names[kfid]] = f
    est.sources += [str(cameras), str(images)]
    return est


def _read(source: Path, options: ImportOptions) -> ExternalEstimate:
    return read_photoslam(source)


SYSTEM = ExternalSystem(
    key="photoslam", title="Photo-SLAM", read=_read, output="output folder",
    camera_files={"tum-rgbd": CameraFile("photoslam_rgbd.yaml",
                                          orb_settings_file(orbslam3_settings))})
