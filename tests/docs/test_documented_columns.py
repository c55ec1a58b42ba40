"""The columns docs/guide/evaluation.md lists for `leaderboard --format csv` are the columns the
leaderboard writes, for the default metrics and with fps added."""

from __future__ import annotations

import re
from pathlib import Path

from egs_bench.eval.leaderboard import leaderboard
from tests.helpers.eval_fixtures import make_run, make_sequence

GUIDE = Path(__file__).resolve().parents[2] / "docs" / "guide" / "evaluation.md"


def _documented_columns() -> list[str]:
    text = " ".join(GUIDE.read_text(encoding="utf-8").split())
    match = re.search(r"`--format csv` is long-format: one row per run with `([^`]+)`", text)
    assert match, "the guide no longer describes the csv columns"
    return [c.strip() for c in match[1].split(",")]


def test_the_guide_lists_the_csv_columns_the_leaderboard_writes(tmp_path: Path) -> None:
    seq = make_sequence(tmp_path / "data")
    make_run(tmp_path / "runs", seq)
    header = leaderboard(tmp_path / "runs", fmt="csv").splitlines()[0].split(",")
    documented = _documented_columns()
    assert header == documented
    with_fps = leaderboard(tmp_path / "runs", fmt="csv",
                           metrics=["ate", "psnr", "ssim", "lpips", "fps"]).splitlines()[0]
    at = documented.index("lpips") + 1
    assert with_fps.split(",") == [*documented[:at], "fps", *documented[at:]]
