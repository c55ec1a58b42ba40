"""RPE against evo's own ``evo_rpe`` (its command-line function and executable), analytic cases
and an independent numpy/scipy computation; the GT EST argument order of ``ate`` and ``rpe``."""

import json
import subprocess
import sys
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from egs_bench.errors import ConfigError, InputError
from egs_bench.eval.ate import ate_from_files, check_argument_order, file_role_hint
from egs_bench.eval.rpe import RpeResult, compute_rpe, rpe_from_files, standard_rpe
from egs_bench.geometry import Trajectory, pose_from_tq, write_tum
from tests.helpers.cli import assert_cli_error, run_cli
from tests.helpers.trajectory_pairs import PAIRS, REAL, SYNTHETIC, pair_paths

# (our keyword options, the same options for evo_rpe)
OPTIONS = [
    ({"relation": "trans_part"}, ["-r", "trans_part"]),  # per frame, translation
    ({"relation": "angle_deg"}, ["-r", "angle_deg"]),  # per frame, rotation
    ({"relation": "trans_part", "delta": 1, "delta_unit": "m"}, ["-d", "1", "-u", "m"]),
    ({"relation": "angle_deg", "delta": 1, "delta_unit": "m"},
     ["-r", "angle_deg", "-d", "1", "-u", "m"]),
    ({"relation": "trans_part", "delta": 10, "all_pairs": True}, ["-d", "10", "--all_pairs"]),
    ({"relation": "angle_rad", "delta": 5, "delta_unit": "d"},
     ["-r", "angle_rad", "-d", "5", "-u", "d"]),
    ({"relation": "trans_part", "align": "sim3"}, ["-as"]),
]


def _evo_rpe_function(gt: Path, est: Path, extra: list[str], out: Path) -> zipfile.ZipFile:
    """evo_rpe's own command-line function: its argument parser and ``evo.cli.rpe.run``."""
    from evo.cli import rpe as evo_rpe_cli
    from evo.cli import rpe_parser

    args = rpe_parser.parser().parse_args(
        ["tum", str(gt), str(est), *extra, "--no_warnings", "--silent", "--save_results",
         str(out)])
    evo_rpe_cli.run(args)
    return zipfile.ZipFile(out)


def _assert_same(ours: RpeResult, ref_zip: zipfile.ZipFile) -> None:
    import io

    stats = json.loads(ref_zip.read("stats.json"))
    for key in ("rmse", "mean", "median", "std", "min", "max"):
        assert getattr(ours, key) == pytest.approx(stats[key], rel=1e-10, abs=1e-14), key
    errors = np.load(io.BytesIO(ref_zip.read("error_array.npy")))
    stamps = np.load(io.BytesIO(ref_zip.read("timestamps.npy")))
    np.testing.assert_allclose(ours.errors, errors, rtol=1e-10, atol=1e-14)
    np.testing.assert_array_equal(ours.timestamps, stamps)  # the same pose pairs


@pytest.mark.parametrize(("est_name", "gt_name"), PAIRS)
@pytest.mark.parametrize(("ours", "evo_args"), OPTIONS)
def test_rpe_equals_evo_rpe(request: pytest.FixtureRequest, tmp_path: Path, est_name: Any,
                            gt_name: Any, ours: Any, evo_args: Any) -> None:
    est, gt = pair_paths(request, tmp_path, est_name, gt_name)
    with _evo_rpe_function(gt, est, evo_args, tmp_path / "res.zip") as ref:
        _assert_same(rpe_from_files(est, gt, **ours), ref)


@pytest.mark.parametrize(("est_name", "gt_name"), [SYNTHETIC, REAL[1]])
def test_rpe_equals_evo_rpe_executable(request: pytest.FixtureRequest, tmp_path: Path,
                                       est_name: Any, gt_name: Any) -> None:
    est, gt = pair_paths(request, tmp_path, est_name, gt_name)
    evo_rpe = Path(sys.executable).parent / "evo_rpe"
    out = tmp_path / "res.zip"
    subprocess.run([str(evo_rpe), "tum", str(gt), str(est), "-r", "angle_deg", "-d", "1", "-u",
                    "m", "--no_warnings", "--save_results", str(out)], check=True,
                   capture_output=True)
    with zipfile.ZipFile(out) as ref:
        _assert_same(rpe_from_files(est, gt, relation="angle_deg", delta=1, delta_unit="m"), ref)


def _wiggle(n: int = 120) -> Trajectory:
    s = np.linspace(0, 2 * np.pi, n)
    t = np.stack([np.cos(s), 0.5 * np.sin(2 * s), 0.2 * np.sin(s)], axis=1)
    q = Rotation.from_euler("zyx", np.stack([s, 0.3 * s, 0.1 * np.sin(s)], axis=1)).as_quat()
    return Trajectory(np.arange(n) / 30.0, pose_from_tq(t, q))


