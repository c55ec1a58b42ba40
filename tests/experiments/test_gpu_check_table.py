"""``benchmarks/gpu_check.py``'s Markdown table (the GPU campaign's table in BENCHMARKS.md)
from a check's JSON report, including runs left out by ``--until-s``."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.helpers.bench_scripts import load_script


def test_table_lists_every_run_and_the_ones_left_out() -> None:
    check = load_script("gpu_check")
    run = {"fps": 0.5, "fps_after_frame0": 0.8, "frame0_s": 12.34, "per_frame_s_median": 1.25,
           "tracking_iterations_mean": 37.5, "ate_rmse_cm": 0.875, "psnr_db": 25.125}
    report = {"environment": {"device": "NVIDIA H200", "torch": "2.11", "gsplat": "1.5.3"},
              "sequence": {"name": "office1", "resolution": "448x256", "frames_used": 40},
              "date": "2026-12-02", "runs": {
                  "egs/sequential": run,  # a report of the earlier layout: the paper preset
                  "egs/cpu/sequential": {**run, "work_per_frame_after_frame0": {
                      "pixels": 2_500_000.0}},
                  "egs/paper/concurrent": {"skipped": "past --until-s"}}}
    lines = check.markdown_table(report).splitlines()
    assert lines[0].startswith("NVIDIA H200, torch 2.11, gsplat 1.5.3; office1 448x256, first 40")
    assert lines[4] == ("| egs | paper | sequential | 0.50 | 0.80 | 12.3 | 1.25 | 37.5 | -- "
                        "| 0.88 | 25.12 |")
    assert lines[5] == ("| egs | cpu | sequential | 0.50 | 0.80 | 12.3 | 1.25 | 37.5 | 2.50 "
                        "| 0.88 | 25.12 |")
    assert lines[6].startswith("| egs | paper | concurrent | not run (past --until-s)")


def test_run_entries_name_a_preset_a_sweep_setting_and_a_mapping_mode(tmp_path: Path) -> None:
    check = load_script("gpu_check")
    levers = tmp_path / "levers.yaml"
    levers.write_text("settings:\n  lean: {mapping_iters: 50, segments: 3}\n")
    assert check.parse_run_entry("cpu", levers) == ("cpu", "cpu", "sequential", {})
    assert check.parse_run_entry("paper@lean:concurrent", levers) == (
        "paper@lean", "paper", "concurrent", {"mapping_iters": 50, "segments": 3})
    with pytest.raises(SystemExit, match="levers.yaml has no setting 'fast' \\(it has lean\\)"):
        check.parse_run_entry("paper@fast", levers)


def test_every_default_run_entry_is_a_valid_configuration() -> None:
    """The GPU campaign's default entries resolve to configurations the SLAM system accepts,
    so a renamed field fails here and not on a lent GPU."""
    from egs_bench.runs.registry import get_method, with_options

    check = load_script("gpu_check")
    for entry in check.DEFAULT_RUNS.split(","):
        _, preset, schedule, options = check.parse_run_entry(entry)
        for method in ("egs", "monogs"):
            configured = with_options(get_method(method), {**options, "mapping_mode": schedule})
            config = configured.config(preset)  # type: ignore[attr-defined]
            for key, value in options.items():
                set_in = [getattr(group, key) for group in vars(config).values()
                          if hasattr(group, key)]
                assert set_in == [value], (entry, key)
