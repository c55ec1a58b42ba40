"""``egs-bench import-run --from ...``: files shaped exactly as each system writes them
(ORB-SLAM2 ``System::SaveTrajectoryTUM`` / ``SaveKeyFrameTrajectoryTUM``, Photo-SLAM's output
folder, MonoGS ``eval_ate``'s ``trj_final.json``, RampVO ``evaluate.py:save_results``), mapped
back onto the exported sequence, marked when partial, and evaluated honestly."""

from __future__ import annotations

import json
import shutil
from collections.abc import Sequence as Sequence_
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from egs_bench.datasets.sequence import Sequence
from egs_bench.errors import ConfigError, InputError, OutputError, UnwritableOutputError
from egs_bench.eval.evaluate import evaluate_run
from egs_bench.geometry import invert_pose, pose_from_tq, pose_to_tq
from egs_bench.interop.export import export_sequence
from egs_bench.interop.importing import import_external_run
from egs_bench.interop.monogs import monogs_kept_frames
from tests.helpers.cli import assert_cli_error
from tests.helpers.interop_consumers import monogs_tum_parser, retimed_copy

pytestmark = pytest.mark.filterwarnings("ignore:Input line .* contained no data:UserWarning")


@pytest.fixture(scope="module")
def seq_path(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """10 frames, 64x48, of the plane scene (30 fps, 15 ms exposures), with its ground truth
    replaced by a 6-DoF helix: the plane's straight line cannot be aligned (Umeyama needs a
    non-degenerate trajectory) and these tests only need poses, not matching images."""
    from egs_bench.geometry import read_tum, write_tum
    from tests.helpers.plane_scene import make_plane_sequence

    path = make_plane_sequence(tmp_path_factory.mktemp("imp") / "plane", frames=10)
    stamps = read_tum(path / "groundtruth.txt").timestamps
    a = np.linspace(0, 2.0, len(stamps))
    t = np.stack([0.5 * np.cos(a), 0.4 * np.sin(a), 0.3 * a], axis=1)
    half = 0.15 * a
    q = np.stack([np.sin(half) * 0.6, np.sin(half) * 0.8, np.zeros_like(a), np.cos(half)], 1)
    write_tum(path / "groundtruth.txt", stamps, pose_from_tq(t, q))
    return path


@pytest.fixture(scope="module")
def seq(seq_path: Path) -> Sequence:
    return Sequence.open(seq_path)


@pytest.fixture(scope="module")
def export(seq: Sequence, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return export_sequence(seq, tmp_path_factory.mktemp("exp") / "tum", fmt="tum-rgbd").path


def _estimated(seq: Sequence, noise: float = 0.002, seed: int = 0) -> np.ndarray:
    """Ground truth with a few mm of noise, expressed relative to frame 0 (ORB-SLAM's world is
    its first keyframe)."""
    rng = np.random.default_rng(seed)
    poses = seq.poses.copy()
    poses[:, :3, 3] += rng.normal(0, noise, (len(poses), 3))
    return np.einsum("ij,njk->nik", invert_pose(seq.poses[0]), poses)


def _orbslam_lines(stamps: np.ndarray, poses: np.ndarray, value_precision: int) -> str:
    """``f << fixed << setprecision(6) << t << " " << setprecision(p) << tx ... qw``."""
    t, q = pose_to_tq(poses)
    lines = []
    for ts, ti, qi in zip(stamps, t, q, strict=True):
        lines.append(f"{ts:.6f} " + " ".join(f"{v:.{value_precision}f}" for v in (*ti, *qi)))
    return "\n".join(lines) + "\n"


def _orbslam_folder(folder: Path, seq: Sequence, lost: tuple[int, ...] = (3,),
                    keyframes: tuple[int, ...] = (0, 4, 8), stamps: np.ndarray | None = None,
                    names: tuple[str, str] = ("CameraTrajectory.txt", "KeyFrameTrajectory.txt")
                    ) -> np.ndarray:
    folder.mkdir(parents=True, exist_ok=True)
    stamps = seq.timestamps_s if stamps is None else stamps
    est = _estimated(seq)
    tracked = [i for i in range(len(seq)) if i not in lost]
    (folder / names[0]).write_text(_orbslam_lines(stamps[tracked], est[tracked], 9))
    kf = list(keyframes)
    (folder / names[1]).write_text(_orbslam_lines(stamps[kf], est[kf], 7))
    return est


# ---------------------------------------------------------------- ORB-SLAM2
def test_orbslam2_folder(seq: Sequence, export: Path, tmp_path: Path) -> None:
    est = _orbslam_folder(tmp_path / "orb", seq)
    run = import_external_run(tmp_path / "orb", tmp_path / "run", fmt="orbslam2",
                              export_dir=export)
    assert run.method == "ORB-SLAM2" and run.sequence_name == seq.name
    assert run.estimate["poses"] == "all" and run.estimate["renders"] == "none"
    traj = run.read_trajectory()
    tracked = [i for i in range(len(seq)) if i != 3]
    np.testing.assert_allclose(traj.timestamps, seq.timestamps_s[tracked], atol=1e-9)
    np.testing.assert_allclose(traj.poses, est[tracked], atol=2e-6)
    keyframes = run.read_keyframes()
    assert keyframes is not None and keyframes.tolist() == [0, 4, 8]
    m = evaluate_run(run.path)
    assert m["ate"]["n_matched"] == 9 and m["ate"]["rmse_m"] < 0.006  # the 2 mm noise
    assert any("ATE over 9 of 10 frames" in n for n in m["notes"])
    m = evaluate_run(run.path, "monogs", write=False)  # keyframes from KeyFrameTrajectory.txt
    assert m["ate"]["n_matched"] == 3


def test_orbslam2_keyframe_file_alone_is_marked(seq: Sequence, export: Path,
                                                tmp_path: Path) -> None:
    _orbslam_folder(tmp_path / "orb", seq)
    run = import_external_run(tmp_path / "orb" / "KeyFrameTrajectory.txt", tmp_path / "run",
                              fmt="orbslam2", export_dir=export)
    assert run.estimate["poses"] == "keyframes"
    keyframes = run.read_keyframes()
    assert keyframes is not None and keyframes.tolist() == [0, 4, 8]
    m = evaluate_run(run.path)
    assert m["ate"]["n_matched"] == 3 and m["ate"]["estimate_poses"] == "keyframes"
    # ORB-SLAM wrote the file at shutdown: it read all 10 frames (not the last keyframe's
    # index + 1), and under the all-frame protocol the estimate covers its 3 poses
    assert run.estimate["frames_processed"] == 10
    assert any("ATE over 3 of 10 frames: the estimate holds keyframes poses only" in n
               for n in m["notes"])
    assert m["coverage"] == {"frames_processed": 3, "frames_in_sequence": 10}
    assert any("RPE per frame pairs consecutive poses of the estimate (keyframes)" in n
               for n in m["notes"])


def test_retimed_export_maps_back_to_sequence_stamps(seq_path: Path, tmp_path: Path) -> None:
    fast = Sequence.open(retimed_copy(seq_path, tmp_path / "fast", 20_000))
    exp = export_sequence(fast, tmp_path / "exp", fmt="tum-rgbd")
    assert exp.retimed
    t_export = np.round(fast.timestamps_s[0] + np.arange(len(fast)) / 30, 6)
    _orbslam_folder(tmp_path / "orb", fast, lost=(), stamps=t_export)
    run = import_external_run(tmp_path / "orb", tmp_path / "run", fmt="orbslam2",
                              export_dir=exp.path)
    np.testing.assert_allclose(run.read_trajectory().timestamps, fast.timestamps_s, atol=1e-9)
    # without the export's index the retimed stamps match no frame: a clear error
    with pytest.raises(InputError, match="matches no frame"):
        import_external_run(tmp_path / "orb", tmp_path / "run2", fmt="orbslam2",
                            sequence_path=fast.path)


# ---------------------------------------------------------------- Photo-SLAM
def _photoslam_folder(folder: Path, seq: Sequence, export: Path,
                      keyframes: tuple[int, ...] = (0, 4, 8), size: tuple[int, int] | None = None
                      ) -> dict[int, np.ndarray]:
    _orbslam_folder(folder, seq, lost=(), keyframes=keyframes,
                    names=("CameraTrajectory_TUM.txt", "KeyFrameTrajectory_TUM.txt"))
    shutdown = folder / "30000_shutdown"
    (shutdown / "image").mkdir(parents=True)
    (shutdown / "ply").mkdir()
    cameras, written = [], {}
    for kfid, frame in enumerate(keyframes):
        rng = np.random.default_rng(frame)
        img = rng.integers(0, 256, (*(size or (seq.height, seq.width)), 3), dtype=np.uint8)
        # recordKeyframeRendered: RGB float -> cvtColor(RGB2BGR) -> imwrite "<iter>_<kfid>.jpg"
        cv2.imwrite(str(shutdown / "image" / f"30000_{kfid}.jpg"), img[:, :, ::-1])
        image = cv2.imread(str(shutdown / "image" / f"30000_{kfid}.jpg"))
        assert image is not None
        written[frame] = image[:, :, ::-1]
        cameras.append({"id": kfid, "img_name": f"rgb/{frame:06d}.png", "width": seq.width,
                        "height": seq.height, "position": [0, 0, 0],
                        "rotation": np.eye(3).tolist(), "fy": 1.0, "fx": 1.0})
    (shutdown / "ply" / "cameras.json").write_text(json.dumps(cameras, indent=3))
    (shutdown / "image" / "30000_0_gt.jpg").write_bytes(b"")  # other files are ignored
    return written


def test_photoslam_folder_with_keyframe_renders(seq: Sequence, export: Path,
                                                tmp_path: Path) -> None:
    written = _photoslam_folder(tmp_path / "ps", seq, export)
    run = import_external_run(tmp_path / "ps", tmp_path / "run", fmt="photoslam",
                              export_dir=export)
    assert run.method == "Photo-SLAM"
    assert run.estimate["poses"] == "all" and run.estimate["renders"] == "keyframes"
    assert run.render_indices() == [0, 4, 8]
    for frame, img in written.items():
        np.testing.assert_array_equal(run.read_render(frame), img)
    m = evaluate_run(run.path)
    assert m["rendering"] is None
    assert any("renders not scored" in n and "keyframes" in n for n in m["notes"])


def test_photoslam_render_of_the_wrong_size(seq: Sequence, export: Path, tmp_path: Path) -> None:
    _photoslam_folder(tmp_path / "ps", seq, export, size=(24, 32))
    with pytest.raises(InputError, match="render is 32x24"):
        import_external_run(tmp_path / "ps", tmp_path / "run", fmt="photoslam",
                            export_dir=export)


# ---------------------------------------------------------------- MonoGS
def _monogs_result(folder: Path, seq: Sequence, uids: Sequence_[int] = (0, 3, 6, 9),
                   frames: Sequence_[int] | None = None) -> np.ndarray:
    """``plot/trj_final.json`` as ``eval_ate`` writes it (json.dump, indent=4, c2w lists),
    plus its stats and rendering results."""
    rows = list(uids) if frames is None else list(frames)
    est = _estimated(seq)[rows]
    (folder / "plot").mkdir(parents=True)
    data = {"trj_id": list(uids), "trj_est": [p.tolist() for p in est],
            "trj_gt": [p.tolist() for p in seq.poses[rows]]}
    (folder / "plot" / "trj_final.json").write_text(json.dumps(data, indent=4))
    (folder / "plot" / "stats_final.json").write_text(json.dumps(
        {"rmse": 0.01, "mean": 0.009, "median": 0.008, "std": 0.002, "min": 0.0, "max": 0.02,
         "sse": 0.001}, indent=4))
    (folder / "psnr" / "before_opt").mkdir(parents=True)
    (folder / "psnr" / "before_opt" / "final_result.json").write_text(json.dumps(
        {"mean_psnr": 25.0, "mean_ssim": 0.8, "mean_lpips": 0.2}, indent=4))
    return est


def test_monogs_result_folder(seq: Sequence, export: Path, tmp_path: Path) -> None:
    est = _monogs_result(tmp_path / "mono", seq)
    # the TUM reader still rejects the JSON, as before: the format must be named
    from egs_bench.geometry import read_tum

    with pytest.raises(InputError, match="expected 8 numbers"):
        read_tum(tmp_path / "mono" / "plot" / "trj_final.json")
    run = import_external_run(tmp_path / "mono", tmp_path / "run", fmt="monogs",
                              export_dir=export)
    traj = run.read_trajectory()
    np.testing.assert_allclose(traj.timestamps, seq.timestamps_s[[0, 3, 6, 9]], atol=1e-9)
    np.testing.assert_allclose(traj.poses, est, atol=1e-9)
    assert run.estimate["poses"] == "keyframes"
    keyframes = run.read_keyframes()
    assert keyframes is not None and keyframes.tolist() == [0, 3, 6, 9]
    reported = json.loads((run.path / "reported_metrics.json").read_text())
    assert reported["ate_stats"]["rmse"] == 0.01
    assert reported["rendering_before_opt"]["mean_psnr"] == 25.0
    m = evaluate_run(run.path)
    assert m["ate"]["n_matched"] == 4
    assert any("keyframes poses only" in n for n in m["notes"])


def test_monogs_uids_follow_its_frame_dropping(seq_path: Path, tmp_path: Path) -> None:
    """Exported without retiming at 50 fps, MonoGS keeps frames 0, 2, 4, ...: uid k is frame
    2k (its TUMParser's 1/32 s rule)."""
    fast = Sequence.open(retimed_copy(seq_path, tmp_path / "fast", 20_000))
    exp = export_sequence(fast, tmp_path / "exp", fmt="tum-rgbd", retime="never").path
    kept_by_monogs = len(monogs_tum_parser(str(exp))[0])
    kept = monogs_kept_frames(fast.timestamps_s)
    assert len(kept) == kept_by_monogs and kept.tolist() == list(range(0, len(fast), 2))
    _monogs_result(tmp_path / "mono", fast, uids=(0, 1, 3), frames=(0, 2, 6))
    run = import_external_run(tmp_path / "mono", tmp_path / "run", fmt="monogs",
                              export_dir=exp)
    np.testing.assert_allclose(run.read_trajectory().timestamps,
                               fast.timestamps_s[[0, 2, 6]], atol=1e-9)
    _monogs_result(tmp_path / "bad", fast, uids=(0, 1, 7), frames=(0, 2, 6))
    with pytest.raises(InputError, match="uid 7 beyond the 5 frames"):
        import_external_run(tmp_path / "bad", tmp_path / "run2", fmt="monogs", export_dir=exp)


def test_monogs_all_frame_dump_counts_as_all_frames(seq: Sequence, export: Path,
                                                    tmp_path: Path) -> None:
    """A trj_*.json holding every uid (the documented dump hook) is an all-frame estimate."""
    _monogs_result(tmp_path / "mono", seq, uids=range(len(seq)))
    run = import_external_run(tmp_path / "mono" / "plot" / "trj_final.json", tmp_path / "run",
                              fmt="monogs", export_dir=export)
    assert run.estimate["poses"] == "all" and run.read_keyframes() is None


def test_monogs_ply_is_rendered_at_the_imported_poses(seq: Sequence, export: Path,
                                                      tmp_path: Path) -> None:
    """A map of near-opaque pixel-sized Gaussians made from frame 0's display colours and depth
    renders frame 0 back at its pose (measured 19.0 dB on this fine texture: the Gaussians are
    about a pixel wide; against the frame shifted by one pixel 14.2 dB); at frame 9's far pose
    it shows another view (6.2 dB)."""
    import torch

    from egs_bench.eval.image_metrics import psnr
    from egs_bench.render.gaussian_map import GaussianMap
    from egs_bench.render.ply import save_ply

    est = _monogs_result(tmp_path / "mono", seq, uids=(0, 4, 9))
    gmap = GaussianMap.empty()
    gmap.add_from_depth(seq.rgb(0) / 255.0, seq.depth(0), seq.intrinsics, est[0], downsample=1,
                        point_size=0.1, opacity=0.99, generator=torch.Generator().manual_seed(0))
    (tmp_path / "mono" / "point_cloud" / "final").mkdir(parents=True)
    save_ply(gmap, tmp_path / "mono" / "point_cloud" / "final" / "point_cloud.ply")
    run = import_external_run(tmp_path / "mono", tmp_path / "run", fmt="monogs",
                              export_dir=export, render_ply=True)
    assert run.render_indices() == [0, 4, 9] and run.estimate["renders"] == "keyframes"
    at_pose = psnr(run.read_render(0), seq.rgb(0))
    assert at_pose > 17.5
    assert psnr(run.read_render(0), np.roll(seq.rgb(0), 1, axis=1)) < at_pose - 3
    assert psnr(run.read_render(9), seq.rgb(0)) < at_pose - 3


# ---------------------------------------------------------------- RampVO
def _rampvo_file(path: Path, seq: Sequence, frames: list[int] | np.ndarray, scale: float = 0.5
                 ) -> np.ndarray:
    """evaluate.py: traj_est from lietorch (t xyz, q xyzw, camera-to-world), wrapped by
    PoseTrajectory3D with ``orientations_quat_wxyz=traj_est[:, 3:][:, (1, 2, 3, 0)]`` and image
    stamps in seconds, then ``save_results``: ``np.savetxt`` of ``t * 1e-9``, positions and
    ``orientations_quat_wxyz``. The trajectory is scaled (monocular)."""
    from evo.core.trajectory import PoseTrajectory3D

    est = _estimated(seq, noise=0.0)[list(frames)]
    est[:, :3, 3] *= scale
    t, q_xyzw = pose_to_tq(est)
    traj_est = np.concatenate([t, q_xyzw], axis=1)
    traj = PoseTrajectory3D(positions_xyz=traj_est[:, :3],
                            orientations_quat_wxyz=traj_est[:, 3:][:, (1, 2, 3, 0)],
                            timestamps=seq.timestamps_s[list(frames)])
    time_est = (traj.timestamps * 10 ** -9)[..., np.newaxis]
    np.savetxt(path, np.concatenate((time_est, traj.positions_xyz,
                                     traj.orientations_quat_wxyz), axis=1))
    return est


def test_rampvo_estimate(seq: Sequence, tmp_path: Path) -> None:
    eds = export_sequence(seq, tmp_path / "eds", fmt="eds").path
    frames = [5, 1, 3, 7, 9, 8]  # list(set(...)) order: not necessarily sorted
    est = _rampvo_file(tmp_path / "stamped_traj_estimate.txt", seq, frames)
    run = import_external_run(tmp_path / "stamped_traj_estimate.txt", tmp_path / "run",
                              fmt="rampvo", export_dir=eds)
    assert run.method == "RampVO"
    assert run.estimate["poses"] == "subset" and run.estimate["scale_free"] is True
    traj = run.read_trajectory()
    order = np.argsort(frames)
    np.testing.assert_allclose(traj.timestamps, seq.timestamps_s[np.sort(frames)], atol=1e-9)
    np.testing.assert_allclose(traj.poses, est[order], atol=1e-7)
    m = evaluate_run(run.path)
    assert m["ate"]["alignment"] == "sim3" and m["ate"]["scale"] == pytest.approx(2.0, rel=1e-5)
    assert m["ate"]["rmse_m"] < 1e-6
    assert any("sim3 alignment instead of the protocol's se3" in n for n in m["notes"])
    assert any("ATE over 6 of 10 frames" in n for n in m["notes"])
    assert any("RPE translation is in the estimate's own scale" in n for n in m["notes"])
    # the labelled order (w first) gives other rotations: the option matters
    run2 = import_external_run(tmp_path / "stamped_traj_estimate.txt", tmp_path / "run2",
                               fmt="rampvo", export_dir=eds, quaternion="wxyz")
    assert np.abs(run2.read_trajectory().poses[:, :3, :3] - est[order][:, :3, :3]).max() > 0.1


def test_rampvo_bad_files(seq: Sequence, tmp_path: Path) -> None:
    bad = tmp_path / "seven.txt"
    np.savetxt(bad, np.ones((4, 7)))
    with pytest.raises(InputError, match="expected 8 columns"):
        import_external_run(bad, tmp_path / "r", fmt="rampvo", sequence_path=seq.path)
    off = tmp_path / "off.txt"
    rows = np.concatenate([seq.timestamps_s[:4, None] + 0.01, np.zeros((4, 3)),
                           np.tile([0, 0, 0, 1.0], (4, 1))], axis=1)
    np.savetxt(off, rows)
    with pytest.raises(InputError, match="off.txt: time stamp"):
        import_external_run(off, tmp_path / "r", fmt="rampvo", sequence_path=seq.path)
    with pytest.raises(ConfigError, match="quaternion order"):
        import_external_run(off, tmp_path / "r", fmt="rampvo", sequence_path=seq.path,
                            quaternion="xyzw")


# ---------------------------------------------------------------- bad input and safety
@pytest.mark.parametrize("content, message", [
    ({"trj_est": []}, "needs 'trj_id' and 'trj_est'"),
    ({"trj_id": [0, 1, 2], "trj_est": [np.eye(4).tolist()] * 2}, "one 4x4 matrix per"),
    ({"trj_id": [0, 1, 2], "trj_est": [(2 * np.eye(4)).tolist()] * 3}, "not a rigid"),
    ({"trj_id": [0, 0, 1], "trj_est": [np.eye(4).tolist()] * 3}, "repeated ids"),
])
def test_monogs_bad_json(seq: Sequence, tmp_path: Path, content: dict[str, Any], message: str
                         ) -> None:
    path = tmp_path / "trj_final.json"
    path.write_text(json.dumps(content))
    with pytest.raises(InputError, match=message):
        import_external_run(path, tmp_path / "r", fmt="monogs", sequence_path=seq.path)
    path.write_text("{not json")
    with pytest.raises(InputError, match="trj_final.json: not a MonoGS trajectory JSON"):
        import_external_run(path, tmp_path / "r", fmt="monogs", sequence_path=seq.path)


def test_import_safety_and_options(seq: Sequence, export: Path, tmp_path: Path) -> None:
    _orbslam_folder(tmp_path / "orb", seq)
    with pytest.raises(ConfigError, match="unknown import format"):
        import_external_run(tmp_path / "orb", tmp_path / "r", fmt="kitti", export_dir=export)
    with pytest.raises(InputError, match="needs the export folder"):
        import_external_run(tmp_path / "orb", tmp_path / "r", fmt="orbslam2")
    with pytest.raises(InputError, match="holds neither"):
        import_external_run(tmp_path, tmp_path / "r", fmt="orbslam2", export_dir=export)
    import_external_run(tmp_path / "orb", tmp_path / "r", fmt="orbslam2", export_dir=export)
    with pytest.raises(OutputError, match="already exists; pass --overwrite"):
        import_external_run(tmp_path / "orb", tmp_path / "r", fmt="orbslam2", export_dir=export)
    run = import_external_run(tmp_path / "orb", tmp_path / "r", fmt="orbslam2",
                              export_dir=export, overwrite=True, method="ORB2-custom")
    assert run.method == "ORB2-custom"
    moved = tmp_path / "moved_export"
    shutil.copytree(export, moved)
    run = import_external_run(tmp_path / "orb", tmp_path / "r3", fmt="orbslam2",
                              export_dir=moved, sequence_path=seq.path)
    assert run.sequence_path == seq.path.resolve()


def test_cli_import_run(seq: Sequence, export: Path, tmp_path: Path,
                        capsys: pytest.CaptureFixture[str]) -> None:
    from egs_bench.cli import main

    _orbslam_folder(tmp_path / "orb", seq)
    assert main(["import-run", str(tmp_path / "orb" / "KeyFrameTrajectory.txt"),
                 "-o", str(tmp_path / "run"), "--from", "orbslam2", "--export", str(export)]) == 0
    out = capsys.readouterr().out
    assert "imported ORB-SLAM2 on plane" in out and "poses: keyframes" in out
    assert main(["eval", str(tmp_path / "run")]) == 0
    assert "keyframes poses only" in capsys.readouterr().out
    code = main(["import-run", str(tmp_path / "orb"), "-o", str(tmp_path / "run2"), "--from",
                 "tum"])
    assert_cli_error(code, capsys.readouterr().err, 2, "--from tum needs --method and --sequence")


# ---------------------------------------------------------------- validation at import
def _no_leftovers(folder: Path) -> bool:
    return not [p for p in folder.iterdir() if p.name.startswith(".")]


def _tum_estimate(path: Path, seq: Sequence, offset_s: float = 0.0) -> Path:
    from egs_bench.geometry import write_tum

    write_tum(path, seq.timestamps_s + offset_s, _estimated(seq))
    return path


def _renders(folder: Path, seq: Sequence, frames: tuple[int, ...] = (0, 5),
             size: tuple[int, int] | None = None) -> Path:
    folder.mkdir()
    for f in frames:
        img = np.full((*(size or (seq.height, seq.width)), 3), 40 + f, dtype=np.uint8)
        cv2.imwrite(str(folder / f"{f:06d}.png"), img)
    return folder


def _truncate(path: Path) -> None:
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


def test_tum_import_validates_as_eval_would(seq: Sequence, tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    """A missing or corrupt sequence folder, an estimate 100 s off the ground truth, renders
    of the wrong size or truncated: each is refused with one line naming the file, and no
    run folder is left (a retry needs no --overwrite)."""
    from egs_bench.cli import main
    from egs_bench.interop.importing import import_tum_run

    est = _tum_estimate(tmp_path / "est.txt", seq)
    off = _tum_estimate(tmp_path / "off.txt", seq, offset_s=100.0)
    broken = tmp_path / "broken_seq"
    shutil.copytree(seq.path, broken)
    (broken / "meta.yaml").write_bytes(b"\x00\xff binary")
    small = _renders(tmp_path / "small", seq, size=(24, 32))
    cut = _renders(tmp_path / "cut", seq)
    _truncate(cut / "000005.png")
    beyond = _renders(tmp_path / "beyond", seq, frames=(0, 12))
    out = tmp_path / "run"
    cases = [
        ([str(est), "--sequence-path", str(tmp_path / "nowhere")], "nowhere"),
        ([str(est), "--sequence-path", str(broken)], "meta.yaml"),
        ([str(off), "--sequence-path", str(seq.path)], "off.txt: no timestamp overlap"),
        ([str(off), "--groundtruth", str(seq.path / "groundtruth.txt")],
         "off.txt: no timestamp overlap"),
        ([str(est), "--sequence-path", str(seq.path), "--renders", str(small)],
         "000000.png: render is 32x24, the sequence is 64x48"),
        ([str(est), "--sequence-path", str(seq.path), "--renders", str(cut)],
         "000005.png: cannot read image"),
        ([str(est), "--sequence-path", str(seq.path), "--renders", str(beyond)],
         "frame 12, beyond the sequence's 10 frames"),
    ]
    for argv, message in cases:
        code = main(["import-run", *argv, "-o", str(out), "--from", "tum", "-m", "ext", "-s",
                     "plane"])
        assert_cli_error(code, capsys.readouterr().err, 3, message)
        assert not out.exists() and _no_leftovers(tmp_path), argv
    # the fixed inputs import into the same folder without --overwrite
    run = import_tum_run(est, out, method="ext", sequence_name="plane",
                         sequence_path=seq.path, renders_dir=_renders(tmp_path / "ok", seq))
    assert run.read_status().state == "done" and run.render_indices() == [0, 5]
    assert run.path == out and evaluate_run(out)["ate"]["n_matched"] == len(seq)


def test_external_import_with_a_bad_render_leaves_nothing(seq: Sequence, export: Path,
                                                          tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]
                                                          ) -> None:
    """A truncated Photo-SLAM render (decoded before anything is written) and a failure while
    writing (the staging folder is removed): neither leaves a folder that blocks a retry."""
    from egs_bench.cli import main

    _photoslam_folder(tmp_path / "ps", seq, export)
    jpg = tmp_path / "ps" / "30000_shutdown" / "image" / "30000_1.jpg"
    good = jpg.read_bytes()
    _truncate(jpg)
    out = tmp_path / "run"
    code = main(["import-run", str(tmp_path / "ps"), "-o", str(out), "--from", "photoslam",
                 "--export", str(export)])
    assert_cli_error(code, capsys.readouterr().err, 3, jpg)
    assert not out.exists() and _no_leftovers(tmp_path)
    jpg.write_bytes(good)
    # a failure after the run folder was created (disk full while writing a render)
    from egs_bench.runs.folder import RunFolder

    def full_disk(self: Any, index: int, image: np.ndarray) -> None:
        raise OSError(28, "No space left on device")

    original = RunFolder.write_render
    RunFolder.write_render = full_disk  # type: ignore[method-assign, assignment]
    try:
        with pytest.raises(UnwritableOutputError, match=f"{out}: cannot write: the disk is full"):
            import_external_run(tmp_path / "ps", out, fmt="photoslam", export_dir=export)
    finally:
        RunFolder.write_render = original  # type: ignore[method-assign]
    assert not out.exists() and _no_leftovers(tmp_path)
    run = import_external_run(tmp_path / "ps", out, fmt="photoslam", export_dir=export)
    assert run.read_status().state == "done" and run.render_indices() == [0, 4, 8]
    # replacing an existing import keeps the user's own files (rewritten in place)
    (out / "notes.txt").write_text("mine")
    import_external_run(tmp_path / "ps", out, fmt="photoslam", export_dir=export,
                        overwrite=True)
    assert (out / "notes.txt").read_text() == "mine"


def test_monogs_keyframes_report_their_real_coverage(seq: Sequence, export: Path,
                                                     tmp_path: Path) -> None:
    """MonoGS's keyframe-only trj_final.json (keyframes 0, 3, 6 of 10 frames,
    the last keyframe not the last frame) covers the 10 frames MonoGS read: complete under the
    monogs protocol, which scores keyframes; under the all-frame protocol it covers its 3
    poses, not "7 of 10" (the last keyframe's index + 1)."""
    from egs_bench.eval.results import collect_results

    _monogs_result(tmp_path / "mono", seq, uids=(0, 3, 6))
    runs = tmp_path / "runs"
    run = import_external_run(tmp_path / "mono", runs / "monogs", fmt="monogs",
                              export_dir=export)
    assert run.estimate["poses"] == "keyframes" and run.estimate["frames_processed"] == 10
    m = evaluate_run(run.path, "monogs", write=False)
    assert m["coverage"] == {"frames_processed": 10, "frames_in_sequence": 10}
    assert not any("covers" in n for n in m["notes"]), m["notes"]
    (result,) = collect_results(runs, protocol="monogs", evaluate_missing=True).runs
    assert result.status == "ok" and result.complete
    m = evaluate_run(run.path, "egs", write=False)
    assert m["coverage"] == {"frames_processed": 3, "frames_in_sequence": 10}
    assert any("ATE over 3 of 10 frames: the estimate holds keyframes poses only" in n
               for n in m["notes"]), m["notes"]
    (result,) = collect_results(runs, protocol="egs").runs
    assert result.status == "incomplete" and result.reason == "covers 3 of 10 frames"
    # an intermediate trj_<n>.json: MonoGS was still running, coverage ends at its last pose
    (tmp_path / "mono" / "plot" / "trj_final.json").rename(tmp_path / "mono" / "plot" /
                                                           "trj_00006.json")
    run = import_external_run(tmp_path / "mono" / "plot" / "trj_00006.json",
                              tmp_path / "mid", fmt="monogs", export_dir=export)
    assert "frames_processed" not in run.estimate
    assert evaluate_run(run.path, "monogs", write=False)["coverage"]["frames_processed"] == 7
