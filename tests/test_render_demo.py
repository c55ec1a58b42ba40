"""``egs-bench render-demo``'s library function: one synthetic RGB-D view as a Gaussian map,
rendered."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from egs_bench.demo import render_demo
from egs_bench.images import read_ldr_image


def test_the_render_demo_writes_input_render_depth_and_novel_view(tmp_path: Path) -> None:
    out = tmp_path / "demo.png"
    gmap = render_demo(out, width=64, height=40)
    img = read_ldr_image(out)
    assert img.shape == (40, 64 * 4 + 12, 3) and len(gmap) > 500
    # the re-render of the input view resembles the input (mean abs error of 8-bit sRGB)
    assert np.abs(img[:, :64].astype(float) - img[:, 68:132]).mean() < 25
