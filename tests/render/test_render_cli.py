"""CLI commands of the render area."""

from __future__ import annotations

import imageio.v3 as iio
import numpy as np
import torch
from typer.testing import CliRunner

import egs_bench.cli.render_cmds  # noqa: F401  (registers the commands)
from egs_bench.cli.app import app
from egs_bench.geometry import Intrinsics
from egs_bench.render import GaussianMap

runner = CliRunner()


def test_render_map_writes_png_and_reports_bad_input(tmp_path):
    intr = Intrinsics(30.0, 30.0, 16, 12, 32, 24)
    gmap = GaussianMap.empty()
    gmap.add_from_depth(np.full((24, 32, 3), 0.5, np.float32), np.full((24, 32), 2.0, np.float32),
                        intr, np.eye(4), downsample=2, point_size=1.0,
                        generator=torch.Generator().manual_seed(0))
    ply = tmp_path / "m.ply"
    gmap.save_ply(ply)
    out = tmp_path / "v.png"
    res = runner.invoke(app, ["render-map", str(ply), "-o", str(out), "--width", "48",
                              "--height", "32", "--pose", "0 0 0 0 0 0 1"])
    assert res.exit_code == 0, res.output
    img = iio.imread(out)
    assert img.shape == (32, 48, 3) and img[16, 24].max() > 100  # the grey plane is in view
    res = runner.invoke(app, ["render-map", str(tmp_path / "none.ply"), "-o", str(out)])
    assert res.exit_code != 0
    res = runner.invoke(app, ["render-map", str(ply), "-o", str(out), "--pose", "1 2 3"])
    assert res.exit_code != 0
