"""Work accounting of SLAM runs (slam_stats.json's ``work``), the coarse-to-fine levels, the
insertion rule, the timing split and ``egs-bench info RUN``."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

import egs_bench.cli.data_cmds  # noqa: F401  (registers the commands)
from egs_bench.datasets.sequence import Sequence
from egs_bench.runs.folder import RunFolder
from egs_bench.slam import methods
from egs_bench.slam.levels import coarse_iterations
from egs_bench.slam.runner import RunSettings, run_slam
from tests.helpers.cli import run_cli

W, H = 64, 48  # tiny_room
# Every stage runs; a fixed tracking budget (no early stop) makes the counts exact.
BASE = dict(resolution_scale=1.0, init_iters=6, tracking_iters=8, mapping_iters=3,
            views_per_iter=2, kf_interval=2, pcd_downsample_init=2, pcd_downsample=4,
            converged_threshold=0.0, segments=3, kf_overlap=1.0,
            tracking_coarse_scale=1.0, mapping_coarse_scale=1.0)  # levels: where a test sets them
# the coarse levels render every sub-pose unless a test says otherwise
ALL_SUBPOSES = dict(tracking_coarse_segments=None, mapping_coarse_segments=None)
# frame 1 tracks with tracking_iters like every other frame
NO_PRIOR_BUDGET = dict(tracking_iters_no_prior=None)


def _run(seq_path: Path, out: Path, method: str = "egs", **options: Any
         ) -> tuple[RunFolder, dict[str, Any]]:
    seq = Sequence.open(seq_path)
    fields = {**BASE, **ALL_SUBPOSES, **NO_PRIOR_BUDGET, **options}
    cfg = methods.BUILTIN[method].config("cpu").replace(**fields)
    run = run_slam(seq, out, method_name=method, config=cfg,
                   settings=RunSettings(preset="cpu", seed=0, progress=False))
    return run, json.loads((run.path / "slam_stats.json").read_text())


@pytest.fixture(scope="module")
def plain(tiny_room: Path, tmp_path_factory: pytest.TempPathFactory
          ) -> tuple[RunFolder, dict[str, Any]]:
    return _run(tiny_room, tmp_path_factory.mktemp("work") / "plain")


def test_tracking_counts_follow_the_iterations(plain: tuple[RunFolder, dict[str, Any]]) -> None:
    _, stats = plain
    per_frame = stats["work"]["per_frame"]
    assert len(per_frame) == stats["frames"]
    assert set(per_frame[0]) <= {"init", "selection"}  # frame 0 builds the map
    assert per_frame[0]["init"]["cameras"] == BASE["init_iters"] * (BASE["segments"] + 1)
    for i in range(1, stats["frames"]):
        tracking = per_frame[i]["tracking"]
        iters = stats["tracking_iterations"][i]
        assert iters == BASE["tracking_iters"]
        assert tracking["calls"] == iters
        assert tracking["cameras"] == iters * (BASE["segments"] + 1)  # K + 1 sub-poses
        assert tracking["pixels"] == tracking["cameras"] * W * H
        assert tracking["blends_fwd"] == tracking["blends_bwd"] > 0  # every render differentiated
        assert per_frame[i]["selection"]["blends_bwd"] == 0  # keyframe decisions: no backward
    mapped = [rec for rec in per_frame[1:] if "mapping" in rec]
    assert mapped, "a keyframe was mapped"
    assert all(rec["mapping"]["calls"] == BASE["mapping_iters"] for rec in mapped)


def test_totals_add_up(plain: tuple[RunFolder, dict[str, Any]]) -> None:
    _, stats = plain
    work = stats["work"]
    for key in ("cameras", "pixels", "blends_fwd"):
        by_frame = sum(rec[p][key] for rec in work["per_frame"] for p in rec)
        assert work["total"][key] == by_frame == sum(v[key] for v in work["by_phase"].values())
    later = work["per_frame"][1:]
    mean = sum(sum(rec[p]["cameras"] for p in rec) for rec in later) / len(later)
    assert work["per_frame_after_init"]["cameras"] == pytest.approx(mean)


def test_coarse_tracking_renders_its_share_at_the_coarse_level(tiny_room: Path, tmp_path: Path
                                                               ) -> None:
    _, stats = _run(tiny_room, tmp_path / "coarse", tracking_coarse_scale=0.5,
                    tracking_coarse_fraction=0.5)
    n, m = BASE["tracking_iters"], BASE["segments"] + 1
    coarse = coarse_iterations(int(n), 0.5, 0.5)
    assert coarse == 4
    for rec in stats["work"]["per_frame"][1:]:
        assert rec["tracking"]["cameras"] == n * m
        assert rec["tracking"]["pixels"] == m * (coarse * (W // 2) * (H // 2)
                                                 + (n - coarse) * W * H)


def test_coarse_mapping_renders_its_share_at_the_coarse_level(tiny_room: Path, tmp_path: Path
                                                              ) -> None:
    _, stats = _run(tiny_room, tmp_path / "coarse_map", mapping_coarse_scale=0.5,
                    mapping_coarse_fraction=0.5)
    m, init = BASE["segments"] + 1, BASE["init_iters"]
    coarse = coarse_iterations(int(init), 0.5, 0.5)
    assert stats["work"]["per_frame"][0]["init"]["pixels"] == m * (
        coarse * (W // 2) * (H // 2) + (init - coarse) * W * H)


def test_coarse_levels_render_their_own_sub_poses(tiny_room: Path, tmp_path: Path) -> None:
    """``*_coarse_segments = 1``: the coarse iterations render the exposure's first and last
    sub-pose only, the fine ones all K + 1."""
    _, stats = _run(tiny_room, tmp_path / "coarse_k", tracking_coarse_scale=0.5,
                    tracking_coarse_fraction=0.5, tracking_coarse_segments=1,
                    mapping_coarse_scale=0.5, mapping_coarse_fraction=0.5,
                    mapping_coarse_segments=1)
    n, m = BASE["tracking_iters"], BASE["segments"] + 1
    coarse = coarse_iterations(int(n), 0.5, 0.5)
    for rec in stats["work"]["per_frame"][1:]:
        assert rec["tracking"]["cameras"] == coarse * 2 + (n - coarse) * m
        assert rec["tracking"]["pixels"] == (coarse * 2 * (W // 2) * (H // 2)
                                             + (n - coarse) * m * W * H)
    init = BASE["init_iters"]
    coarse_init = coarse_iterations(int(init), 0.5, 0.5)
    assert stats["work"]["per_frame"][0]["init"]["cameras"] == coarse_init * 2 + (
        init - coarse_init) * m


def test_uncovered_insertion_adds_fewer_gaussians(plain: tuple[RunFolder, dict[str, Any]],
                                                  tiny_room: Path, tmp_path: Path) -> None:
    _, all_stats = plain
    _, uncovered = _run(tiny_room, tmp_path / "uncovered", insertion="uncovered")
    # the same map until the first keyframe inserts
    assert uncovered["gaussians_per_frame"][0] == all_stats["gaussians_per_frame"][0]
    assert uncovered["keyframes"] >= 2 and all_stats["keyframes"] >= 2
    grown_all = all_stats["gaussians_per_frame"][-1] - all_stats["gaussians_per_frame"][0]
    grown = uncovered["gaussians_per_frame"][-1] - uncovered["gaussians_per_frame"][0]
    assert grown < grown_all


def test_timing_keeps_compilation_and_frame_zero_apart(plain: tuple[RunFolder, dict[str, Any]]
                                                       ) -> None:
    run, _ = plain
    timing = json.loads((run.path / "timing.json").read_text())
    assert timing["compile_s"] >= 0
    per_frame = timing["per_frame_s"]
    assert timing["init_s"] == per_frame[0]
    assert timing["fps_after_init"] == pytest.approx((len(per_frame) - 1) / sum(per_frame[1:]))


def test_info_shows_a_run_and_its_work(plain: tuple[RunFolder, dict[str, Any]],
                                       capsys: pytest.CaptureFixture[str]) -> None:
    from egs_bench.runs.summary import run_summary

    run, stats = plain
    summary = run_summary(run.path)
    assert summary["method"] == "egs" and summary["state"] == "done"
    mean = stats["work"]["per_frame_after_init"]
    assert f"{mean['blends_fwd'] / 1e6:.2f} M blends forward" in \
        summary["work per frame after frame 0"]
    assert "kernels" in summary["speed"] and "after frame 0" in summary["speed"]
    code, out, err = run_cli(capsys, "info", run.path)
    assert code == 0, err
    assert "work per frame" in out and "speed" in out  # the labels fit any terminal width


def test_compilation_is_not_in_the_frame_rate(tiny_room: Path, tmp_path: Path,
                                              monkeypatch: pytest.MonkeyPatch) -> None:
    """A cold kernel cache (here: a preparation that takes 2 s) shows in compile_s, not in the
    SLAM loop's time that the FPS divides by."""
    import time

    from egs_bench.render import cpu_kernels

    def slow_prepare() -> None:
        time.sleep(2.0)

    monkeypatch.setattr(cpu_kernels, "prepare_kernels", slow_prepare)
    run, _ = _run(tiny_room, tmp_path / "cold", tracking_iters=2, init_iters=2)
    timing = json.loads((run.path / "timing.json").read_text())
    assert timing["compile_s"] >= 2.0
    assert timing["total_wall_s"] - sum(timing["per_frame_s"]) < 2.0


@pytest.mark.parametrize("iterations, fraction, expected", [
    (20, 0.85, 17), (30, 0.95, 28), (3, 0.85, 2), (1, 0.9, 0), (0, 0.5, 0), (10, 0.0, 0)])
def test_coarse_iterations_always_end_at_the_fine_level(iterations: int, fraction: float,
                                                        expected: int) -> None:
    assert coarse_iterations(iterations, 0.25, fraction) == expected
    assert coarse_iterations(iterations, 1.0, fraction) == 0  # scale 1: no coarse level
