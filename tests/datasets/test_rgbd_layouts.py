"""``make-eventreplica --layout tum-rgbd`` / ``--layout generic``: TUM association on the real
benchmark trajectories, the camera rules, a round trip through ``egs-bench export --format
tum-rgbd`` and a short run on the result, and one clear line for every bad input."""

from __future__ import annotations

import os
import shutil
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
import yaml

from egs_bench.cli import main
from egs_bench.datasets.eventreplica import ResizeCrop
from egs_bench.datasets.rgbd_layouts import (
    TUM_CAMERAS,
    RGBDInput,
    associate,
    read_generic_rgbd,
    read_tum_rgbd,
)
from egs_bench.datasets.sequence import Sequence
from egs_bench.errors import ConfigError, InputError
from egs_bench.geometry import Intrinsics, read_tum, write_tum
from egs_bench.images import write_depth_png, write_ldr_image
from tests.helpers.cli import assert_cli_error


def tum_associate_oracle(first: np.ndarray, second: np.ndarray, max_difference: float
                         ) -> list[tuple[float, float]]:
    """The TUM benchmark's associate.py rule, stated directly: every pair within the window,
    sorted by (difference, first stamp, second stamp), accepted while both stamps are unused."""
    diff = np.abs(first[:, None] - second[None, :])
    ia, ib = np.nonzero(diff < max_difference)
    candidates = sorted((float(diff[i, j]), float(first[i]), float(second[j]))
                        for i, j in zip(ia, ib, strict=True))
    free_a, free_b = set(first.tolist()), set(second.tolist())
    matches = []
    for _, a, b in candidates:
        if a in free_a and b in free_b:
            free_a.remove(a)
            free_b.remove(b)
            matches.append((a, b))
    return sorted(matches)


@pytest.mark.parametrize(("estimate", "truth", "limit"), [
    ("freiburg1_xyz-rgbdslam.txt", "freiburg1_xyz-groundtruth.txt", None),
    ("fr2_desk_ORB.txt", "fr2_desk_groundtruth.txt", 500),
])
@pytest.mark.parametrize("max_dt", [0.02, 0.005])
def test_association_follows_tum_rule_on_real_trajectories(shared_data: Path, estimate: str,
                                                           truth: str, limit: int | None,
                                                           max_dt: float) -> None:
    folder = shared_data / "trajectories"
    est = read_tum(folder / estimate).timestamps[:limit]
    gt = np.unique(read_tum(folder / truth).timestamps)
    if limit is not None:  # keep the oracle's all-pairs table small
        gt = gt[(gt > est[0] - 1) & (gt < est[-1] + 1)]
    i, j = associate(est, gt, max_dt)
    expected = tum_associate_oracle(est, gt, max_dt)
    assert list(zip(est[i].tolist(), gt[j].tolist(), strict=True)) == expected
    assert len(set(i.tolist())) == len(i) and len(set(j.tolist())) == len(j)
    assert np.all(np.abs(est[i] - gt[j]) < max_dt)
    assert len(i) > 0.75 * len(est)  # most frames fall inside the motion capture's span


def test_association_is_one_to_one_where_nearest_would_match_twice() -> None:
    # both colour stamps are nearest to depth 1.00; the second takes its other neighbour
    i, j = associate(np.array([1.0, 1.004]), np.array([0.99, 1.0, 1.012]), 0.02)
    assert i.tolist() == [0, 1] and j.tolist() == [1, 2]
    i, j = associate(np.array([1.0, 1.004]), np.array([1.0]), 0.02)
    assert i.tolist() == [0] and j.tolist() == [0]
    i, j = associate(np.array([1.0]), np.array([1.02]), 0.02)  # the window is open
    assert len(i) == 0 and len(j) == 0


