"""Your own RGB-D data through ``make-eventreplica --layout tum-rgbd / generic``: a frame is
never dropped or emptied silently. Out-of-order and repeated stamps are refused as the
trajectory readers refuse them, and so is a depth map the sequence could not keep (all zero,
or a ``depth_scale`` that puts every depth kilometres away), naming the file."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from egs_bench.datasets.sequence import Sequence
from egs_bench.geometry import write_tum
from egs_bench.images import write_depth_png, write_ldr_image
from tests.helpers.cli import assert_cli_error, run_cli

W, H, N = 64, 48, 4
STAMPS = [1.0 + k / 30 for k in range(N)]
CAMERA = "fx: 50.0\nfy: 50.0\ncx: 31.5\ncy: 23.5\n"


def _tum_folder(root: Path, depth_value: int = 10000) -> Path:
    """A TUM RGB-D folder: textured colour frames, flat depth (2 m at 5000 per metre), a
    short sideways path, an intrinsics yaml beside it."""
    rng = np.random.default_rng(0)
    texture = rng.integers(30, 220, (H, W + 8, 3)).astype(np.uint8)
    (root / "rgb").mkdir(parents=True)
    (root / "depth").mkdir()
    rgb_lines, depth_lines = ["# color images"], ["# depth maps"]
    for k, t in enumerate(STAMPS):
        write_ldr_image(root / "rgb" / f"{t:.6f}.png", texture[:, k:k + W].copy())
        write_depth_png(root / "depth" / f"{t:.6f}.png", np.full((H, W), depth_value, np.uint16))
        rgb_lines.append(f"{t:.6f} rgb/{t:.6f}.png")
        depth_lines.append(f"{t:.6f} depth/{t:.6f}.png")
    (root / "rgb.txt").write_text("\n".join(rgb_lines) + "\n")
    (root / "depth.txt").write_text("\n".join(depth_lines) + "\n")
    poses = np.repeat(np.eye(4)[None], N, axis=0)
    poses[:, 0, 3] = 0.01 * np.arange(N)
    write_tum(root / "groundtruth.txt", np.array(STAMPS), poses)
    (root.parent / "camera.yaml").write_text(CAMERA)
    return root


def _make(capsys: pytest.CaptureFixture[str], folder: Path, out: Path, *extra: str | Path
          ) -> tuple[int, str]:
    code, _, err = run_cli(capsys, "make-eventreplica", "--layout", "tum-rgbd", "--input",
                           folder, "--intrinsics", folder.parent / "camera.yaml", "--out", out,
                           "--width", "48", "--height", "32", "--upsample", "2",
                           "--no-progress", *extra)
    return code, err


def test_a_clean_folder_becomes_a_sequence(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                           ) -> None:
    code, err = _make(capsys, _tum_folder(tmp_path / "tum"), tmp_path / "out")
    assert code == 0, err
    assert len(Sequence.open(tmp_path / "out")) == N - 1  # the first frame starts the timeline


@pytest.mark.parametrize("edit,message", [
    (lambda lines: [lines[0], lines[1], lines[3], lines[2], lines[4]],
     "line 4: time stamp 1.033333 comes before the 1.066667 of line 3 (the list must be in "
     "time order)"),
    (lambda lines: [lines[0], lines[1], lines[2], lines[2].replace(".png", "b.png"), *lines[3:]],
     "line 4: time stamp 1.033333 of rgb/1.033333b.png is also the stamp of rgb/1.033333.png"),
], ids=["out-of-order", "repeated"])
def test_out_of_order_and_repeated_stamps_are_refused(edit: Callable[..., Any], message: str,
                                                      tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    folder = _tum_folder(tmp_path / "tum")
    lines = (folder / "rgb.txt").read_text().splitlines()
    (folder / "rgb.txt").write_text("\n".join(edit(lines)) + "\n")
    if "b.png" in message:
        (folder / "rgb" / "1.033333b.png").write_bytes((folder / "rgb" / "1.033333.png")
                                                       .read_bytes())
    code, err = _make(capsys, folder, tmp_path / "out")
    assert_cli_error(code, err, 3, f"{folder / 'rgb.txt'}: {message}")
    assert not (tmp_path / "out").exists()


def test_an_exactly_repeated_line_is_read_once(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                               ) -> None:
    folder = _tum_folder(tmp_path / "tum")
    lines = (folder / "rgb.txt").read_text().splitlines()
    (folder / "rgb.txt").write_text("\n".join([*lines[:3], lines[2], *lines[3:]]) + "\n")
    code, err = _make(capsys, folder, tmp_path / "out")
    assert code == 0, err


def test_all_zero_depth_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = _tum_folder(tmp_path / "tum", depth_value=0)
    code, err = _make(capsys, folder, tmp_path / "out")
    assert_cli_error(code, err, 3, f"{folder / 'depth' / '1.000000.png'}: holds no depth: "
                                   "every pixel is 0")
    assert not (tmp_path / "out").exists()


def test_a_depth_scale_that_puts_every_depth_out_of_range_is_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = _tum_folder(tmp_path / "tum")  # 10000 = 2 m at 5000 per metre
    (tmp_path / "camera.yaml").write_text(CAMERA + "depth_scale: 1\n")
    code, err = _make(capsys, folder, tmp_path / "out")
    assert_cli_error(code, err, 3, f"{folder / 'depth' / '1.000000.png'}: every depth is "
                                   "beyond the 13.107 m a sequence stores (10000 to 10000 m at "
                                   "depth_scale 1 per metre)", "is the depth scale right?")


def test_generic_layout_refuses_a_frame_without_depth(tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    folder = _tum_folder(tmp_path / "tum")
    write_depth_png(folder / "depth" / f"{STAMPS[2]:.6f}.png", np.zeros((H, W), np.uint16))
    (tmp_path / "generic.yaml").write_text(CAMERA + "depth_scale: 5000\n")
    code, _, err = run_cli(capsys, "make-eventreplica", "--layout", "generic", "--rgb-dir",
                           folder / "rgb", "--depth-dir", folder / "depth", "--trajectory",
                           folder / "groundtruth.txt", "--intrinsics", tmp_path / "generic.yaml",
                           "--out", tmp_path / "out", "--width", "48", "--height", "32",
                           "--upsample", "2", "--no-progress")
    assert_cli_error(code, err, 3, f"{folder / 'depth' / f'{STAMPS[2]:.6f}.png'}: holds no "
                                   "depth")
    assert not (tmp_path / "out").exists()
