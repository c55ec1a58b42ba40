from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from egs_bench.errors import InputError
from egs_bench.geometry import (
    Intrinsics,
    interpolate_pose,
    interpolate_trajectory,
    invert_pose,
    pose_from_tq,
    pose_to_tq,
    read_tum,
    rotation_angle,
    write_tum,
)


def _random_pose(rng: np.random.Generator) -> np.ndarray:
    return pose_from_tq(rng.normal(size=3), Rotation.random(random_state=rng).as_quat())


def test_pose_roundtrip_and_inverse() -> None:
    rng = np.random.default_rng(0)
    pose = _random_pose(rng)
    t, q = pose_to_tq(pose)
    np.testing.assert_allclose(pose_from_tq(t, q), pose, atol=1e-12)
    np.testing.assert_allclose(invert_pose(pose) @ pose, np.eye(4), atol=1e-12)


def test_interpolate_pose_endpoints_and_midpoint() -> None:
    rng = np.random.default_rng(1)
    a, b = _random_pose(rng), _random_pose(rng)
    np.testing.assert_allclose(interpolate_pose(a, b, 0.0), a, atol=1e-12)
    np.testing.assert_allclose(interpolate_pose(a, b, 1.0), b, atol=1e-12)
    mid = interpolate_pose(a, b, 0.5)
    # geodesic midpoint: equal angle to both ends, translation halfway
    assert rotation_angle(a, mid) == pytest.approx(rotation_angle(mid, b), abs=1e-9)
    np.testing.assert_allclose(mid[:3, 3], (a[:3, 3] + b[:3, 3]) / 2, atol=1e-12)
    batch = interpolate_pose(a, b, np.array([0.0, 0.5, 1.0]))
    assert batch.shape == (3, 4, 4)
    np.testing.assert_allclose(batch[1], mid, atol=1e-12)


def test_interpolate_trajectory_matches_pairwise() -> None:
    rng = np.random.default_rng(2)
    poses = np.stack([_random_pose(rng) for _ in range(3)])
    times = np.array([0.0, 1.0, 3.0])
    out = interpolate_trajectory(times, poses, np.array([0.25, 2.0]))
    np.testing.assert_allclose(out[0], interpolate_pose(poses[0], poses[1], 0.25), atol=1e-9)
    np.testing.assert_allclose(out[1], interpolate_pose(poses[1], poses[2], 0.5), atol=1e-9)


def test_tum_roundtrip(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    poses = np.stack([_random_pose(rng) for _ in range(4)])
    write_tum(tmp_path / "t.txt", np.arange(4) * 0.1, poses)
    traj = read_tum(tmp_path / "t.txt")
    np.testing.assert_allclose(traj.poses, poses, atol=1e-8)
    np.testing.assert_allclose(traj.timestamps, np.arange(4) * 0.1)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("0 1 2 3 0 0 0\n", "expected 8 numbers"),
        ("0 1 2 3 0 0 0 x\n", "not a number"),
        ("0 1 2 nan 0 0 0 1\n", "NaN"),
        ("0 1 2 3 0 0 0 0\n", "zero quaternion"),
        ("1 0 0 0 0 0 0 1\n0 0 0 0 0 0 0 1\n", "not sorted"),
    ],
)
def test_tum_bad_input(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "bad.txt"
    path.write_text(text)
    with pytest.raises(InputError, match=message) as info:
        read_tum(path)
    assert str(path) in str(info.value)


def test_tum_missing_file(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="not found"):
        read_tum(tmp_path / "missing.txt")


def test_intrinsics_resize_crop_keep_projection() -> None:
    """A 3-D point lands on the same content before and after resize + crop (gsplat convention)."""
    cam = Intrinsics(600.0, 600.0, 600.0, 340.0, 1200, 680)
    small = cam.resized(459, 260)
    x0, y0 = small.center_crop_offsets(448, 256)
    crop = small.cropped(x0, y0, 448, 256)
    point = np.array([[0.3, -0.2, 2.0]])
    uv = cam.project(point)[0]
    expected = np.array([uv[0] * 459 / 1200 - x0, uv[1] * 260 / 680 - y0])
    np.testing.assert_allclose(crop.project(point)[0], expected, atol=1e-9)
    # back-projecting a pixel centre and projecting it again returns the centre
    depth = np.full((256, 448), 2.0)
    pts = crop.backproject(depth)
    np.testing.assert_allclose(crop.project(pts[10, 20][None])[0], [20.5, 10.5], atol=1e-9)