def _tum_folder(root: Path, rgb_t: np.ndarray, depth_t: np.ndarray,
                size: tuple[int, int] = (640, 480)) -> Path:
    """A TUM-layout folder with flat images named by stamp (no groundtruth.txt)."""
    (root / "rgb").mkdir(parents=True)
    (root / "depth").mkdir()
    rgb_lines, depth_lines = ["# color images", "# timestamp filename"], ["# depth maps"]
    for k, t in enumerate(rgb_t):
        write_ldr_image(root / "rgb" / f"{t:.6f}.png",
                        np.full((size[1], size[0], 3), 10 + k, dtype=np.uint8))
        rgb_lines.append(f"{t:.6f} rgb/{t:.6f}.png")
    for k, t in enumerate(depth_t):
        write_depth_png(root / "depth" / f"{t:.6f}.png",
                        np.full((size[1], size[0]), 5000 + k, dtype=np.uint16))
        depth_lines.append(f"{t:.6f}\tdepth/{t:.6f}.png")
    (root / "rgb.txt").write_text("\n".join(rgb_lines) + "\n")
    (root / "depth.txt").write_text("\n".join(depth_lines) + "\n")
    return root


@pytest.mark.parametrize(("estimate", "truth", "camera"), [
    ("freiburg1_xyz-rgbdslam.txt", "freiburg1_xyz-groundtruth.txt", "fr1"),
    ("fr2_desk_ORB.txt", "fr2_desk_groundtruth.txt", "fr2"),
])
def test_tum_folder_with_real_groundtruth(shared_data: Path, tmp_path: Path, estimate: str,
                                          truth: str, camera: str) -> None:
    """Colour stamps of a real run, depth stamps a few ms off (one missing), the real
    100 Hz ground truth (fr2/desk's holds one repeated stamp): frames, poses and camera."""
    trajectories = shared_data / "trajectories"
    rgb_t = read_tum(trajectories / estimate).timestamps[20:32]
    depth_t = np.delete(rgb_t + np.tile([0.004, -0.011], 6), 5)
    root = _tum_folder(tmp_path / f"rgbd_dataset_freiburg{camera[-1]}_test", rgb_t, depth_t)
    shutil.copyfile(trajectories / truth, root / "groundtruth.txt")

    scene = read_tum_rgbd(root)
    kept = np.delete(rgb_t, 5)
    np.testing.assert_array_equal(scene.timestamps_s, kept)
    assert [p.name for p in scene.depth_paths] == [f"{t:.6f}.png" for t in depth_t]
    gt = read_tum(root / "groundtruth.txt")
    for k, t in enumerate(kept):  # the nearest pose (each is used once: 100 Hz vs 30 Hz)
        nearest = int(np.argmin(np.abs(gt.timestamps - t)))
        np.testing.assert_allclose(scene.poses[k], gt.poses[nearest], atol=1e-12)
    rec = scene.record["association"]
    assert (rec["colour_listed"], rec["depth_listed"], rec["frames"]) == (12, 11, 11)
    assert rec["colour_dropped"] == 1 and rec["max_depth_dt_s"] == pytest.approx(0.011, abs=1e-6)
    assert rec["repeated_stamps_dropped"]["groundtruth"] == (1 if camera == "fr2" else 0)
    # camera from the folder name: the benchmark's calibration, in egs-bench's convention
    cam = TUM_CAMERAS[camera]
    assert scene.intrinsics == Intrinsics(cam.fx, cam.fy, cam.cx + 0.5, cam.cy + 0.5, 640, 480)
    assert scene.distortion == cam.distortion and scene.depth_scale == 5000.0
    assert scene.record["camera_source"] == f"TUM {camera} calibration"
    # depth at 5000 per metre, undistorted with nearest neighbour (flat map stays flat inside)
    depth = scene.depth(0)
    assert depth[240, 320] == pytest.approx(5000 / 5000.0)
    # the aspect rule: 640x480 is scaled by one factor before the 448x256 crop
    geo = ResizeCrop()
    assert geo.resized_size(scene.intrinsics) == (448, 336)
    out = geo.intrinsics(scene.intrinsics)
    assert out.fx / out.fy == pytest.approx(cam.fx / cam.fy, rel=1e-12)

    # a tighter window drops the depth maps 11 ms away
    assert len(read_tum_rgbd(root, max_dt_s=0.01)) == 6


