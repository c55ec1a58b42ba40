"""``egs-bench export``: each layout is read back with the consuming tool's own parsing logic,
reproduced here from its source (MonoGS ``utils/dataset.py`` TUMParser / ReplicaParser at
muskie82/MonoGS@6c9254c, ORB-SLAM2 ``Examples/RGB-D/rgbd_tum.cc`` LoadImages at
raulmur/ORB_SLAM2@f2e6f51, ORB-SLAM3 ``Settings.cc`` type rules as in HuajianUP/Photo-SLAM@f8bfb2f,
RampVO ``evaluate.py`` / ``data/events.py`` / ``utils/eval_utils.py`` at uzh-rpg/rampvo@9353aaa),
and every frame must come back with its own image, depth and pose."""

from __future__ import annotations

import glob
import json
import os
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from PIL import Image

from egs_bench.datasets.sequence import Sequence
from egs_bench.errors import InputError, OutputError
from egs_bench.interop.export import export_sequence, read_export_index
from tests.helpers.cli import assert_cli_error
from tests.helpers.interop_consumers import (
    monogs_replica_parser,
    monogs_tum_parser,
    orbslam3_read,
    orbslam_load_images,
    quat_wxyz_to_matrix,
    retimed_copy,
)

# np.loadtxt warns about the '#' comment lines MonoGS' parser skips
pytestmark = pytest.mark.filterwarnings("ignore:Input line .* contained no data:UserWarning")


# ---------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def seq(tiny_sequence: Path) -> Sequence:
    return Sequence.open(tiny_sequence)


