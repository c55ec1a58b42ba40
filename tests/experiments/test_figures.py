"""Comparison figures: several trajectories with the ground truth, a qualitative grid with
zoomed crops and per-image PSNR (checked against an independent computation), file formats."""

from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest

from egs_bench.cli import main
from egs_bench.datasets.sequence import Sequence
from egs_bench.errors import ConfigError, InputError
from egs_bench.eval.evaluate import compute_run_ate
from egs_bench.eval.figures import (
    CROP_COLORS,
    Panel,
    crop_strip,
    plot_comparison_grid,
    qualitative_figure,
    trajectory_figure,
)
from egs_bench.eval.image_metrics import psnr_masked
from egs_bench.eval.protocols import get_protocol
from egs_bench.runs.folder import RunFolder
from tests.helpers.cli import assert_cli_error
from tests.helpers.sweep_fixtures import BAD, GOOD, make_sequence


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> tuple[Sequence, RunFolder, RunFolder]:
    root = tmp_path_factory.mktemp("fig")
    seq = Sequence.open(make_sequence(root / "data", "sa", 8, 0))
    good = GOOD.run(seq, root / "runs/good", seed=0)
    bad = BAD.run(seq, root / "runs/bad", seed=0)
    return seq, good, bad


def test_trajectory_figure_lists_every_method_and_the_ground_truth(
        runs: tuple[Sequence, RunFolder, RunFolder], tmp_path: Path
) -> None:
    seq, good, bad = runs
    svg = trajectory_figure([good.path, bad.path], tmp_path / "traj.svg").read_text()
    proto = get_protocol("egs")
    for run in (good, bad):
        rmse = compute_run_ate(run, proto, seq).rmse
        assert f"{run.method} (ATE {100 * rmse:.2f} cm)" in svg
    assert "ground truth" in svg
    pdf = trajectory_figure([good.path, bad.path], tmp_path / "traj.pdf", labels=["A", "B"])
    assert pdf.read_bytes().startswith(b"%PDF")
    with pytest.raises(ConfigError, match="figures are written as png, pdf, svg"):
        trajectory_figure([good.path], tmp_path / "traj.jpg")


def test_crop_strip_enlarges_pixels_exactly() -> None:
    rng = np.random.default_rng(0)
    img = rng.integers(0, 255, (32, 48, 3), dtype=np.uint8)
    strip = crop_strip(img, [(10, 5, 8, 6)])
    # one slot of 48 px: scale min(44 / 8, 12 / 6) = 2, tile 16x12 + a 2-px border, centred
    assert strip.shape == (16, 48, 3)
    x0 = (48 - 20) // 2
    expected = np.repeat(np.repeat(img[5:11, 10:18], 2, axis=0), 2, axis=1)
    np.testing.assert_array_equal(strip[2:14, x0 + 2:x0 + 18], expected)
    red = np.array([0xE4, 0x1A, 0x1C], np.uint8)
    assert CROP_COLORS[0] == "#e41a1c" and (strip[0, x0] == red).all()


def test_comparison_grid_psnr_and_crops(runs: tuple[Sequence, RunFolder, RunFolder], tmp_path: Path
                                        ) -> None:
    seq, good, bad = runs
    svg = qualitative_figure([good.path, bad.path], tmp_path / "grid.svg", frames=[0, 5],
                             crops=[(4, 4, 12, 8), (30, 20, 10, 8)]).read_text()
    for f in (0, 5):
        for run in (good, bad):
            sharp = seq.sharp(f)
            assert sharp is not None
            value = psnr_masked(run.read_render(f), sharp)
            assert f"PSNR {value:.2f} dB" in svg
        assert f"frame {f}" in svg
    assert svg.count("PSNR") == 2 * 3  # observed + 2 methods per row; the reference has none
    sharp0 = seq.sharp(0)
    assert sharp0 is not None
    png = plot_comparison_grid([[Panel("a", seq.rgb(0)), Panel("ref", sharp0)]],
                               tmp_path / "grid.png", crops=[(4, 4, 12, 8)])
    img = iio.imread(png)
    red = (img[..., 0] > 200) & (img[..., 1] < 60) & (img[..., 2] < 60)
    assert red.sum() > 20  # the rectangle and the crop border are drawn
    with pytest.raises(ConfigError, match="outside the 48x32 image"):
        plot_comparison_grid([[Panel("a", seq.rgb(0))]], tmp_path / "x.png",
                             crops=[(40, 0, 12, 8)])
    with pytest.raises(InputError, match="outside the sequence"):
        qualitative_figure([good.path], tmp_path / "x.png", frames=[99])


def test_figure_cli(runs: tuple[Sequence, RunFolder, RunFolder], tmp_path: Path,
                    capsys: pytest.CaptureFixture[str]) -> None:
    _, good, bad = runs
    out = tmp_path / "q.pdf"
    assert main(["figure", "qualitative", str(good.path), str(bad.path), "-o", str(out),
                 "--frames", "0,5", "--crop", "4,4,12,8"]) == 0
    assert out.read_bytes().startswith(b"%PDF")
    code = main(["figure", "qualitative", str(good.path), "-o", str(out)])
    assert_cli_error(code, capsys.readouterr().err, 2, f"{out}: already exists")
    code = main(["figure", "trajectories", str(good.path), "-o", str(tmp_path)])
    assert_cli_error(code, capsys.readouterr().err, 2, f"{tmp_path}: ", "is a folder")
    code = main(["figure", "histogram", str(good.path), "-o", str(tmp_path / "h.pdf")])
    assert_cli_error(code, capsys.readouterr().err, 2, "histogram")
    code = main(["figure", "qualitative", str(good.path), "-o", str(tmp_path / "c.pdf"),
                 "--crop", "1,2,3"])
    assert_cli_error(code, capsys.readouterr().err, 2, "--crop must be x,y,w,h")


def test_detail_crops_find_the_textured_regions_without_overlap() -> None:
    from egs_bench.eval.figures import detail_crops

    rng = np.random.default_rng(0)
    img = np.full((64, 100, 3), 128, np.uint8)
    img[40:56, 70:90] = rng.integers(0, 255, (16, 20, 3))  # strongest texture
    img[5:15, 5:25] = rng.integers(90, 170, (10, 20, 3))   # weaker texture
    crops = detail_crops(img, n=2, size=(20, 16))
    (x0, y0, w, h), (x1, y1, _, _) = crops
    assert (w, h) == (20, 16)
    assert abs(x0 - 70) <= 2 and abs(y0 - 40) <= 2
    assert x1 < 30 and y1 < 20  # the second box goes to the other textured patch
    assert x1 + w <= x0 or x0 + w <= x1 or y1 + h <= y0 or y0 + h <= y1  # no overlap