def test_undistortion_moves_points_to_their_pinhole_projection(tmp_path: Path) -> None:
    """A dot drawn where OpenCV's distortion model (cv2.projectPoints) puts a 3-D point lands,
    after reading, where the pinhole intrinsics put it."""
    cam = TUM_CAMERAS["fr1"]
    k_cv = np.array([[cam.fx, 0, cam.cx], [0, cam.fy, cam.cy], [0, 0, 1.0]])
    point = np.array([[-0.55, 0.35, 1.0]])  # near the corner, where the distortion is large
    distorted = cv2.projectPoints(point, np.zeros(3), np.zeros(3), k_cv,
                                  np.array(cam.distortion))[0].reshape(2)
    pinhole = k_cv[:2, :2] @ point[0, :2] + k_cv[:2, 2]
    assert np.linalg.norm(distorted - pinhole) > 5  # so a missing undistortion fails
    img = np.zeros((480, 640, 3), dtype=np.uint8)
    cv2.circle(img, tuple(int(round(v)) for v in distorted), 3, (255, 255, 255), -1)
    root = _tum_folder(tmp_path / "tum", np.array([1.0, 1.1]), np.array([1.0, 1.1]))
    write_ldr_image(root / "rgb" / "1.000000.png", img)
    write_tum(root / "groundtruth.txt", np.array([1.0, 1.1]), np.stack([np.eye(4)] * 2))
    scene = read_tum_rgbd(root, tum_camera="fr1")
    out = scene.rgb(0)[..., 0].astype(float)
    ys, xs = np.nonzero(out > 128)
    centre = np.array([xs.mean(), ys.mean()])  # OpenCV convention: pixel centres at integers
    assert np.linalg.norm(centre - pinhole) < 1.0


def _export_tum(tiny_sequence: Path, out: Path) -> Path:
    assert main(["export", str(tiny_sequence), "-o", str(out), "--format", "tum-rgbd"]) == 0
    return out


