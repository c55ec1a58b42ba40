"""Synthetic scenes: trajectories, determinism, TUM re-timing, make_synthetic, CLI."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from egs_bench.cli import main as cli_main
from egs_bench.datasets.synthetic import (
    SCENES,
    HandheldTrajectory,
    SyntheticSource,
    TumTrajectoryInRoom,
    build_scene,
    default_intrinsics,
    exposure_windows,
    list_scenes,
    make_synthetic,
)
from egs_bench.errors import ConfigError, InputError
from egs_bench.geometry import (
    interpolate_trajectory,
    invert_pose,
    read_tum,
    rotation_angle,
    write_tum,
)
from tests.helpers.cli import assert_cli_error


def test_scene_registry() -> None:
    scenes = list_scenes()
    assert len(scenes) >= 3
    assert all(isinstance(d, str) and len(d) > 20 for d in scenes.values())
    with pytest.raises(ConfigError, match="unknown scene 'nope'.*office"):
        build_scene("nope")


@pytest.mark.parametrize("name", list(SCENES))
def test_camera_and_target_boxes_are_inside_free_space(name: str) -> None:
    scene = build_scene(name)
    grid = np.stack(np.meshgrid(*[np.linspace(a, b, 7) for a, b in zip(*scene.camera_box,
                                                                        strict=True)]), -1)
    assert scene.free_space_violation(grid.reshape(-1, 3), clearance=0.15).max() == 0.0
    assert (np.asarray(scene.target_box[0]) > scene.lo).all()
    assert (np.asarray(scene.target_box[1]) < scene.hi).all()
    # The checker itself flags points in furniture and near walls.
    lo, hi = scene.object_bounds()[0]
    assert scene.free_space_violation(((lo + hi) / 2)[None])[0] > 0
    assert scene.free_space_violation(np.array([[scene.lo[0] + 0.01, 1.0, 1.0]]))[0] > 0


@pytest.mark.parametrize("name", list(SCENES))
def test_handheld_motion_stays_in_the_room_and_looks_at_the_target(name: str) -> None:
    scene = build_scene(name)
    traj = HandheldTrajectory(scene.camera_box, scene.target_box, speed=2.0, seed=3)
    t = np.linspace(0.0, 120.0, 24001)
    eye, target = traj.positions_targets(t)
    assert (eye >= np.asarray(scene.camera_box[0]) - 1e-12).all()
    assert (eye <= np.asarray(scene.camera_box[1]) + 1e-12).all()
    assert scene.free_space_violation(eye, clearance=0.15).max() == 0.0
    poses = traj.poses(t[::40])
    axis = poses[:, :3, 2]
    look = (target - eye)[::40]
    look /= np.linalg.norm(look, axis=1, keepdims=True)
    angle = np.degrees(np.arccos(np.clip((axis * look).sum(1), -1, 1)))
    assert angle.max() < 1.0  # only the small hand shake tilts the axis off the target
    np.testing.assert_allclose(poses[:, :3, :3] @ poses[:, :3, :3].transpose(0, 2, 1),
                               np.broadcast_to(np.eye(3), (len(poses), 3, 3)), atol=1e-12)


def test_handheld_motion_is_smooth_and_speed_rescales_time() -> None:
    scene = build_scene("office")
    dt = 1e-3
    t = np.arange(0.0, 5.0, dt)
    slow = HandheldTrajectory(scene.camera_box, scene.target_box, speed=1.0, seed=5)
    fast = HandheldTrajectory(scene.camera_box, scene.target_box, speed=2.5, seed=5)
    np.testing.assert_allclose(fast.poses(t), slow.poses(2.5 * t), atol=1e-12)
    p = slow.poses(t)
    vel = np.diff(p[:, :3, 3], axis=0) / dt
    acc = np.diff(vel, axis=0) / dt
    speed = np.linalg.norm(vel, axis=1)
    assert 0.05 < speed.mean() < 2.0  # m/s: hand-held, not teleporting
    assert np.linalg.norm(acc, axis=1).max() < 20.0  # m/s^2: no jumps
    ang = np.array([rotation_angle(a, b) for a, b in zip(p[:-1], p[1:], strict=True)]) / dt
    assert ang.max() < 5.0  # rad/s
    assert np.abs(np.diff(ang)).max() / dt < 200.0  # rad/s^2: smooth rotation
    fast_ang = np.array([rotation_angle(a, b) for a, b in
                         zip(fast.poses(t[:-1]), fast.poses(t[1:]), strict=True)]) / dt
    assert fast_ang.mean() > 2.0 * ang.mean()
    static = HandheldTrajectory(scene.camera_box, scene.target_box, speed=0.0, seed=5)
    np.testing.assert_array_equal(static.poses(t[:3]), static.poses(np.zeros(3)))


def test_camera_sees_scene_content_at_finite_depth() -> None:
    scene = build_scene("livingroom")
    cam = default_intrinsics(48, 28)
    traj = HandheldTrajectory(scene.camera_box, scene.target_box, speed=1.0, seed=0)
    source = SyntheticSource(scene, cam, traj, supersample=1)
    far = float(np.linalg.norm(np.subtract(scene.hi, scene.lo)))
    for t_us in (0, 700_000, 2_300_000, 9_100_000):
        frame = source.render(t_us)
        assert (frame.depth > 0.3).all() and (frame.depth < far).all()
        np.testing.assert_array_equal(frame.pose, source.pose(t_us))
        # Looking into the room: the image is textured, not a blank wall.
        luma = frame.rgb.mean(-1)
        assert np.log(luma + 1e-3).std() > 0.3


def test_rendering_is_deterministic_for_a_seed() -> None:
    scene = build_scene("studio")
    cam = default_intrinsics(40, 24)
    frames = []
    for seed in (4, 4, 5):
        traj = HandheldTrajectory(scene.camera_box, scene.target_box, speed=1.0, seed=seed)
        frames.append(SyntheticSource(scene, cam, traj, supersample=2).render(1_234_567))
    np.testing.assert_array_equal(frames[0].rgb, frames[1].rgb)
    np.testing.assert_array_equal(frames[0].depth, frames[1].depth)
    assert not np.allclose(frames[0].pose, frames[2].pose)


def test_tum_trajectory_is_retimed_and_placed_at_the_anchor(shared_data: Path) -> None:
    path = shared_data / "trajectories" / "freiburg1_xyz-groundtruth.txt"
    raw = read_tum(path)
    scene = build_scene("office")
    anchor = scene.anchor_pose()
    placed = TumTrajectoryInRoom(raw, anchor, speed=1.0, time_scale=2.0)
    np.testing.assert_allclose(placed.pose(0.0), anchor, atol=1e-12)
    assert placed.duration_s == pytest.approx(2.0 * (raw.timestamps[-1] - raw.timestamps[0]))
    # Relative motion between two sequence times equals the file's relative motion between
    # the re-timed file times (time_scale 2: sequence second 3 is file second 1.5).
    t_a, t_b = 1.0, 3.0
    file_poses = interpolate_trajectory(raw.timestamps, raw.poses,
                                        raw.timestamps[0] + np.array([t_a, t_b]) / 2.0)
    rel_file = invert_pose(file_poses[0]) @ file_poses[1]
    seq_poses = placed.poses(np.array([t_a, t_b]))
    np.testing.assert_allclose(invert_pose(seq_poses[0]) @ seq_poses[1], rel_file, atol=1e-9)


def _tiny(scene: str, out: Path, **kwargs: Any) -> Path:
    options: dict[str, Any] = dict(frames=3, width=40, height=24, supersample=1, progress=False)
    options.update(kwargs)
    return make_synthetic(scene, out, **options)


def test_make_synthetic_writes_a_valid_sequence(tmp_path: Path) -> None:
    from egs_bench.datasets.sequence import Sequence

    out = _tiny("corridor", tmp_path / "seq", fps=25.0, exposure_ms=12.0, speed=1.5, seed=2)
    seq = Sequence.open(out)
    assert len(seq) == 3
    t_start, t_end = exposure_windows(3, 25.0, 12_000)
    np.testing.assert_array_equal(seq.t_start_us, t_start)
    np.testing.assert_array_equal(seq.t_end_us, t_end)
    assert t_start[0] == 0 and (np.diff(t_end) == 40_000).all()
    assert seq.meta["synthetic"]["scene"] == "corridor"
    assert seq.meta["synthetic"]["motion"] == {"kind": "handheld", "speed": 1.5, "seed": 2}
    assert seq.dense_trajectory is not None and len(seq.dense_trajectory) > 3
    assert len(seq.events) > 0
    # Ground truth agrees with the source: pose and exact depth at exposure end.
    scene = build_scene("corridor")
    traj = HandheldTrajectory(scene.camera_box, scene.target_box, speed=1.5, seed=2)
    source = SyntheticSource(scene, seq.intrinsics, traj, supersample=1)
    for i in range(len(seq)):
        latent = source.render(int(seq.t_end_us[i]))
        np.testing.assert_allclose(seq.poses[i], latent.pose, atol=1e-6)
        np.testing.assert_allclose(seq.depth(i), latent.depth, atol=1.0 / seq.depth_scale)
        assert seq.sharp(i) is not None


def test_make_synthetic_rejects_bad_options_and_trajectories(tmp_path: Path,
                                                             shared_data: Path) -> None:
    with pytest.raises(ConfigError, match="longer than the frame period"):
        _tiny("office", tmp_path / "a", fps=30.0, exposure_ms=40.0)
    with pytest.raises(ConfigError, match="--supersample"):
        _tiny("office", tmp_path / "a", supersample=0)
    xyz = shared_data / "trajectories" / "freiburg1_xyz-groundtruth.txt"
    with pytest.raises(InputError, match="covers .* but the sequence needs"):
        _tiny("office", tmp_path / "a", frames=100, fps=1.0, exposure_ms=5.0, trajectory=xyz)
    # A recorded path that walks 10 m forward leaves any room.
    t = np.linspace(0.0, 2.0, 50)
    poses = np.tile(np.eye(4), (50, 1, 1))
    poses[:, 2, 3] = 5.0 * t
    runaway = tmp_path / "runaway.txt"
    write_tum(runaway, t, poses)
    with pytest.raises(InputError, match="leaves the room's free space"):
        _tiny("office", tmp_path / "a", frames=30, trajectory=runaway)
    assert not (tmp_path / "a").exists()


def test_make_synthetic_replays_a_tum_file(tmp_path: Path, shared_data: Path) -> None:
    from egs_bench.datasets.sequence import Sequence

    xyz = shared_data / "trajectories" / "freiburg1_xyz-groundtruth.txt"
    out = _tiny("office", tmp_path / "tum", trajectory=xyz, time_scale=0.5)
    seq = Sequence.open(out)
    assert seq.meta["synthetic"]["motion"]["kind"] == "tum"
    np.testing.assert_allclose(seq.poses[0], build_scene("office").anchor_pose()
                               @ invert_pose(read_tum(xyz).poses[0])
                               @ interpolate_trajectory(read_tum(xyz).timestamps,
                                                        read_tum(xyz).poses,
                                                        read_tum(xyz).timestamps[:1]
                                                        + seq.t_end_us[0] * 1e-6 / 0.5)[0],
                               atol=1e-6)


def test_cli_list_scenes_and_errors(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    assert cli_main(["list-scenes"]) == 0
    printed = capsys.readouterr().out
    for name in SCENES:
        assert name in printed
    code = cli_main(["make-synthetic", "--scene", "nope", "--out", str(tmp_path / "x")])
    assert_cli_error(code, capsys.readouterr().err, 2, "unknown scene 'nope'")
    assert cli_main(["make-synthetic", "--scene", "studio", "--out", str(tmp_path / "s"),
                     "--frames", "2", "--width", "32", "--height", "20", "--supersample", "1",
                     "--quiet"]) == 0
    assert (tmp_path / "s" / "meta.yaml").is_file()