def test_rpe_constant_relative_error_is_exact() -> None:
    """Every estimated step = the true step followed by the same error E: each per-frame pair
    has exactly E's translation norm and rotation angle, whatever the trajectory."""
    gt = _wiggle()
    err = np.eye(4)
    err[:3, :3] = Rotation.from_rotvec(np.radians(0.7) * np.array([0.6, 0.0, 0.8])).as_matrix()
    err[:3, 3] = [0.003, -0.004, 0.0]  # 5 mm
    steps = [gt.poses[0]]
    for i in range(1, len(gt)):
        step = np.linalg.inv(gt.poses[i - 1]) @ gt.poses[i]
        steps.append(steps[-1] @ step @ err)
    est = Trajectory(gt.timestamps, np.stack(steps))
    trans = compute_rpe(est, gt, relation="trans_part")
    rot = compute_rpe(est, gt, relation="angle_deg")
    assert trans.n_pairs == rot.n_pairs == len(gt) - 1
    np.testing.assert_allclose(trans.errors, 0.005, atol=1e-12)
    np.testing.assert_allclose(rot.errors, 0.7, atol=1e-9)
    assert trans.unit == "m" and rot.unit == "deg" and trans.std < 1e-12
    # the ATE of the same estimate grows with the drift; RPE does not see the accumulation
    assert compute_rpe(est, gt, relation="trans_part", align="se3").rmse == pytest.approx(
        trans.rmse, abs=1e-12)


def test_rpe_per_metre_on_a_scaled_straight_line() -> None:
    """Estimate moves 0.25 m per frame, truth 0.125 m: pairs are 1 m of the estimate's path
    apart (4 frames) and each pair's translation error is exactly 1 - 0.5 = 0.5 m."""
    n = 21
    steps = np.arange(n, dtype=np.float64)
    q = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
    gt = Trajectory(steps / 10, pose_from_tq(np.stack([0.125 * steps, 0 * steps, 0 * steps], 1),
                                             q))
    est = Trajectory(steps / 10, pose_from_tq(np.stack([0.25 * steps, 0 * steps, 0 * steps], 1),
                                              q))
    res = compute_rpe(est, gt, relation="trans_part", delta=1, delta_unit="m")
    assert res.n_pairs == 5 and res.delta_unit == "meters"
    np.testing.assert_array_equal(res.timestamps, [0.4, 0.8, 1.2, 1.6, 2.0])
    np.testing.assert_allclose(res.errors, 0.5, atol=1e-15)
    # a collinear path cannot be Umeyama-aligned: reported, not a traceback
    with pytest.raises(InputError, match="cannot align to ground truth"):
        compute_rpe(est, gt, delta=1, delta_unit="m", align="sim3")


def test_rpe_matches_independent_computation_and_sim3_scale() -> None:
    gt = _wiggle(90)
    rng = np.random.default_rng(5)
    poses = gt.poses.copy()
    poses[:, :3, 3] += rng.normal(0, 0.004, (len(gt), 3))
    noise = Rotation.from_rotvec(rng.normal(0, np.radians(0.3), (len(gt), 3))).as_matrix()
    poses[:, :3, :3] = poses[:, :3, :3] @ noise
    est = Trajectory(gt.timestamps, poses)
    # independent: E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j) for consecutive frames (TUM RGB-D's RPE)
    q_rel = np.linalg.inv(gt.poses[:-1]) @ gt.poses[1:]
    p_rel = np.linalg.inv(est.poses[:-1]) @ est.poses[1:]
    e = np.linalg.inv(q_rel) @ p_rel
    trans = np.linalg.norm(e[:, :3, 3], axis=1)
    angle = np.degrees(Rotation.from_matrix(e[:, :3, :3]).magnitude())
    res_t = compute_rpe(est, gt, relation="trans_part")
    res_r = compute_rpe(est, gt, relation="angle_deg")
    np.testing.assert_allclose(res_t.errors, trans, rtol=1e-10, atol=1e-13)
    np.testing.assert_allclose(res_r.errors, angle, rtol=1e-8, atol=1e-10)
    assert res_t.rmse == pytest.approx(np.sqrt(np.mean(trans**2)), rel=1e-12)
    # an estimate in another scale: Sim(3) alignment recovers the RPE of the scaled copy
    scaled = est.poses.copy()
    scaled[:, :3, 3] *= 0.4
    small = Trajectory(gt.timestamps, scaled)
    assert compute_rpe(small, gt, relation="trans_part").rmse > 3 * res_t.rmse
    sim3 = compute_rpe(small, gt, relation="trans_part", align="sim3")
    assert sim3.scale == pytest.approx(1 / 0.4, rel=0.02)
    assert sim3.rmse == pytest.approx(res_t.rmse, rel=0.05)


