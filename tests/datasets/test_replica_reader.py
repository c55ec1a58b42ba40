"""Replica-layout reader/writer: round trip, intrinsics convention, and every bad-input case."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from egs_bench.datasets.replica import export_replica_layout, read_replica
from egs_bench.errors import InputError
from egs_bench.geometry import Intrinsics, pose_from_tq

SMALL = Intrinsics(fx=50.0, fy=52.0, cx=40.0, cy=24.0, width=80, height=48)


def _poses(n: int) -> np.ndarray:
    rng = np.random.default_rng(3)
    q = rng.normal(size=(n, 4))
    return pose_from_tq(rng.normal(size=(n, 3)), q / np.linalg.norm(q, axis=1, keepdims=True))


def _scene(tmp_path: Path, n: int = 3, intr: Intrinsics = SMALL, name: str = "scene") -> Path:
    rng = np.random.default_rng(0)
    rgb = [rng.integers(0, 256, (intr.height, intr.width, 3), dtype=np.uint8) for _ in range(n)]
    depth = [rng.uniform(0.5, 8.0, (intr.height, intr.width)).astype(np.float32) for _ in range(n)]
    depth[0][0, 0] = 0.0
    return export_replica_layout(rgb, depth, _poses(n), tmp_path / name, intrinsics=intr,
                                 image_format="png")


def test_round_trip_exact(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    rgb = [rng.integers(0, 256, (48, 80, 3), dtype=np.uint8) for _ in range(3)]
    depth = [rng.uniform(0.5, 8.0, (48, 80)).astype(np.float32) for _ in range(3)]
    poses = _poses(3)
    export_replica_layout(rgb, depth, poses, tmp_path / "s", intrinsics=SMALL, image_format="png")
    scene = read_replica(tmp_path / "s")
    assert len(scene) == 3 and scene.name == "s"
    assert scene.intrinsics == SMALL  # the 0.5 shift is undone on read
    np.testing.assert_allclose(scene.poses, poses, atol=1e-12)
    for i in range(3):
        np.testing.assert_array_equal(scene.rgb(i), rgb[i])
        np.testing.assert_allclose(scene.depth(i), depth[i], atol=0.5 / 6553.5 + 1e-6)
        assert scene.depth(i).dtype == np.float32


def test_cam_params_are_converted_to_our_pixel_convention(tmp_path: Path) -> None:
    path = _scene(tmp_path)
    cam = json.loads((path / "cam_params.json").read_text())["camera"]
    assert cam["cx"] == SMALL.cx - 0.5 and cam["cy"] == SMALL.cy - 0.5
    # the same file one level up (as in the NICE-SLAM download) is found too
    (path / "cam_params.json").rename(tmp_path / "cam_params.json")
    scene = read_replica(path)
    assert scene.cam_params_path == tmp_path / "cam_params.json"
    assert (scene.intrinsics.cx, scene.intrinsics.cy) == (40.0, 24.0)


def test_replica_defaults_without_cam_params(tmp_path: Path) -> None:
    blank = [np.zeros((680, 1200, 3), np.uint8)] * 2
    export_replica_layout(blank, [np.ones((680, 1200))] * 2, _poses(2), tmp_path / "r",
                          image_format="png")
    scene = read_replica(tmp_path / "r")
    assert scene.cam_params_path is None and scene.depth_scale == 6553.5
    # Replica: fx = fy = 600, cx = 599.5, cy = 339.5 with pixel centres at integers
    assert scene.intrinsics == Intrinsics(600.0, 600.0, 600.0, 340.0, 1200, 680)
    # the image centre in our convention is W / 2 = 600: the principal point
    assert scene.intrinsics.cx == scene.intrinsics.width / 2


def test_jpeg_layout_as_nice_slam(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    smooth = cv2.GaussianBlur(rng.integers(0, 256, (48, 80, 3), dtype=np.uint8), (0, 0), 3)
    export_replica_layout([smooth] * 2, [np.ones((48, 80))] * 2, _poses(2), tmp_path / "j",
                          intrinsics=SMALL)
    scene = read_replica(tmp_path / "j")
    assert scene.rgb_paths[0].name == "frame000000.jpg"
    assert np.abs(scene.rgb(1).astype(int) - smooth).mean() < 2.0


# --- bad input: each raises InputError naming the file and the problem ----------------------------


def _expect(path: Path, *words: str, **kwargs: Any) -> InputError:
    with pytest.raises(InputError) as info:
        read_replica(path, **kwargs)
    return info.value


def test_missing_scene_folder(tmp_path: Path) -> None:
    err = _expect(tmp_path / "nowhere")
    assert "nowhere" in str(err) and "does not exist" in str(err)


def test_missing_results_folder(tmp_path: Path) -> None:
    (tmp_path / "s").mkdir()
    err = _expect(tmp_path / "s")
    assert err.path == tmp_path / "s" / "results" and "results" in err.problem


def test_missing_traj(tmp_path: Path) -> None:
    path = _scene(tmp_path)
    (path / "traj.txt").unlink()
    err = _expect(path)
    assert err.path == path / "traj.txt" and "missing" in err.problem


def test_no_frames(tmp_path: Path) -> None:
    path = _scene(tmp_path)
    for f in (path / "results").glob("frame*"):
        f.unlink()
    err = _expect(path)
    assert err.path == path / "results" and "no colour frames" in err.problem


def test_depth_count_mismatch(tmp_path: Path) -> None:
    path = _scene(tmp_path)
    (path / "results" / "depth000002.png").unlink()
    err = _expect(path)
    assert "3 colour frames but 2 depth frames" in err.problem


def test_pose_count_mismatch(tmp_path: Path) -> None:
    path = _scene(tmp_path)
    lines = (path / "traj.txt").read_text().splitlines()
    (path / "traj.txt").write_text("\n".join(lines[:2]) + "\n")
    err = _expect(path)
    assert err.path == path / "traj.txt" and "2 poses but 3 frames" in err.problem


def test_gap_in_numbering(tmp_path: Path) -> None:
    path = _scene(tmp_path)
    (path / "results" / "frame000001.png").rename(path / "results" / "frame000007.png")
    err = _expect(path)
    assert "missing number 1" in err.problem


@pytest.mark.parametrize(
    ("mutate", "expected"),
    [
        (lambda f: f[:15], "line 2: expected 16 numbers, found 15"),
        (lambda f: [*f[:15], "abc"], "line 2: not a number"),
        (lambda f: [*f[:5], "nan", *f[6:]], "line 2: non-finite value"),
        (lambda f: [*f[:12], "0", "0", "1", "1"], "line 2: last matrix row"),
        (lambda f: ["2", *f[1:]], "line 2: the 3x3 block is not a rotation"),
    ],
    ids=["short", "text", "nan", "last-row", "not-rotation"],
)
def test_bad_traj_line(tmp_path: Path, mutate: Callable[..., Any], expected: str) -> None:
    path = _scene(tmp_path)
    lines = (path / "traj.txt").read_text().splitlines()
    lines[1] = " ".join(mutate(lines[1].split()))
    (path / "traj.txt").write_text("\n".join(lines) + "\n")
    err = _expect(path)
    assert err.path == path / "traj.txt" and expected in err.problem


def test_wrong_image_size(tmp_path: Path) -> None:
    path = _scene(tmp_path)
    cv2.imwrite(str(path / "results" / "frame000001.png"), np.zeros((40, 80, 3), np.uint8))
    err = _expect(path)
    assert err.path.name == "frame000001.png" and "80x40, expected 80x48" in err.problem
    # the check also runs when a frame is loaded (headers skipped on open)
    scene = read_replica(path, check_image_headers=False)
    with pytest.raises(InputError, match="frame000001.png: image is 80x40"):
        scene.rgb(1)


def test_depth_not_16_bit(tmp_path: Path) -> None:
    path = _scene(tmp_path)
    cv2.imwrite(str(path / "results" / "depth000000.png"), np.zeros((48, 80), np.uint8))
    err = _expect(path)
    assert err.path.name == "depth000000.png" and "16-bit" in err.problem
    scene = read_replica(path, check_image_headers=False)
    with pytest.raises(InputError, match="depth000000.png: depth PNG must be single-channel"):
        scene.depth(0)


def test_corrupt_image(tmp_path: Path) -> None:
    path = _scene(tmp_path)
    (path / "results" / "frame000002.png").write_bytes(b"not an image")
    err = _expect(path)
    assert err.path.name == "frame000002.png" and "unreadable" in err.problem
    scene = read_replica(path, check_image_headers=False)
    with pytest.raises(InputError, match="frame000002.png: cannot read image"):
        scene.rgb(2)


@pytest.mark.parametrize(
    ("content", "expected"),
    [
        ("{not json", "not valid JSON"),
        ('{"camera": {"fx": NaN}}', "'fx' must be a positive finite number"),
        ('{"camera": {"fy": -3}}', "'fy' must be a positive finite number"),
        ('{"camera": {"w": 80.5}}', "'w' must be an integer"),
        ("[1, 2]", "expected a JSON object"),
    ],
    ids=["json", "nan", "negative", "non-integer", "not-object"],
)
def test_bad_cam_params(tmp_path: Path, content: str, expected: str) -> None:
    path = _scene(tmp_path)
    (path / "cam_params.json").write_text(content)
    err = _expect(path)
    assert err.path == path / "cam_params.json" and expected in err.problem


def test_explicit_cam_params_missing(tmp_path: Path) -> None:
    path = _scene(tmp_path)
    err = _expect(path, cam_params=tmp_path / "nope.json")
    assert err.path == tmp_path / "nope.json"
