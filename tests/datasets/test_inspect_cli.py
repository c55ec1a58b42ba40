"""`egs-bench info` / `egs-bench show` and the blur measures behind them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from egs_bench.cli import main
from egs_bench.datasets.inspect import blur_extent_px, event_map_image, sequence_summary
from egs_bench.datasets.sequence import Sequence
from tests.helpers.cli import assert_cli_error


def test_summary_values(tiny_sequence: Path) -> None:
    seq = Sequence.open(tiny_sequence)
    summary = sequence_summary(seq)
    assert summary["frames"] == 4 and summary["resolution"] == "64x48"
    assert summary["events"] == len(seq.events)
    # plane at 2 m, camera at 0.5 m/s, 15 ms exposure, fx = 57.6 px
    expected_px = 0.5 * 0.015 * 57.6 / 2.0
    extent = blur_extent_px(seq, 1)
    assert extent is not None and abs(extent - expected_px) < 0.01
    assert summary["sharpness_ratio_mean"] < 1.0


def test_event_map_colours() -> None:
    img = event_map_image(np.array([[3, 0, -3]]))
    assert tuple(img[0, 0]) == (255, 0, 0)
    assert tuple(img[0, 1]) == (255, 255, 255)
    assert tuple(img[0, 2]) == (0, 0, 255)


def test_info_and_show_commands(tiny_sequence: Path, tmp_path: Path,
                                capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["info", str(tiny_sequence)]) == 0
    assert "events" in capsys.readouterr().out
    out = tmp_path / "panel.png"
    assert main(["show", str(tiny_sequence), "--frame", "1", "--out", str(out)]) == 0
    with Image.open(out) as img:
        assert img.size[0] > 300
    code = main(["show", str(tiny_sequence), "--frame", "9", "--out", str(out)])
    assert_cli_error(code, capsys.readouterr().err, 2, "--frame", "out of range")
    code = main(["show", str(tiny_sequence), "--frame", "2", "--out", str(out)])
    assert_cli_error(code, capsys.readouterr().err, 2, f"{out}: already exists; pass --overwrite")
    before = out.read_bytes()
    assert main(["show", str(tiny_sequence), "--frame", "2", "--out", str(out),
                 "--overwrite"]) == 0
    assert out.read_bytes() != before  # frame 2's panel replaced frame 1's


def test_info_bad_path_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["info", str(tmp_path / "missing")])  # a data error, not a usage error
    assert_cli_error(code, capsys.readouterr().err, 3,
                     f"{tmp_path / 'missing'}: no such sequence folder")