@pytest.fixture(scope="module")
def tum_export(seq: Sequence, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return export_sequence(seq, tmp_path_factory.mktemp("exp") / "tum", fmt="tum-rgbd").path


# ---------------------------------------------------------------- tum-rgbd
def test_monogs_tum_parser_pairs_every_frame(seq: Sequence, tum_export: Path) -> None:
    cfg = yaml.full_load((tum_export / "monogs_rgbd.yaml").read_text())
    cal = cfg["Dataset"]["Calibration"]
    assert cfg["inherit_from"] == "configs/rgbd/tum/base_config.yaml"
    assert cfg["Dataset"]["type"] == "tum" and cfg["Dataset"]["single_thread"] is True
    # relative to the MonoGS checkout, where the export is linked: no path of this machine
    assert cfg["Dataset"]["dataset_path"] == f"datasets/egs_bench/{tum_export.name}/"
    assert str(tum_export.parent) not in (tum_export / "monogs_rgbd.yaml").read_text()
    assert (cal["cx"], cal["cy"]) == (seq.intrinsics.cx - 0.5, seq.intrinsics.cy - 0.5)
    assert (cal["width"], cal["height"], cal["distorted"]) == (seq.width, seq.height, False)
    colors, depths, poses = monogs_tum_parser(f"{tum_export}/")
    assert len(colors) == len(seq)
    for i in range(len(seq)):
        image = np.array(Image.open(colors[i]))
        assert image.shape == (seq.height, seq.width, 3)
        np.testing.assert_array_equal(image, seq.rgb(i))
        depth = np.array(Image.open(depths[i])) / cal["depth_scale"]
        np.testing.assert_allclose(depth, seq.depth(i), atol=0.5 / cal["depth_scale"])
        np.testing.assert_allclose(np.linalg.inv(poses[i]), seq.poses[i], atol=2e-8)


def test_monogs_would_lose_the_first_pose_without_the_header(tum_export: Path) -> None:
    """The pitfall the header line avoids: skiprows=1 drops a leading pose."""
    first = (tum_export / "groundtruth.txt").read_text().splitlines()[0]
    assert first.startswith("#")


def test_frames_closer_than_1_32_s_are_retimed(tiny_sequence: Path, tmp_path: Path) -> None:
    """At 50 fps MonoGS keeps only every other frame of the plain stamps; the default export
    rewrites them to 1/30 s steps and keeps all, and the index maps back to the sequence."""
    fast = Sequence.open(retimed_copy(tiny_sequence, tmp_path / "fast", 20_000))
    plain = export_sequence(fast, tmp_path / "plain", fmt="tum-rgbd", retime="never").path
    assert len(monogs_tum_parser(str(plain))[0]) == 2  # the pitfall is real
    res = export_sequence(fast, tmp_path / "auto", fmt="tum-rgbd")
    assert res.retimed
    colors, _, poses = monogs_tum_parser(str(res.path))
    assert len(colors) == len(fast)
    index = read_export_index(res.path)
    np.testing.assert_allclose(index.t_sequence_s, fast.timestamps_s, atol=1e-6)
    np.testing.assert_allclose(np.diff(index.t_export_s), 1 / 30, atol=1e-6)
    np.testing.assert_allclose(np.linalg.inv(poses[3]), fast.poses[3], atol=2e-8)


def test_orbslam2_reads_associations_and_settings(seq: Sequence, tum_export: Path) -> None:
    rgb, depth, stamps = orbslam_load_images(str(tum_export / "associations.txt"))
    assert len(rgb) == len(seq)
    np.testing.assert_allclose(stamps, seq.timestamps_s, atol=1e-6)
    fs = cv2.FileStorage(str(tum_export / "orbslam2_rgbd.yaml"), cv2.FILE_STORAGE_READ)
    assert fs.isOpened()
    assert fs.getNode("Camera.fx").real() == pytest.approx(seq.intrinsics.fx)
    assert fs.getNode("Camera.cx").real() == pytest.approx(seq.intrinsics.cx - 0.5)
    assert fs.getNode("Camera.cy").real() == pytest.approx(seq.intrinsics.cy - 0.5)
    assert int(fs.getNode("Camera.RGB").real()) == 0  # cv::imread gives BGR
    factor = fs.getNode("DepthMapFactor").real()
    for i in range(len(seq)):
        im = cv2.imread(str(tum_export / rgb[i]), cv2.IMREAD_UNCHANGED)
        assert im is not None
        np.testing.assert_array_equal(im[:, :, ::-1], seq.rgb(i))
        d = cv2.imread(str(tum_export / depth[i]), cv2.IMREAD_UNCHANGED)
        assert d is not None
        assert d.dtype == np.uint16
        np.testing.assert_allclose(d / factor, seq.depth(i), atol=0.5 / factor)


def test_photoslam_settings_pass_orbslam3_type_checks(seq: Sequence, tum_export: Path) -> None:
    fs = cv2.FileStorage(str(tum_export / "photoslam_rgbd.yaml"), cv2.FILE_STORAGE_READ)
    assert fs.getNode("File.version").string() == "1.0"
    assert orbslam3_read(fs, "Camera.type", "string") == "PinHole"
    for key, want in (("Camera1.fx", seq.intrinsics.fx), ("Camera1.fy", seq.intrinsics.fy),
                      ("Camera1.cx", seq.intrinsics.cx - 0.5),
                      ("Camera1.cy", seq.intrinsics.cy - 0.5),
                      ("RGBD.DepthMapFactor", 5000.0)):
        assert orbslam3_read(fs, key, "float") == pytest.approx(want)
    assert fs.getNode("Camera1.k1").empty()  # no distortion: ORB-SLAM3 does not undistort
    assert orbslam3_read(fs, "Camera.width", "int") == seq.width
    assert orbslam3_read(fs, "Camera.height", "int") == seq.height
    assert orbslam3_read(fs, "Camera.fps", "int") == 30
    assert orbslam3_read(fs, "Camera.RGB", "int") == 1  # Photo-SLAM converts BGR to RGB
    for key in ("Stereo.ThDepth", "Stereo.b", "ORBextractor.scaleFactor", "Viewer.KeyFrameSize",
                "Viewer.KeyFrameLineWidth", "Viewer.GraphLineWidth", "Viewer.PointSize",
                "Viewer.CameraSize", "Viewer.CameraLineWidth", "Viewer.ViewpointX",
                "Viewer.ViewpointY", "Viewer.ViewpointZ", "Viewer.ViewpointF"):
        orbslam3_read(fs, key, "float")
    for key in ("ORBextractor.nFeatures", "ORBextractor.nLevels", "ORBextractor.iniThFAST",
                "ORBextractor.minThFAST"):
        orbslam3_read(fs, key, "int")


# ---------------------------------------------------------------- replica
def test_replica_layout_read_by_monogs_and_egs_bench(seq: Sequence, tmp_path: Path) -> None:
    from egs_bench.datasets.replica import read_replica
    from egs_bench.eval.image_metrics import psnr

    out = export_sequence(seq, tmp_path / "replica", fmt="replica").path
    colors, depths, poses = monogs_replica_parser(str(out))
    assert len(colors) == len(depths) == len(seq)
    cfg = yaml.full_load((out / "monogs_replica.yaml").read_text())
    cal = cfg["Dataset"]["Calibration"]
    assert cfg["Dataset"]["type"] == "replica" and cal["cx"] == seq.intrinsics.cx - 0.5
    for i in range(len(seq)):
        image = np.array(Image.open(colors[i]))
        assert psnr(image, seq.rgb(i)) > 35.0  # JPEG 95, 4:4:4 (measured 37.1 dB; 4:2:0 28.7)
        depth = np.array(Image.open(depths[i])) / cal["depth_scale"]
        np.testing.assert_allclose(depth, seq.depth(i), atol=0.5 / cal["depth_scale"])
        np.testing.assert_allclose(np.linalg.inv(poses[i]), seq.poses[i], atol=1e-12)
    cam = json.loads((out / "cam_params.json").read_text())["camera"]
    assert (cam["cx"], cam["cy"]) == (seq.intrinsics.cx - 0.5, seq.intrinsics.cy - 0.5)
    assert read_replica(out).intrinsics == seq.intrinsics  # egs-bench's own reader agrees
    nice = yaml.safe_load((out / "nice_slam.yaml").read_text())
    assert nice["cam"]["W"] == seq.width and nice["cam"]["cx"] == seq.intrinsics.cx - 0.5
    assert nice["data"]["input_folder"] == f"datasets/egs_bench/{out.name}"
    for config in ("nice_slam.yaml", "monogs_replica.yaml"):
        assert str(out.parent) not in (out / config).read_text(), config
    centres = seq.poses[:, :3, 3]
    for axis, (lo, hi) in enumerate(nice["mapping"]["bound"]):
        assert lo < centres[:, axis].min() and hi > centres[:, axis].max()


# ---------------------------------------------------------------- eds (RampVO)
def test_eds_layout_passes_rampvo_loaders(seq: Sequence, tmp_path: Path) -> None:
    import h5py

    out = export_sequence(seq, tmp_path / "eds", fmt="eds").path
    images = sorted(glob.glob(os.path.join(out, "image_left", "*.png")))
    stamps = np.loadtxt(os.path.join(out, "timestamps.txt")) / 1e6  # EDS: microseconds
    assert len(images) == len(stamps) == len(seq)
    np.testing.assert_allclose(stamps, seq.timestamps_s, atol=1e-9)
    for i, f in enumerate(images):
        np.testing.assert_array_equal(np.array(Image.open(f)), seq.rgb(i))
    mat = np.loadtxt(os.path.join(out, "pose_left.txt")).astype(float)  # read_eds_format_poses
    np.testing.assert_allclose(mat[:, 0], seq.timestamps_s, atol=1e-6)
    for i in range(len(seq)):
        T = quat_wxyz_to_matrix(np.roll(mat[i, 4:], 1))
        T[:3, 3] = mat[i, 1:4]
        np.testing.assert_allclose(T, seq.poses[i], atol=2e-8)
    k = yaml.safe_load((out / "K.yaml").read_text())["cam0"]
    assert k["intrinsics"] == [seq.intrinsics.fx, seq.intrinsics.fy, seq.intrinsics.cx - 0.5,
                               seq.intrinsics.cy - 0.5]
    assert k["resolution"] == [seq.width, seq.height]
    with h5py.File(out / "events.h5") as handle:  # H5EventHandle + Events asserts
        ev = handle["events"]
        assert {"x", "y", "t", "p", "height", "width"} <= set(ev.keys())
        height, width = ev["height"][()], ev["width"][()]
        x, y, t, p = (ev[k][:] for k in "xytp")
    assert (height, width) == (seq.height, seq.width)
    assert t.dtype == np.int64 and p.dtype == np.int8
    assert p.max() <= 1 and x.max() <= width - 1 and y.max() <= height - 1
    assert seq.events.t_first is not None
    want = seq.events.window(seq.events.t_first, int(seq.t_end_us[-1]) + 1)
    np.testing.assert_array_equal(t, want.t)  # absolute microseconds, like timestamps.txt
    np.testing.assert_array_equal(np.where(p == 0, -1, p), want.p)
    np.testing.assert_array_equal(x, want.x)


# ---------------------------------------------------------------- safety and CLI
def test_output_safety(seq: Sequence, tmp_path: Path) -> None:
    user = tmp_path / "mine"
    user.mkdir()
    (user / "notes.txt").write_text("keep me")
    for overwrite in (False, True):
        with pytest.raises(OutputError, match="mine"):
            export_sequence(seq, user, fmt="tum-rgbd", overwrite=overwrite)
    assert (user / "notes.txt").read_text() == "keep me"
    out = export_sequence(seq, tmp_path / "exp", fmt="tum-rgbd").path
    with pytest.raises(OutputError, match="--overwrite"):  # exit code 2, like every output
        export_sequence(seq, out, fmt="tum-rgbd")
    (out / "stale.txt").write_text("x")
    export_sequence(seq, out, fmt="eds", overwrite=True)
    assert not (out / "stale.txt").exists() and (out / "events.h5").is_file()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temp leftovers


def test_cli_export_and_errors(tiny_sequence: Path, tmp_path: Path,
                               capsys: pytest.CaptureFixture[str]) -> None:
    from egs_bench.cli import main

    assert main(["export", str(tiny_sequence), "-o", str(tmp_path / "o"), "--format", "tum-rgbd",
                 "--quiet"]) == 0
    assert (tmp_path / "o" / "monogs_rgbd.yaml").is_file()
    code = main(["export", str(tiny_sequence), "-o", str(tmp_path / "o2"), "--format", "kitti"])
    assert_cli_error(code, capsys.readouterr().err, 2, "--format", "kitti")
    assert not (tmp_path / "o2").exists()


def _damaged_copy(src: Path, dst: Path, column: str, how: str) -> Path:
    """A copy of ``src`` whose frame 2 ``column`` image is truncated or of another size."""
    shutil.copytree(src, dst)
    image = dst / column / "000002.png"
    if how == "truncated":
        data = image.read_bytes()
        image.write_bytes(data[: len(data) // 2])
    else:  # a valid PNG of the wrong size, same mode as the original
        raw = cv2.imread(str(image), cv2.IMREAD_UNCHANGED)
        assert raw is not None
        cv2.imwrite(str(image), np.ascontiguousarray(raw[:-2]))
    return dst


@pytest.mark.parametrize("fmt", ["tum-rgbd", "replica", "eds"])
@pytest.mark.parametrize("column,how", [("rgb", "truncated"), ("depth", "truncated"),
                                        ("rgb", "resized")])
def test_export_refuses_a_bad_image(tiny_sequence: Path, tmp_path: Path, fmt: str,
                                    column: str, how: str) -> None:
    if fmt == "eds" and column == "depth":
        pytest.skip("the eds layout holds no depth")
    src = _damaged_copy(tiny_sequence, tmp_path / "seq", column, how)
    seq = Sequence.open(src, check_images=False)  # a header-only check would miss truncation
    bad = src / column / "000002.png"
    for overwrite in (False, True):
        out = tmp_path / "out"
        with pytest.raises(InputError) as err:
            export_sequence(seq, out, fmt=fmt, overwrite=overwrite)
        assert str(bad) in str(err.value)
        if not overwrite:
            assert not out.exists()
            good = export_sequence(tiny_sequence, out, fmt=fmt).path
            before = sorted(p.relative_to(good) for p in good.rglob("*"))
        else:  # the earlier export is left as it was
            assert sorted(p.relative_to(out) for p in out.rglob("*")) == before
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_cli_export_of_a_truncated_frame(tiny_sequence: Path, tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    from egs_bench.cli import main

    src = _damaged_copy(tiny_sequence, tmp_path / "seq", "rgb", "truncated")
    code = main(["export", str(src), "-o", str(tmp_path / "o"), "--format", "tum-rgbd", "--quiet"])
    assert_cli_error(code, capsys.readouterr().err, 3, src / "rgb" / "000002.png")
    assert not (tmp_path / "o").exists()
