"""ORB-SLAM2 (Mur-Artal and Tardos, 2017), RGB-D.

**Export.** ``rgbd_tum`` reads the ``tum-rgbd`` layout (``associations.txt``) with an OpenCV
``FileStorage`` YAML like ``Examples/RGB-D/TUM1.yaml`` (``orbslam2_rgbd.yaml``: ``Camera.fx
...``, ``DepthMapFactor``); values are read without type checks.

**Import** (``--from orbslam2``). ``CameraTrajectory.txt`` (every tracked frame; lost frames
skipped) and ``KeyFrameTrajectory.txt``, both TUM with ``%.6f`` stamps and no header, written
into the working directory (``System::SaveTrajectoryTUM``); give the folder or one file.
"""

from __future__ import annotations

from pathlib import Path

from egs_bench.errors import InputError
from egs_bench.geometry import Intrinsics, read_tum
from egs_bench.interop.camera_files import (
    ORB_BASELINE_M,
    ORB_TH_DEPTH,
    file_header,
    frame_rate,
    opencv_real,
    orb_settings_file,
    orb_settings_text,
)
from egs_bench.interop.systems import (
    CameraFile,
    ExternalEstimate,
    ExternalSystem,
    ImportOptions,
)


def orbslam2_settings(cam: Intrinsics, *, fps: float, depth_scale: float, name: str) -> str:
    """ORB-SLAM2 RGB-D settings (``./Examples/RGB-D/rgbd_tum VOC THIS_FILE DIR ASSOC``).

    ``Camera.RGB: 0``: ``rgbd_tum`` loads images with ``cv::imread``, i.e. in BGR order.
    """
    lines = ["%YAML:1.0", file_header(cam, name).rstrip("\n"),
             f"Camera.fx: {opencv_real(cam.fx)}", f"Camera.fy: {opencv_real(cam.fy)}",
             f"Camera.cx: {opencv_real(cam.cx)}", f"Camera.cy: {opencv_real(cam.cy)}",
             "Camera.k1: 0.0", "Camera.k2: 0.0", "Camera.p1: 0.0", "Camera.p2: 0.0",
             "Camera.k3: 0.0",
             f"Camera.width: {cam.width}", f"Camera.height: {cam.height}",
             f"Camera.fps: {opencv_real(frame_rate(fps))}",
             f"Camera.bf: {opencv_real(ORB_BASELINE_M * cam.fx)}",
             "Camera.RGB: 0",
             f"ThDepth: {opencv_real(ORB_TH_DEPTH)}",
             f"DepthMapFactor: {opencv_real(depth_scale)}", ""]
    return orb_settings_text(lines)


def read_orbslam2(source: str | Path, *, camera_file: str = "CameraTrajectory.txt",
                  keyframe_file: str = "KeyFrameTrajectory.txt") -> ExternalEstimate:
    """ORB-SLAM2 (or ORB-SLAM3 with ``*_TUM.txt`` names): a folder holding both files, or one
    of them (a file whose name contains ``KeyFrame`` is the keyframe trajectory)."""
    source = Path(source)
    cam: Path | None
    kf: Path | None
    if source.is_dir():
        cam, kf = source / camera_file, source / keyframe_file
        cam = cam if cam.is_file() else None
        kf = kf if kf.is_file() else None
    elif source.is_file():
        cam, kf = (None, source) if "keyframe" in source.name.lower() else (source, None)
    else:
        raise InputError(source, "not found")
    if cam is not None:
        traj = read_tum(cam, min_poses=3)
        est = ExternalEstimate(traj.poses, stamps_s=traj.timestamps, sources=[str(cam)])
        if kf is not None:
            est.keyframe_stamps_s = read_tum(kf).timestamps
            est.sources.append(str(kf))
        return est
    if kf is None:
        raise InputError(source, f"holds neither {camera_file} nor {keyframe_file}")
    traj = read_tum(kf, min_poses=3)
    # ORB-SLAM writes its keyframe trajectory at shutdown
    return ExternalEstimate(traj.poses, stamps_s=traj.timestamps, poses_kind="keyframes",
                            keyframe_stamps_s=traj.timestamps, sources=[str(kf)],
                            written_at_end=True)


def _read(source: Path, options: ImportOptions) -> ExternalEstimate:
    return read_orbslam2(source)


SYSTEM = ExternalSystem(
    key="orbslam2", title="ORB-SLAM2", read=_read,
    output="CameraTrajectory.txt / KeyFrameTrajectory.txt or their folder",
    camera_files={"tum-rgbd": CameraFile("orbslam2_rgbd.yaml",
                                          orb_settings_file(orbslam2_settings))})
