"""``benchmarks/gpu_cost_model.py``: the check on the committed H200 data, its failure with a
perturbed constant, the committed constants against a refit, and the work counted from a
small run folder written here."""

import dataclasses
import json
from pathlib import Path

import pytest
import yaml

from tests.helpers.bench_scripts import load_script

cm = load_script("gpu_cost_model")


def test_check_passes_on_the_committed_measurements(capsys: pytest.CaptureFixture[str]) -> None:
    assert cm.main(["--check"]) == 0
    out = capsys.readouterr().out
    assert "egs: measured 0.37 FPS" in out and "monogs: measured 1.78 FPS" in out


@pytest.mark.parametrize("constant", ["map_camera_blur_ms=3.5", "launch_ms=0.05"])
def test_a_perturbed_constant_fails_the_check(constant: str, capsys: pytest.CaptureFixture[str]
                                              ) -> None:
    assert cm.main(["--check", "--constant", constant]) == 1
    assert "OFF by more than 25 %" in capsys.readouterr().out


def test_committed_constants_are_the_fit_of_the_committed_data() -> None:
    fitted = dataclasses.astuple(cm.fit_constants())
    committed = dataclasses.astuple(cm.CostConstants())
    assert fitted == pytest.approx(committed, rel=2e-3)
    # 4 free parameters against 12 per-phase points, not 2 against the 2 FPS figures
    a, y, _ = cm.fit_points()
    assert a.shape == (12, 4) and len(y) == 12


def _write_run(folder: Path, *, log: str | None) -> None:
    folder.mkdir()
    slam = {"method": {"blur_model": True}, "mapping": {"n_random_kfs": 1, "refine_iters": 7},
            "budget": {"segments": 2, "window_size": 3, "views_per_iter": None,
                       "init_iters": 40, "mapping_iters": 10, "tracking_iters": 5}}
    (folder / "config.yaml").write_text(yaml.safe_dump({"method": "egs", "slam": slam}))
    # frame 0's entry is the map initialisation's iteration count
    (folder / "slam_stats.json").write_text(json.dumps(
        {"tracking_iterations": [40] + [5, 3, 4, 5, 2, 5, 5, 1, 5, 5, 5, 5]}))
    (folder / "keyframes.txt").write_text("0\n3\n6\n9\n12\n")
    if log is not None:
        (folder / "log.txt").write_text(log)


def test_work_counted_from_a_run_folder(tmp_path: Path) -> None:
    _write_run(tmp_path / "run", log="frame 3: keyframe\nframe 9: keyframe; window -[3]\n")
    s = cm.schedule_from_run(tmp_path / "run")
    assert s.family == "blur" and s.cameras_per_view == 3 and s.frames == 13
    assert s.tracking_iters == (5, 3, 4, 5, 2, 5, 5, 1, 5, 5, 5, 5)
    # windows 2, 3, 3 (one removed at frame 9, then 4 > window_size 3) plus a random older
    # keyframe once one lies outside the window: views 2, 3, 4, 4, x 3 cameras each
    assert s.mapping_cameras == (6, 9, 12, 12)
    assert (s.init_iters, s.mapping_iters, s.refine_iters) == (40, 10, 7)
    assert not s.concurrent

    c = cm.CostConstants(launch_ms=0.0, track_camera_ms=1.0, map_camera_blur_ms=2.0,
                         map_camera_plain_ms=99.0)
    p = cm.predict(s, c)
    assert p.init_s == pytest.approx(40 * 3 * 2.0 / 1e3)
    assert p.tracking_s == pytest.approx(50 * 3 * 1.0 / 1e3)
    assert p.mapping_s == pytest.approx((10 * (6 + 9 + 12 + 12) + 7 * 3) * 2.0 / 1e3)
    assert p.total_s == pytest.approx(p.init_s + p.tracking_s + p.mapping_s)
    overlapped = cm.predict(s.replace(concurrent=True), c)
    assert overlapped.total_s == pytest.approx(p.init_s + max(p.tracking_s, p.mapping_s))
    assert cm.converged(s, 2.5).tracking_iters.count(3) == 6  # 30 iterations over 12 frames


def test_without_a_log_the_window_is_at_its_largest(tmp_path: Path) -> None:
    _write_run(tmp_path / "run", log=None)
    assert cm.schedule_from_run(tmp_path / "run").mapping_cameras == (6, 9, 12, 12)


def test_a_run_folder_without_stats_is_one_line_naming_the_file(tmp_path: Path,
                                                                capsys: pytest.CaptureFixture[str]
                                                                ) -> None:
    _write_run(tmp_path / "run", log=None)
    (tmp_path / "run" / "slam_stats.json").unlink()
    assert cm.main(["--run", str(tmp_path / "run")]) == 3
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "slam_stats.json" in err[0] and "not found" in err[0]


def test_a_bad_constant_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    assert cm.main(["--check", "--constant", "nope=1"]) == 2
    assert "--constant" in capsys.readouterr().err


def test_level_share_follows_the_budget() -> None:
    assert cm.level_share({}, "tracking") == 1.0
    assert cm.level_share({"resolution_scale": 0.5}, "mapping") == pytest.approx(0.25)
    coarse = {"resolution_scale": 1.0, "tracking_coarse_scale": 0.25,
              "tracking_coarse_fraction": 0.75}
    assert cm.level_share(coarse, "tracking") == pytest.approx(0.75 / 16 + 0.25)
    assert cm.level_share(coarse, "mapping") == 1.0  # the other phase's levels do not count


def test_coarse_levels_with_fewer_sub_poses_count_fewer_cameras() -> None:
    """K = 3 with 3 in 4 tracking iterations at 1/4 rendering Kc = 1 (2 sub-poses): cameras
    per view 0.75 x 2 + 0.25 x 4 = 2.5; pixels per camera (1.5 / 16 + 1) / 2.5."""
    budget = {"tracking_coarse_scale": 0.25, "tracking_coarse_fraction": 0.75,
              "tracking_coarse_segments": 1}
    assert cm.level_cameras(budget, "tracking", 3) == pytest.approx(2.5)
    assert cm.level_share(budget, "tracking", 3) == pytest.approx((1.5 / 16 + 1.0) / 2.5)
    assert cm.level_cameras(budget, "mapping", 3) == 4.0  # the other phase keeps K + 1
    assert cm.level_cameras({**budget, "tracking_coarse_segments": 9}, "tracking", 3) == 4.0
    # total pixels per view and iteration are the sum over the levels
    total = cm.level_cameras(budget, "tracking", 3) * cm.level_share(budget, "tracking", 3)
    assert total == pytest.approx(0.75 * 2 / 16 + 0.25 * 4)


def test_pixel_scalings_bracket_a_reduced_resolution() -> None:
    s = cm.paper_scale("egs", 25)
    small = s.replace(tracking_pixel_share=0.25, mapping_pixel_share=0.25)
    full = cm.predict(s).fps
    assert cm.predict(small, scaling="cameras").fps == pytest.approx(full)
    fast = cm.predict(small, scaling="pixels").fps
    assert fast > 2 * full  # most of egs's time is per-camera rendering
    with pytest.raises(cm.ConfigError):
        cm.predict(small, scaling="tiles")


def test_presets_table_labels_predictions(capsys: pytest.CaptureFixture[str]) -> None:
    assert cm.main(["--presets"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("| prediction") and "| egs, cpu | 300 |" in out