def test_rpe_bad_options_and_short_trajectories(tmp_path: Path) -> None:
    gt = _wiggle(30)
    with pytest.raises(ConfigError, match="unknown RPE relation 'yaw'"):
        compute_rpe(gt, gt, relation="yaw")  # type: ignore[arg-type]  # the runtime check
    with pytest.raises(ConfigError, match="unknown delta unit 's'"):
        compute_rpe(gt, gt, delta_unit="s")  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="must be an integer"):
        compute_rpe(gt, gt, delta=1.5)
    with pytest.raises(ConfigError, match="must be > 0"):
        compute_rpe(gt, gt, delta=0)
    with pytest.raises(ConfigError, match="unknown alignment"):
        compute_rpe(gt, gt, align="affine")  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"est\.txt: no pose pair 100 meters apart"):
        compute_rpe(gt, gt, delta=100, delta_unit="m", est_name="est.txt")
    with pytest.raises(InputError, match="no pose pair 40 frames apart"):
        compute_rpe(gt, gt, delta=40)
    # the benchmark summary: a 0.3 m trajectory has no per-metre pair, said in a note
    s = np.linspace(0, 0.3, 10)
    short = Trajectory(np.arange(10) / 30.0,
                       pose_from_tq(np.stack([s, s**2, 0 * s], 1), np.tile([0, 0, 0, 1.0],
                                                                          (10, 1))))
    summary = standard_rpe(short, short)
    assert summary["per_frame"]["translation"]["rmse"] == 0.0
    assert summary["per_frame"]["translation"]["n_pairs"] == 9
    assert summary["per_metre"]["translation"] is None
    assert "no pose pair 1 meters apart" in summary["per_metre"]["note"]


def test_cli_rpe_and_ate_take_gt_first(shared_data: Path, tmp_path: Path,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    d = shared_data / "trajectories"
    gt, est = d / "freiburg1_xyz-groundtruth.txt", d / "freiburg1_xyz-rgbdslam.txt"
    ref = rpe_from_files(est, gt, relation="angle_deg", delta=1, delta_unit="m")
    code, out, _ = run_cli(capsys, "rpe", str(gt), str(est), "-r", "angle_deg", "-d", "1", "-u",
                           "m")
    assert code == 0 and f"{ref.rmse:.6f}" in out and "8 pairs of 785 matched poses" in out
    code, out, _ = run_cli(capsys, "ate", str(gt), str(est))
    assert code == 0 and "0.013470" in out and f"reference {gt}" in out
    # the old order fails with one clear line ...
    code, _, err = run_cli(capsys, "ate", str(est), str(gt), "--align", "sim3")
    assert_cli_error(code, err, 2, "takes GT EST (evo's order)", "looks like ground truth",
                     "--est-first")
    # ... or, with the explicit flag, gives exactly the numbers of the new order
    sim3 = ate_from_files(est, gt, align="sim3")
    code, out, _ = run_cli(capsys, "ate", "--est-first", str(est), str(gt), "--align", "sim3")
    assert code == 0 and f"{sim3.rmse:.6f}" in out and f"scale: {sim3.scale:.6f}" in out
    # why the order matters: swapping the roles changes Sim(3) ATE (not SE(3) ATE)
    swapped = ate_from_files(gt, est, align="sim3")
    assert abs(swapped.rmse - sim3.rmse) > 1e-4
    code, _, err = run_cli(capsys, "rpe", str(est), str(gt))
    assert_cli_error(code, err, 2, "egs-bench rpe takes GT EST", "--est-first")


def test_file_role_hints(tmp_path: Path) -> None:
    from egs_bench.runs.folder import RunFolder

    run = RunFolder.create(tmp_path / "run", method="m", sequence_name="s",
                           sequence_path=tmp_path)
    traj = _wiggle(5)
    write_tum(run.trajectory_path, traj.timestamps, traj.poses)
    assert file_role_hint(run.trajectory_path) == "estimate"
    assert file_role_hint(tmp_path / "trajectory.txt") is None  # not in a run folder
    for name in ("groundtruth.txt", "fr1_xyz-groundtruth.txt", "stamped_groundtruth.txt",
                 "desk_gt.txt", "GT.txt", "ground_truth.tum"):
        assert file_role_hint(tmp_path / name) == "groundtruth", name
    for name in ("CameraTrajectory.txt", "KeyFrameTrajectory_TUM.txt",
                 "stamped_traj_estimate.txt", "my_estimate.txt"):
        assert file_role_hint(tmp_path / name) == "estimate", name
    for name in ("orb.txt", "gtsam_out.txt", "light.txt", "groundtruth_estimate.txt"):
        assert file_role_hint(tmp_path / name) is None, name
    check_argument_order(tmp_path / "groundtruth.txt", run.trajectory_path, command="ate",
                         swap_hint="")
    check_argument_order(tmp_path / "a.txt", tmp_path / "b.txt", command="ate", swap_hint="")
    with pytest.raises(ConfigError, match="the ground truth .*trajectory.txt looks like an "
                                          "estimate and the estimate .*groundtruth.txt"):
        check_argument_order(run.trajectory_path, tmp_path / "groundtruth.txt", command="ate",
                             swap_hint="")
