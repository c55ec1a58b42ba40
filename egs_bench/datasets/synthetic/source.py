"""Latent source for the generation pipeline, and the ``make_synthetic`` entry point."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from egs_bench.color import LdrResponse
from egs_bench.datasets.esim import EventSimConfig
from egs_bench.datasets.pipeline import LatentFrame, SamplingConfig, generate_sequence
from egs_bench.datasets.synthetic.raycast import Renderer
from egs_bench.datasets.synthetic.scene import Scene, pack_scene
from egs_bench.datasets.synthetic.scenes import build_scene
from egs_bench.datasets.synthetic.trajectory import HandheldTrajectory, TumTrajectoryInRoom
from egs_bench.errors import ConfigError, InputError
from egs_bench.geometry import Intrinsics, Trajectory, read_tum
from egs_bench.outputs import prepare_output

# Focal length of EventReplica at 448x256 (600 px at 1200 wide, resized to 459): ~88 deg HFOV.
FOCAL_PER_WIDTH = 229.5 / 448.0
# A recorded trajectory may not bring the camera closer than this to walls or object bounds.
TRAJECTORY_CLEARANCE_M = 0.1


class CameraPath(Protocol):
    def poses(self, t_s: np.ndarray) -> np.ndarray: ...


def default_intrinsics(width: int, height: int) -> Intrinsics:
    """Pinhole camera with EventReplica's field of view, principal point at the image centre."""
    f = FOCAL_PER_WIDTH * width
    return Intrinsics(f, f, width / 2.0, height / 2.0, width, height)


class SyntheticSource:
    """A procedural scene seen along a camera path; the pipeline's ``LatentSource``.

    Args:
        scene: the scene.
        intrinsics: camera.
        path: camera path with ``poses(t_s [N]) -> [N, 4, 4]`` (seconds, ``T_wc``).
        supersample: ``ss x ss`` anti-aliasing samples per pixel.
        lod_bias: texture mip level bias (see :class:`Renderer`).
    """

    def __init__(
        self,
        scene: Scene,
        intrinsics: Intrinsics,
        path: CameraPath,
        supersample: int = 2,
        lod_bias: float = 0.0,
    ) -> None:
        self.scene = scene
        self.intrinsics = intrinsics
        self.path = path
        self.renderer = Renderer(pack_scene(scene), intrinsics, supersample, lod_bias=lod_bias)

    def pose(self, t_us: int) -> np.ndarray:
        """``T_wc`` [4, 4] at ``t_us`` microseconds."""
        return self.path.poses(np.array([t_us * 1e-6]))[0]

    def render(self, t_us: int) -> LatentFrame:
        """Sharp linear HDR frame, exact z-depth and pose at ``t_us`` microseconds."""
        pose = self.pose(t_us)
        rgb, depth = self.renderer.render(pose)
        return LatentFrame(rgb=rgb, depth=depth, pose=pose)


def exposure_windows(frames: int, fps: float, exposure_us: int) -> tuple[np.ndarray, np.ndarray]:
    """Frame ``i`` ends its exposure at ``exposure_us + round(i * 1e6 / fps)`` and starts
    ``exposure_us`` earlier (so the first exposure starts at t = 0). Returns int64 [N] each."""
    t_end = exposure_us + np.round(np.arange(frames) * 1e6 / fps).astype(np.int64)
    return t_end - exposure_us, t_end


def _load_tum_path(path: Path, scene: Scene, speed: float, time_scale: float,
                   duration_s: float) -> TumTrajectoryInRoom:
    traj = read_tum(path, min_poses=2)
    keep = np.concatenate([[True], np.diff(traj.timestamps) > 0])  # drop repeated stamps
    traj = Trajectory(traj.timestamps[keep], traj.poses[keep])
    if len(traj) < 2:
        raise InputError(path, "needs at least two poses with distinct time stamps")
    cam_path = TumTrajectoryInRoom(traj, scene.anchor_pose(), speed, time_scale)
    if cam_path.duration_s < duration_s:
        raise InputError(
            path,
            f"covers {cam_path.duration_s:.2f} s after re-timing (speed {speed}, time scale "
            f"{time_scale}) but the sequence needs {duration_s:.2f} s: use fewer frames, a "
            "smaller --time-scale or a higher --speed",
        )
    check_t = np.linspace(0.0, duration_s, max(2, int(duration_s * 200)))
    centres = cam_path.poses(check_t)[:, :3, 3]
    violation = scene.free_space_violation(centres, TRAJECTORY_CLEARANCE_M)
    if violation.max() > 0:
        worst = int(np.argmax(violation))
        raise InputError(
            path,
            f"placed at the '{scene.name}' camera anchor, the path leaves the room's free space "
            f"(by {violation[worst]:.2f} m at t = {check_t[worst]:.2f} s); it must stay "
            f"{TRAJECTORY_CLEARANCE_M} m from walls and furniture",
        )
    return cam_path