@pytest.mark.slow
def test_round_trip_export_make_eventreplica_run(tiny_sequence: Path, tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    """sequence -> export --format tum-rgbd -> make-eventreplica --layout tum-rgbd -> run."""
    src = Sequence.open(tiny_sequence)
    export = _export_tum(tiny_sequence, tmp_path / "export")
    out = tmp_path / "seq"
    code = main(["make-eventreplica", "--layout", "tum-rgbd", "--input", str(export),
                 "--out", str(out), "--width", str(src.width), "--height", str(src.height),
                 "--upsample", "4", "--quiet"])
    assert code == 0, capsys.readouterr().err
    seq = Sequence.open(out)
    assert len(seq) == len(src) - 1  # frame 0 only starts the interpolation
    assert seq.has_events and len(seq.events) > 0
    # the camera comes back from the export's manifest exactly; poses to the file's 9 digits
    assert seq.intrinsics == src.intrinsics
    np.testing.assert_allclose(seq.poses, src.poses[1:], atol=2e-6)
    for i in range(len(seq)):
        np.testing.assert_allclose(seq.depth(i), src.depth(i + 1), atol=1.5 / 5000)
        sharp = seq.sharp(i)
        assert sharp is not None
        assert np.abs(sharp.astype(int) - src.rgb(i + 1).astype(int)).max() <= 1
    er = seq.meta["eventreplica"]
    assert er["layout"] == "tum-rgbd" and er["cam_params"] == "../export/egs_export.yaml"
    assert er["original_timestamps_s"] == pytest.approx(
        [float(t) for t in np.loadtxt(export / "rgb.txt", usecols=0)[1:]])

    run = tmp_path / "run"
    code = main(["run", "--method", "egs", "--seq", str(out), "--preset", "cpu", "--device",
                 "cpu", "--max-frames", "2", "--out", str(run), "--quiet",
                 "--set", "init_iters=5", "--set", "tracking_iters=5",
                 "--set", "mapping_iters=2"])
    assert code == 0, capsys.readouterr().err
    traj = read_tum(run / "trajectory.txt")
    assert len(traj) == 2
    np.testing.assert_allclose(traj.timestamps, seq.timestamps_s[:2], atol=1e-6)


def _generic(tiny_sequence: Path, root: Path, depth_scale: float | None) -> dict[str, Path]:
    """The tiny sequence as the generic layout, with names whose text order is wrong."""
    src = Sequence.open(tiny_sequence)
    (root / "images").mkdir(parents=True)
    (root / "depths").mkdir()
    for i in range(len(src)):
        shutil.copyfile(src.frame_path(i, "rgb"), root / "images" / f"img_{i + 8}.png")
        shutil.copyfile(src.frame_path(i, "depth"), root / "depths" / f"d{i + 8}.png")
    shutil.copyfile(src.path / "groundtruth.txt", root / "traj.txt")
    cam = {"fx": src.intrinsics.fx, "fy": src.intrinsics.fy, "cx": src.intrinsics.cx - 0.5,
           "cy": src.intrinsics.cy - 0.5}
    if depth_scale is not None:
        cam["depth_scale"] = depth_scale
    (root / "camera.yaml").write_text(yaml.safe_dump(cam))
    return {"--rgb-dir": root / "images", "--depth-dir": root / "depths",
            "--trajectory": root / "traj.txt", "--intrinsics": root / "camera.yaml"}


def test_generic_layout_reads_natural_order_and_the_yaml(tiny_sequence: Path, tmp_path: Path
                                                         ) -> None:
    src = Sequence.open(tiny_sequence)
    paths = _generic(tiny_sequence, tmp_path, src.depth_scale)
    scene = read_generic_rgbd(*paths.values())
    assert [p.name for p in scene.rgb_paths] == ["img_8.png", "img_9.png", "img_10.png",
                                                 "img_11.png"]
    assert scene.intrinsics == src.intrinsics and scene.layout == "generic"
    np.testing.assert_allclose(scene.poses, src.poses, atol=2e-6)
    for i in range(len(src)):
        np.testing.assert_array_equal(scene.rgb(i), src.rgb(i))
        np.testing.assert_array_equal(scene.depth(i), src.depth(i))


def test_generic_layout_cli(tiny_sequence: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
                            ) -> None:
    src = Sequence.open(tiny_sequence)
    paths = _generic(tiny_sequence, tmp_path / "in", src.depth_scale)
    args = [a for k, v in paths.items() for a in (k, str(v))]
    code = main(["make-eventreplica", "--layout", "generic", *args, "--out",
                 str(tmp_path / "seq"), "--width", "48", "--height", "32", "--upsample", "2",
                 "--quiet"])
    assert code == 0, capsys.readouterr().err
    seq = Sequence.open(tmp_path / "seq")
    assert len(seq) == len(src) - 1 and (seq.width, seq.height) == (48, 32)
    # 'auto' keeps the aspect ratio: one factor for both axes, the smallest that covers the
    # 48x32 crop (max(48 / 64, 32 / 48) = 0.75), so 64x48 becomes 48x36
    assert seq.meta["eventreplica"]["resize"] == [48, 36]
    # meta.yaml travels with the sequence: its inputs relative to it, no path of this machine
    assert str(tmp_path) not in (tmp_path / "seq" / "meta.yaml").read_text()
    record = seq.meta["eventreplica"]["layout_record"]
    assert record["trajectory"] == os.path.relpath(paths["--trajectory"], tmp_path / "seq")
    assert seq.meta["eventreplica"]["input"].startswith("../in")
    assert seq.intrinsics.fx / seq.intrinsics.fy == pytest.approx(
        src.intrinsics.fx / src.intrinsics.fy)
    np.testing.assert_allclose(seq.poses, src.poses[1:], atol=2e-6)


def _write(path: Path, text: str | bytes) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text)
    return path


@pytest.fixture()
def tum_export(tiny_sequence: Path, tmp_path: Path) -> Path:
    return _export_tum(tiny_sequence, tmp_path / "export")


