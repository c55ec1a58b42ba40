"""ATE against evo's own command-line tool (the reference numbers) and analytic cases."""

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
from egs_bench.eval.ate import ate_from_files, compute_ate
from egs_bench.geometry import Trajectory, pose_from_tq, write_tum
from tests.helpers.trajectory_pairs import PAIRS, REAL, SYNTHETIC, pair_paths


def _evo_ape_cli(gt: Path, est: Path, extra: list[str], tmp_path: Path) -> dict:
    """Run the real ``evo_ape tum GT EST ...`` and read its saved statistics."""
    evo_ape = Path(sys.executable).parent / "evo_ape"
    out = tmp_path / "res.zip"
    subprocess.run([str(evo_ape), "tum", str(gt), str(est), *extra, "--no_warnings",
                    "--save_results", str(out)], check=True, capture_output=True)
    with zipfile.ZipFile(out) as z:
        return json.loads(z.read("stats.json"))


@pytest.mark.parametrize(("est_name", "gt_name"), PAIRS)
def test_ate_equals_evo_ape_cli_se3(request: pytest.FixtureRequest, tmp_path: Path, est_name: Any,
                                    gt_name: Any) -> None:
    est, gt = pair_paths(request, tmp_path, est_name, gt_name)
    ref = _evo_ape_cli(gt, est, ["-a"], tmp_path)
    ours = ate_from_files(est, gt, align="se3")
    for key in ("rmse", "mean", "median", "std", "min", "max"):
        assert abs(getattr(ours, key) - ref[key]) < 1e-9, key
    assert ours.n_matched > 700


@pytest.mark.parametrize(("est_name", "gt_name"), [SYNTHETIC, REAL[0]])
def test_ate_equals_evo_ape_cli_sim3(request: pytest.FixtureRequest, tmp_path: Path, est_name: Any,
                                     gt_name: Any) -> None:
    est, gt = pair_paths(request, tmp_path, est_name, gt_name)
    ref = _evo_ape_cli(gt, est, ["-as"], tmp_path)
    ours = ate_from_files(est, gt, align="sim3")
    assert abs(ours.rmse - ref["rmse"]) < 1e-9
    assert ours.scale != 1.0


def _loop(n: int = 200) -> Trajectory:
    s = np.linspace(0, 2 * np.pi, n)
    t = np.stack([np.cos(s), 0.5 * np.sin(2 * s), 0.2 * np.sin(s)], axis=1)
    q = Rotation.from_euler("zyx", np.stack([s, 0.3 * s, 0.1 * s], axis=1)).as_quat()
    return Trajectory(np.arange(n) / 30.0, pose_from_tq(t, q))


def _transform(traj: Trajectory, rot: np.ndarray, trans: np.ndarray, scale: float = 1.0,
               noise: np.ndarray | None = None) -> Trajectory:
    poses = traj.poses.copy()
    poses[:, :3, :3] = rot @ poses[:, :3, :3]
    poses[:, :3, 3] = scale * poses[:, :3, 3] @ rot.T + trans
    if noise is not None:
        poses[:, :3, 3] += noise
    return Trajectory(traj.timestamps.copy(), poses)


def test_ate_analytic_rigid_and_offset() -> None:
    gt = _loop()
    rot = Rotation.from_rotvec([0.3, -0.2, 1.1]).as_matrix()
    moved = _transform(gt, rot, np.array([2.0, -1.0, 0.5]))
    # a rigid motion of the whole trajectory is absorbed by SE(3) alignment
    res = compute_ate(moved, gt, align="se3")
    assert res.rmse < 1e-9 and res.n_matched == len(gt)
    np.testing.assert_allclose(res.rotation, rot.T, atol=1e-9)
    # without alignment a constant offset d gives exactly |d| everywhere
    shifted = _transform(gt, np.eye(3), np.array([0.03, 0.04, 0.0]))
    res = compute_ate(shifted, gt, align="none")
    assert abs(res.rmse - 0.05) < 1e-12 and abs(res.max - 0.05) < 1e-12
    # sim3 recovers a known scale exactly
    scaled = _transform(gt, rot, np.array([1.0, 2.0, 3.0]), scale=0.37)
    res = compute_ate(scaled, gt, align="sim3")
    assert res.rmse < 1e-9 and abs(res.scale - 1 / 0.37) < 1e-9


def test_ate_analytic_noise_matches_independent_umeyama() -> None:
    gt = _loop(300)
    rng = np.random.default_rng(3)
    noise = rng.normal(0, 0.01, (len(gt), 3))
    rot = Rotation.from_rotvec([0.1, 0.7, -0.4]).as_matrix()
    est = _transform(gt, rot, np.array([0.5, 0.1, -2.0]), noise=noise)
    res = compute_ate(est, gt, align="se3")
    # independent closed-form Umeyama (Kabsch) on the positions, float64
    x, y = est.positions, gt.positions
    mx, my = x.mean(0), y.mean(0)
    u, _, vt = np.linalg.svd((y - my).T @ (x - mx))
    sign = np.diag([1, 1, np.sign(np.linalg.det(u @ vt))])
    r = u @ sign @ vt
    aligned = (x - mx) @ r.T + my
    expected = np.sqrt(np.mean(np.sum((aligned - y) ** 2, axis=1)))
    assert abs(res.rmse - expected) < 1e-12
    # alignment can only absorb part of the noise: close to, and not above, the noise RMSE
    noise_rmse = np.sqrt(np.mean(np.sum(noise**2, axis=1)))
    assert 0.97 * noise_rmse < res.rmse <= noise_rmse


def test_ate_bad_inputs(tmp_path: Path) -> None:
    gt = _loop(50)
    with pytest.raises(ConfigError, match="unknown alignment"):
        compute_ate(gt, gt, align="affine")  # type: ignore[arg-type]  # the runtime check
    few = Trajectory(gt.timestamps[:2], gt.poses[:2])
    with pytest.raises(InputError, match="holds 2 poses, at least 3 needed"):
        compute_ate(few, gt, est_name="est.txt")
    late = Trajectory(gt.timestamps + 100.0, gt.poses)
    with pytest.raises(InputError, match="no timestamp overlap"):
        compute_ate(late, gt, est_name="est.txt")
    partial = Trajectory(np.concatenate([gt.timestamps[:2], gt.timestamps[2:] + 100]), gt.poses)
    with pytest.raises(InputError, match="only 2 poses match"):
        compute_ate(partial, gt, est_name="est.txt")
    nan = gt.poses.copy()
    nan[7, 0, 3] = np.nan
    with pytest.raises(InputError, match="NaN or infinite value in pose 7"):
        compute_ate(Trajectory(gt.timestamps, nan), gt, est_name="est.txt")
    # the same NaN in a file is caught by the reader, naming the file
    path = tmp_path / "est.txt"
    write_tum(path, gt.timestamps, gt.poses)
    lines = path.read_text().splitlines()
    lines[5] = lines[5].rsplit(" ", 1)[0] + " nan"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=r"est\.txt: NaN"):
        ate_from_files(path, path)
    # a camera that never moves cannot be aligned: evo's degenerate case is reported
    still = Trajectory(np.arange(10) / 30.0,
                       pose_from_tq(np.zeros((10, 3)), np.tile([0, 0, 0, 1.0], (10, 1))))
    with pytest.raises(InputError, match="est.txt: cannot align to ground truth: Degenerate"):
        compute_ate(still, still, est_name="est.txt")
