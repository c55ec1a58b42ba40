"""Sharp edges of trajectory evaluation: repeated time stamps (merged once, equal to evo on the
de-duplicated files), keyframe protocols with too few keyframes (the message names
keyframes.txt)."""

import json
from pathlib import Path

import numpy as np
import pytest

from egs_bench.cli import main
from egs_bench.errors import InputError
from egs_bench.eval.ate import compute_ate, merge_duplicate_stamps, trajectory_ate
from egs_bench.eval.evaluate import evaluate_run
from egs_bench.eval.rpe import trajectory_rpe
from egs_bench.geometry import Trajectory, read_tum, write_tum
from tests.helpers.cli import assert_cli_error
from tests.helpers.eval_fixtures import make_run

GT_NAME, EST_NAME = "freiburg1_xyz-groundtruth.txt", "freiburg1_xyz-rgbdslam.txt"


def _evo_ape(gt: Path, est: Path, align: str = "se3") -> dict:
    """evo's own API on two TUM files: read, associate, ``main_ape.ape``."""
    from evo.core import metrics, sync
    from evo.main_ape import ape
    from evo.tools import file_interface

    ref = file_interface.read_tum_trajectory_file(str(gt))
    est_t = file_interface.read_tum_trajectory_file(str(est))
    ref, est_t = sync.associate_trajectories(ref, est_t, max_diff=0.01)
    res = ape(ref, est_t, metrics.PoseRelation.translation_part, align=align != "none",
              correct_scale=align == "sim3")
    return {**res.stats, "n": est_t.num_poses}


def _doubled(src: Path, out: Path, shift_m: float = 0.5) -> Trajectory:
    """Every pose of ``src`` written twice at its stamp, the copy moved by ``shift_m`` in x;
    returns the original."""
    traj = read_tum(src)
    moved = traj.poses.copy()
    moved[:, 0, 3] += shift_m
    stamps = np.repeat(traj.timestamps, 2)
    poses = np.stack([traj.poses, moved], axis=1).reshape(-1, 4, 4)
    write_tum(out, stamps, poses)
    return traj


def test_repeated_stamps_are_scored_once_equal_to_evo_on_the_deduplicated_file(
        shared_data: Path, tmp_path: Path) -> None:
    d = shared_data / "trajectories"
    doubled, once = tmp_path / "doubled_est.txt", tmp_path / "once_est.txt"
    traj = _doubled(d / EST_NAME, doubled)
    write_tum(once, traj.timestamps, traj.poses)  # what de-duplication must leave
    ref = _evo_ape(d / GT_NAME, once)
    ours = trajectory_ate(d / GT_NAME, doubled)
    assert ours.n_matched == ref["n"] > 700  # once per stamp, not twice
    for key in ("rmse", "mean", "median", "std", "min", "max"):
        assert ours.__getattribute__(key) == pytest.approx(ref[key], rel=1e-12), key
    assert len(ours.notes) == 1
    assert f"doubled_est.txt: {len(traj)} time stamp(s) repeated" in ours.notes[0]
    assert "up to 0.500 m" in ours.notes[0]
    # RPE pairs consecutive poses: a duplicate would pair a pose with its own copy
    rpe, rpe_once = trajectory_rpe(d / GT_NAME, doubled), trajectory_rpe(d / GT_NAME, once)
    assert rpe.n_pairs == rpe_once.n_pairs == ref["n"] - 1
    assert rpe.rmse == rpe_once.rmse and rpe.notes == ours.notes


def test_repeated_stamp_in_real_ground_truth(shared_data: Path, tmp_path: Path) -> None:
    """TUM's fr2/desk ground truth repeats 1311868229.5760 with two poses 1 mm apart."""
    d = shared_data / "trajectories"
    gt = read_tum(d / "fr2_desk_groundtruth.txt")
    merged, note = merge_duplicate_stamps(gt, d / "fr2_desk_groundtruth.txt")
    assert len(merged) == len(gt) - 1 and np.all(np.diff(merged.timestamps) > 0)
    assert note is not None and note.startswith("fr2_desk_groundtruth.txt: 1 time stamp(s)")
    i = int(np.flatnonzero(np.diff(gt.timestamps) == 0)[0])
    np.testing.assert_array_equal(merged.poses[i], gt.poses[i])  # the first copy kept
    res = trajectory_ate(d / "fr2_desk_groundtruth.txt", d / "fr2_desk_ORB.txt")
    assert res.notes == (note,)
    assert merge_duplicate_stamps(merged, "x")[1] is None


def test_ate_cli_warns_about_repeated_stamps(shared_data: Path, tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    d = shared_data / "trajectories"
    doubled = tmp_path / "doubled_est.txt"
    _doubled(d / EST_NAME, doubled)
    assert main(["ate", str(d / GT_NAME), str(doubled)]) == 0
    out = capsys.readouterr().out
    matched = trajectory_ate(d / GT_NAME, d / EST_NAME).n_matched
    assert f"{matched} poses matched" in out and f"{2 * matched} poses" not in out
    assert "warning: doubled_est.txt:" in out


def test_eval_of_a_run_with_a_repeated_stamp(tmp_path: Path, eval_sequence: Path) -> None:
    run = make_run(tmp_path, eval_sequence)
    clean = evaluate_run(run.path, "egs", write=False)
    est = run.read_trajectory()
    poses = np.insert(est.poses, 5, est.poses[5], axis=0)
    poses[6, :3, 3] += 0.3  # a second, wrong pose at frame 5's stamp
    run.write_trajectory(np.insert(est.timestamps, 5, est.timestamps[5]), poses)
    dup = evaluate_run(run.path, "egs", write=False)
    assert dup["ate"]["rmse_m"] == clean["ate"]["rmse_m"]
    assert dup["ate"]["n_matched"] == clean["ate"]["n_matched"] == len(est)
    assert any(n.startswith("trajectory.txt: 1 time stamp(s) repeated") for n in dup["notes"])
    assert not any(str(tmp_path) in n for n in dup["notes"])  # metrics.json holds no paths


def test_monogs_protocol_with_too_few_keyframes_names_keyframes_file(
        tmp_path: Path, eval_sequence: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = make_run(tmp_path, eval_sequence, keyframes=(0,))
    with pytest.raises(InputError, match=r"keyframes\.txt: lists 1 keyframe\(s\); protocol "
                                         r"'monogs' evaluates ATE on keyframes") as err:
        evaluate_run(run.path, "monogs", write=False)
    assert "groundtruth" not in str(err.value)
    # the same with a trajectory-only run (the estimate is cut to the keyframes)
    code = main(["eval", str(run.path), "--protocol", "monogs"])
    assert_cli_error(code, capsys.readouterr().err, 3, run.path / "keyframes.txt",
                     "protocol 'monogs' evaluates ATE on keyframes")
    json.dumps(evaluate_run(run.path, "egs", write=False))  # the egs protocol still scores it
    assert compute_ate(run.read_trajectory(), run.read_trajectory()).rmse < 1e-9