def _break(root: Path, case: str) -> tuple[list[str], Path, str]:
    """Damage a TUM export; returns extra CLI arguments, the file the message must name and a
    piece of the message."""
    if case == "no-rgb-list":
        (root / "rgb.txt").unlink()
        return [], root / "rgb.txt", "missing"
    if case == "bad-line":
        _write(root / "depth.txt", "# x\n0.1\n")
        return [], root / "depth.txt", "line 2: expected 'timestamp path'"
    if case == "bad-stamp":
        _write(root / "rgb.txt", "abc rgb/000000.png\n")
        return [], root / "rgb.txt", "line 1: time stamp 'abc' is not a number"
    if case == "missing-image":
        (root / "rgb" / "000002.png").unlink()
        return [], root / "rgb" / "000002.png", "listed in rgb.txt but not found"
    if case == "binary-list":
        _write(root / "depth.txt", bytes(range(256)))
        return [], root / "depth.txt", "not a UTF-8 text file"
    if case == "bad-groundtruth":
        _write(root / "groundtruth.txt", "0.1 1 2 3\n")
        return [], root / "groundtruth.txt", "expected 8 numbers"
    if case == "no-overlap":
        gt = read_tum(root / "groundtruth.txt")
        write_tum(root / "groundtruth.txt", gt.timestamps + 100.0, gt.poses)
        return [], root / "groundtruth.txt", "have a pose within 0.02 s"
    if case == "no-camera":
        (root / "egs_export.yaml").unlink()
        return [], root, "no camera intrinsics"
    if case == "yaml-missing-fx":
        cam = _write(root.parent / "cam.yaml", "fy: 1\ncx: 1\ncy: 1\n")
        return ["--intrinsics", str(cam)], cam, "missing 'fx'"
    if case == "yaml-binary":
        cam = _write(root.parent / "cam.yaml", b"\xff\xfe\x00fx")
        return ["--intrinsics", str(cam)], cam, "not a UTF-8 text file"
    if case == "yaml-not-yaml":
        cam = _write(root.parent / "cam.yaml", "fx: [1\n")
        return ["--intrinsics", str(cam)], cam, "not valid YAML"
    if case == "yaml-distortion":
        cam = _write(root.parent / "cam.yaml", "fx: 50\nfy: 50\ncx: 30\ncy: 20\n"
                                               "distortion: [0.1, 0.2]\n")
        return ["--intrinsics", str(cam)], cam, "'distortion' must be a list of 4, 5 or 8"
    if case == "yaml-size":
        cam = _write(root.parent / "cam.yaml", "fx: 50\nfy: 50\ncx: 30\ncy: 20\n"
                                               "width: 640\nheight: 480\n")
        return ["--intrinsics", str(cam)], root / "rgb" / "000000.png", "expected 640x480"
    if case == "yaml-centre":
        cam = _write(root.parent / "cam.yaml", "fx: 50\nfy: 50\ncx: 300\ncy: 20\n")
        return ["--intrinsics", str(cam)], cam, "principal point"
    if case == "yaml-missing-file":
        return ["--intrinsics", str(root / "nope.yaml")], root / "nope.yaml", "not found"
    raise AssertionError(case)


@pytest.mark.parametrize("case", [
    "no-rgb-list", "bad-line", "bad-stamp", "missing-image", "binary-list", "bad-groundtruth",
    "no-overlap", "no-camera", "yaml-missing-fx", "yaml-binary", "yaml-not-yaml",
    "yaml-distortion", "yaml-size", "yaml-centre", "yaml-missing-file",
])
def test_bad_tum_input_is_one_line_naming_the_file(tum_export: Path, tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str], case: str
                                                   ) -> None:
    extra, named, message = _break(tum_export, case)
    code = main(["make-eventreplica", "--layout", "tum-rgbd", "--input", str(tum_export),
                 "--out", str(tmp_path / "out"), "--width", "48", "--height", "32",
                 "--quiet", *extra])
    assert_cli_error(code, capsys.readouterr().err, 3, f"{named}: ", message)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(("case", "message"), [
    ("count", "3 depth maps for 4 colour images"),
    ("poses", "3 poses for 4 images"),
    ("scale", "missing 'depth_scale'"),
    ("empty", "holds no colour image"),
])
def test_bad_generic_input_is_one_line_naming_the_file(tiny_sequence: Path, tmp_path: Path,
                                                       capsys: pytest.CaptureFixture[str],
                                                       case: str, message: str) -> None:
    paths = _generic(tiny_sequence, tmp_path / "in", None if case == "scale" else 5000.0)
    named = {"count": "--depth-dir", "poses": "--trajectory", "scale": "--intrinsics",
             "empty": "--rgb-dir"}[case]
    if case == "count":
        (paths["--depth-dir"] / "d11.png").unlink()
    elif case == "poses":
        lines = paths["--trajectory"].read_text().splitlines()
        paths["--trajectory"].write_text("\n".join(lines[:-1]) + "\n")
    elif case == "empty":
        for f in paths["--rgb-dir"].iterdir():
            f.unlink()
    args = [a for k, v in paths.items() for a in (k, str(v))]
    code = main(["make-eventreplica", "--layout", "generic", *args, "--out",
                 str(tmp_path / "out"), "--width", "48", "--height", "32", "--quiet"])
    assert_cli_error(code, capsys.readouterr().err, 3, f"{paths[named]}: ", message)


