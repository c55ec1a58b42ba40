"""EventReplica end to end: a tiny synthetic RGB-D sequence exported to Replica layout, turned
into a canonical sequence by the library and by the CLI; the latent source's contract."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from egs_bench.cli import main
from egs_bench.color import linear_to_srgb
from egs_bench.datasets.eventreplica import (
    ReplicaSource,
    ResizeCrop,
    exposure_windows,
    make_eventreplica,
)
from egs_bench.datasets.replica import export_replica_layout, read_replica
from egs_bench.datasets.sequence import Sequence
from egs_bench.errors import ConfigError
from egs_bench.geometry import Intrinsics, interpolate_pose
from tests.helpers import replica_testscene as scene
from tests.helpers.cli import assert_cli_error

# Input camera (egs-bench convention) of the exported scene: small to keep the test fast.
CAM = Intrinsics(fx=60.0, fy=60.0, cx=60.0, cy=36.0, width=120, height=72)
N_FRAMES = 5


@pytest.fixture(scope="module")
def replica_dir(tmp_path_factory: pytest.TempPathFactory
                ) -> tuple[Path, dict[str, tuple[list[np.ndarray], list[np.ndarray], np.ndarray]]]:
    """``root/sceneA`` and ``root/sceneB`` in NICE-SLAM layout (lossless PNG colour)."""
    root = tmp_path_factory.mktemp("replica")
    data = {}
    for name, speed in (("sceneA", 1.0), ("sceneB", -0.7)):
        rgbs, depths, poses = [], [], []
        for k in range(N_FRAMES):
            pose = scene.look_pose([0.03 * k * speed, -0.01 * k, 0.02 * k],
                                   yaw_deg=1.5 * k * speed, pitch_deg=-0.5 * k)
            rgb, depth = scene.render(pose, CAM.fx, CAM.fy, CAM.cx, CAM.cy, CAM.width, CAM.height,
                                      supersample=1)
            rgbs.append(np.round(linear_to_srgb(rgb) * 255).astype(np.uint8))
            depths.append(depth)
            poses.append(pose)
        export_replica_layout(rgbs, depths, poses, root / name, intrinsics=CAM,
                              image_format="png")
        data[name] = (rgbs, depths, np.stack(poses))
    return root, data


def test_source_contract(
        replica_dir: tuple[Path, dict[str, tuple[list[np.ndarray], list[np.ndarray], np.ndarray]]]
) -> None:
    root, data = replica_dir
    rgbs, depths, poses = data["sceneA"]
    geo = ResizeCrop(width=112, height=64, resize=None)
    src = ReplicaSource(read_replica(root / "sceneA"), fps=20.0, stride=2, geometry=geo)
    np.testing.assert_array_equal(src.frame_indices, [0, 2, 4])
    np.testing.assert_array_equal(src.key_times_us, [0, 50_000, 100_000])
    assert src.intrinsics == Intrinsics(60.0, 60.0, 56.0, 32.0, 112, 64)
    # key times: the original frame (crop of it), its depth and pose, exactly
    key = src.render(50_000)
    ldr = np.round(linear_to_srgb(key.rgb) * 255).astype(np.uint8)
    np.testing.assert_array_equal(ldr, rgbs[2][4:68, 4:116])
    np.testing.assert_allclose(key.depth, depths[2][4:68, 4:116], atol=1e-4)
    np.testing.assert_allclose(key.pose, poses[2], atol=1e-12)
    # between key times: slerp/lerp pose, a full frame
    mid = src.render(75_000)
    np.testing.assert_allclose(mid.pose, interpolate_pose(poses[2], poses[4], 0.5), atol=1e-12)
    np.testing.assert_allclose(src.pose(75_000), mid.pose, atol=1e-12)
    assert mid.rgb.shape == (64, 112, 3) and mid.rgb.dtype == np.float32
    assert mid.depth.shape == (64, 112) and (mid.rgb >= 0).all()
    with pytest.raises(ValueError, match="outside"):
        src.render(100_001)
    with pytest.raises(ConfigError, match="need at least 2 frames"):
        ReplicaSource(read_replica(root / "sceneA"), fps=20.0, stride=10)


def test_exposure_windows_skip_frames_without_history() -> None:
    ids, t0, t1 = exposure_windows(np.array([0, 33_333, 66_667]), 20_000)
    np.testing.assert_array_equal(ids, [1, 2])
    np.testing.assert_array_equal(t0, [13_333, 46_667])
    np.testing.assert_array_equal(t1, [33_333, 66_667])


def test_make_eventreplica_end_to_end(
        replica_dir: tuple[Path, dict[str, tuple[list[np.ndarray], list[np.ndarray], np.ndarray]]],
        tmp_path: Path
) -> None:
    root, data = replica_dir
    rgbs, depths, poses = data["sceneA"]
    out = make_eventreplica(root / "sceneA", tmp_path / "seq", fps=30.0, exposure_ms=25.0,
                            width=112, height=64, resize=None, progress=False)
    seq = Sequence.open(out)
    assert len(seq) == N_FRAMES - 1  # frame 0 only starts the interpolation
    assert seq.intrinsics == Intrinsics(60.0, 60.0, 56.0, 32.0, 112, 64)
    np.testing.assert_array_equal(seq.t_end_us, np.round(np.arange(1, N_FRAMES) * 1e6 / 30))
    np.testing.assert_array_equal(seq.t_start_us, seq.t_end_us - 25_000)
    assert seq.meta["eventreplica"]["original_frames"] == [1, 2, 3, 4]
    for i in range(len(seq)):
        # sharp GT = the original frame at exposure end (linearise -> re-encode is lossless)
        sharp_img = seq.sharp(i)
        assert sharp_img is not None
        sharp = sharp_img.astype(int)
        assert np.abs(sharp - rgbs[i + 1][4:68, 4:116]).max() <= 1
        np.testing.assert_allclose(seq.depth(i), depths[i + 1][4:68, 4:116], atol=2e-4)
        np.testing.assert_allclose(seq.poses[i], poses[i + 1], atol=1e-5)
        # the observed frame is blurred: different from the sharp one, and smoother
        observed = seq.rgb(i).astype(float)
        assert np.abs(observed - sharp).mean() > 1.0
        assert np.abs(np.diff(observed, axis=1)).mean() < np.abs(np.diff(sharp, axis=1)).mean()
    events = seq.events.window(int(seq.t_start_us[0]), int(seq.t_end_us[-1]) + 1)
    assert len(events) > 1000
    assert events.t.min() >= seq.t_start_us[0] and events.t.max() <= seq.t_end_us[-1]
    assert set(np.unique(events.p)) == {-1, 1}


def test_flow_interpolator_end_to_end(
        replica_dir: tuple[Path, dict[str, tuple[list[np.ndarray], list[np.ndarray], np.ndarray]]],
        tmp_path: Path
) -> None:
    root, _ = replica_dir
    out = make_eventreplica(root / "sceneB", tmp_path / "seq_flow", fps=30.0, exposure_ms=20.0,
                            width=112, height=64, resize=(116, 70), interpolator="flow",
                            upsample=4, max_frames=3, progress=False)
    seq = Sequence.open(out)
    assert len(seq) == 2 and seq.meta["eventreplica"]["interpolator"] == "flow"
    assert seq.meta["sampling"]["fixed_step_us"] == 33_333 // 4
    # about 4 latent samples per strided interval (+1 for the exposure boundary inside it)
    samples_per_interval = (seq.meta["sampling"]["num_samples"] - 1) / (len(seq) - 0.4)
    assert 4 <= samples_per_interval <= 6
    assert len(seq.events) > 0


def test_cli_several_scenes(
        replica_dir: tuple[Path, dict[str, tuple[list[np.ndarray], list[np.ndarray], np.ndarray]]],
        tmp_path: Path
) -> None:
    root, _ = replica_dir
    code = main(["make-eventreplica", "--replica-root", str(root), "--scene", "sceneA",
                 "--scene", "sceneB", "--out", str(tmp_path / "out"), "--width", "112",
                 "--height", "64", "--resize", "none", "--max-frames", "3", "--upsample", "2",
                 "--quiet"])
    assert code == 0
    for name in ("sceneA", "sceneB"):
        assert len(Sequence.open(tmp_path / "out" / name)) == 2


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--exposure-ms", "40"], "exceeds the frame period"),
        (["--upsample", "many"], "upsample must be 'auto' or a positive integer"),
        (["--interpolator", "film"], "'film' is not one of 'depth', 'flow'"),
        (["--resize", "12by3"], "--resize must look like"),
        (["--width", "200"], "larger than"),
    ],
)
def test_cli_bad_options(
        replica_dir: tuple[Path, dict[str, tuple[list[np.ndarray], list[np.ndarray], np.ndarray]]],
        tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[Any], message: str
) -> None:
    root, _ = replica_dir
    code = main(["make-eventreplica", "--input", str(root / "sceneA"), "--out",
                 str(tmp_path / "bad"), "--resize", "none", "--width", "112", "--height", "64",
                 "--quiet", *args])
    assert_cli_error(code, capsys.readouterr().err, 2, message)
    assert not (tmp_path / "bad").exists()


def test_cli_bad_input_names_the_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["make-eventreplica", "--input", str(tmp_path / "missing"), "--out",
                 str(tmp_path / "o")])
    # a data error (exit 2 is for usage errors)
    assert_cli_error(code, capsys.readouterr().err, 3,
                     f"{tmp_path / 'missing'}: scene folder does not exist")