def _check_options(frames: int, width: int, height: int, fps: float, exposure_ms: float,
                   speed: float, time_scale: float, supersample: int) -> None:
    checks = [
        (frames >= 1, f"--frames must be >= 1, got {frames}"),
        (width >= 16 and height >= 16, f"image must be at least 16x16, got {width}x{height}"),
        (width <= 4096 and height <= 4096, f"image must be at most 4096x4096, got {width}x"
                                            f"{height}"),
        (math.isfinite(fps) and fps > 0, f"--fps must be > 0, got {fps}"),
        (math.isfinite(exposure_ms) and exposure_ms > 0,
         f"--exposure-ms must be > 0, got {exposure_ms}"),
        (math.isfinite(speed) and speed >= 0, f"--speed must be >= 0, got {speed}"),
        (math.isfinite(time_scale) and time_scale > 0,
         f"--time-scale must be > 0, got {time_scale}"),
        (1 <= supersample <= 8, f"--supersample must be in 1..8, got {supersample}"),
    ]
    for ok, message in checks:
        if not ok:
            raise ConfigError(message)
    if exposure_ms * 1e3 > 1e6 / fps + 1e-6:
        raise ConfigError(f"--exposure-ms {exposure_ms} is longer than the frame period "
                          f"{1e3 / fps:.3f} ms at {fps} fps")


def make_synthetic(
    scene: str,
    out: str | Path,
    *,
    frames: int = 100,
    width: int = 448,
    height: int = 256,
    fps: float = 30.0,
    exposure_ms: float = 20.0,
    speed: float = 1.0,
    seed: int = 0,
    trajectory: str | Path | None = None,
    time_scale: float = 1.0,
    supersample: int = 2,
    gain: float = 1.0,
    pos_threshold: float = 0.25,
    neg_threshold: float = 0.25,
    sampling: SamplingConfig | None = None,
    progress: bool = True,
    overwrite: bool = False,
) -> Path:
    """Generate a synthetic sequence (blurred LDR frames, sharp GT, depth, events, poses).

    Args:
        scene: scene name (see :func:`list_scenes`).
        out: destination sequence folder (written atomically).
        frames, width, height, fps: frame count, image size and frame rate.
        exposure_ms: exposure time; frame ``i`` is exposed over
            ``[t_end_i - exposure, t_end_i]`` with ``t_end_i = exposure + i / fps``.
        speed: motion speed factor (blur grows with it); 0 = static camera.
        seed: seeds the hand-held motion.
        trajectory: optional TUM file replayed from the scene's camera anchor instead of the
            hand-held motion; its time axis is multiplied by ``time_scale / speed``.
        time_scale: stretch of the TUM file's time axis (> 1 = slower, less blur).
        supersample: ``ss x ss`` anti-aliasing samples per pixel.
        gain: camera response gain (radiance 1 / gain is LDR white).
        pos_threshold, neg_threshold: event contrast thresholds (log units).
        sampling: temporal sampling rule of the pipeline (default: its defaults).
        progress: show a progress bar.
        overwrite: replace an existing ``out``.

    Returns:
        The sequence folder.

    Raises:
        ConfigError: unknown scene or invalid option. InputError: unusable trajectory file.
    """
    _check_options(frames, width, height, fps, exposure_ms, speed, time_scale, supersample)
    prepare_output(out, "sequence", overwrite=overwrite, inputs=[trajectory])
    sc = build_scene(scene)
    exposure_us = max(1, int(round(exposure_ms * 1e3)))
    t_start, t_end = exposure_windows(frames, fps, exposure_us)
    duration_s = float(t_end[-1]) * 1e-6
    path: CameraPath
    if trajectory is not None:
        trajectory = Path(trajectory)
        if speed == 0:
            raise ConfigError("--speed must be > 0 with --trajectory")
        path = _load_tum_path(trajectory, sc, speed, time_scale, duration_s)
        motion: dict[str, Any] = {"kind": "tum", "file": str(trajectory), "speed": speed,
                                  "time_scale": time_scale,
                                  "placement": "file motion relative to its first pose, "
                                               "replayed from the scene's camera anchor"}
    else:
        path = HandheldTrajectory(sc.camera_box, sc.target_box, speed=speed, seed=seed)
        motion = {"kind": "handheld", "speed": speed, "seed": seed}
    source = SyntheticSource(sc, default_intrinsics(width, height), path, supersample)
    meta_extra = {
        "source": "synthetic",
        "synthetic": {
            "scene": sc.name,
            "description": sc.description,
            "motion": motion,
            "supersample": supersample,
            "renderer": "analytic ray casting (egs_bench.datasets.synthetic), exact z-depth, "
                        "mip-mapped scikit-image textures, point lights + emitters, no shadows",
        },
    }
    sim = EventSimConfig(pos_threshold=pos_threshold, neg_threshold=neg_threshold, seed=seed)
    return generate_sequence(
        source,
        t_start,
        t_end,
        out,
        meta_extra=meta_extra,
        sim=sim,
        response=LdrResponse(gain=gain),
        sampling=sampling or SamplingConfig(),
        progress=progress,
        overwrite=overwrite,
        inputs=[trajectory],
    )