@pytest.mark.parametrize(("args", "message"), [
    (["--layout", "tum"], "'tum' is not one of 'replica', 'tum-rgbd', 'generic'"),
    (["--layout", "tum-rgbd", "--input", "X", "--tum-camera", "fr4"],
     "--tum-camera must be one of fr1, fr2, fr3"),
    (["--layout", "tum-rgbd", "--input", "X", "--max-dt", "nan"],
     "'--max-dt': nan is not a finite number"),
    (["--layout", "tum-rgbd", "--input", "X", "--max-dt", "-1"], "--max-dt must be a positive"),
    (["--layout", "tum-rgbd", "--input", "X", "--cam-params", "c.json"], "--cam-params is the"),
    (["--layout", "tum-rgbd", "--input", "X", "--tum-camera", "fr1", "--intrinsics", "c.yaml"],
     "not both"),
    (["--layout", "tum-rgbd"], "needs --input FOLDER"),
    (["--layout", "tum-rgbd", "--input", "X", "--rgb-dir", "r"], "only work with --layout"),
    (["--layout", "generic", "--input", "X"], "not --input"),
    (["--layout", "generic", "--rgb-dir", "r"], "--layout generic needs"),
    (["--layout", "tum-rgbd", "--replica-root", "X", "--scene", "a"], "only work with --layout"),
    (["--input", "X", "--intrinsics", "c.yaml"], "need --layout tum-rgbd or generic"),
    (["--input", "X", "--tum-camera", "fr1"], "need --layout tum-rgbd or generic"),
])
def test_bad_layout_options_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                         monkeypatch: pytest.MonkeyPatch, args: list[Any],
                                         message: str) -> None:
    monkeypatch.chdir(tmp_path)
    code = main(["make-eventreplica", "--out", str(tmp_path / "out"), "--quiet", *args])
    assert_cli_error(code, capsys.readouterr().err, 2, message)


def test_rgbd_input_validates_and_lists_its_inputs(tmp_path: Path) -> None:
    spec = RGBDInput(layout="generic", rgb_dir=tmp_path / "r", depth_dir=tmp_path / "d",
                     trajectory=tmp_path / "t.txt", camera=tmp_path / "c.yaml")
    assert spec.inputs() == [tmp_path / "r", tmp_path / "d", tmp_path / "t.txt",
                             tmp_path / "c.yaml"]
    with pytest.raises(ConfigError, match="--max-dt"):
        RGBDInput(layout="tum-rgbd", path=tmp_path, max_dt_s=0.0)
    with pytest.raises(InputError, match="TUM RGB-D folder does not exist"):
        RGBDInput(layout="tum-rgbd", path=tmp_path / "missing").open()


@pytest.mark.parametrize("where", ["input", "inside"])
def test_output_may_not_replace_the_input_layout(tum_export: Path,
                                                 capsys: pytest.CaptureFixture[str], where: str
                                                 ) -> None:
    """Never lose user data: the TUM folder (or a folder around it) is refused as --out, even
    with --overwrite, and nothing in it changes."""
    before = sorted(p.relative_to(tum_export) for p in tum_export.rglob("*"))
    out = tum_export if where == "input" else tum_export / "rgb"
    code = main(["make-eventreplica", "--layout", "tum-rgbd", "--input", str(tum_export),
                 "--out", str(out), "--overwrite", "--width", "48", "--height", "32",
                 "--quiet"])
    assert_cli_error(code, capsys.readouterr().err, 2, out)
    assert sorted(p.relative_to(tum_export) for p in tum_export.rglob("*")) == before


def test_shareable_paths_are_relative_to_the_output_or_only_a_name(tmp_path: Path) -> None:
    from egs_bench.outputs import shareable_path

    out = tmp_path / "data" / "seq"
    assert shareable_path(tmp_path / "data" / "replica" / "room0", out) == "../replica/room0"
    assert shareable_path(out / "x.yaml", out) == "x.yaml"
    assert shareable_path(tmp_path / "elsewhere" / "room0", out) == "room0"  # outside: name
