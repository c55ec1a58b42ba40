"""CLI commands of the render area."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch

from egs_bench.geometry import Intrinsics
from egs_bench.images import read_ldr_image
from egs_bench.render import GaussianMap
from egs_bench.render.ply import save_ply
from tests.helpers.cli import assert_cli_error, run_cli


@pytest.fixture
def plane_ply(tmp_path: Path) -> Path:
    intr = Intrinsics(30.0, 30.0, 16, 12, 32, 24)
    gmap = GaussianMap.empty()
    gmap.add_from_depth(np.full((24, 32, 3), 0.5, np.float32), np.full((24, 32), 2.0, np.float32),
                        intr, np.eye(4), downsample=2, point_size=1.0,
                        generator=torch.Generator().manual_seed(0))
    ply = tmp_path / "m.ply"
    save_ply(gmap, ply)
    return ply


def test_render_map_writes_png(tmp_path: Path, plane_ply: Path, capsys: pytest.CaptureFixture[str]
                               ) -> None:
    out = tmp_path / "v.png"
    code, _, err = run_cli(capsys, "render-map", plane_ply, "-o", out, "--width", "48",
                           "--height", "32", "--pose", "0 0 0 0 0 0 1")
    assert code == 0, err
    img = read_ldr_image(out)
    assert img.shape == (32, 48, 3) and img[16, 24].max() > 100  # the grey plane is in view


@pytest.mark.parametrize("argv,code,message", [
    (["{tmp}/none.ply"], 3, "none.ply: no such file"),
    (["{ply}", "--pose", "1 2 3"], 2, "--pose needs 7 numbers 'tx ty tz qx qy qz qw', got '1 2 3'"),
    (["{ply}", "--pose", "0 0 0 0 0 0 0"], 2, "non-zero quaternion"),
    (["{ply}", "--backend", "cuda-magic"], 2,
     "'--backend': Value error, 'cuda-magic' is not one of 'auto', 'numba', 'gsplat'"),
])
def test_render_map_reports_bad_input_in_one_line(tmp_path: Path, plane_ply: Path,
                                                  capsys: pytest.CaptureFixture[str],
                                                  argv: list[Any], code: int, message: str) -> None:
    out = tmp_path / "v.png"
    argv = [a.replace("{tmp}", str(tmp_path)).replace("{ply}", str(plane_ply)) for a in argv]
    got, _, err = run_cli(capsys, "render-map", *argv, "-o", out)
    assert_cli_error(got, err, code, message)
    assert not out.exists()
