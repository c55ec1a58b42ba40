"""Resize + centre-crop: intrinsics stay consistent with the image *content* (not just formulas).

Dots are drawn into a 1200x680 Replica-layout frame at the projection of known 3-D points using
Replica's own convention (pixel centre at the integer index, cx = 599.5), written to disk, read
back through the reader and the EventReplica source (sRGB decode, resize to 459x260, crop to
448x256). The dots' measured centroids must sit where the output intrinsics project the points.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from egs_bench.color import linear_to_srgb
from egs_bench.datasets.eventreplica import ReplicaSource, ResizeCrop
from egs_bench.datasets.replica import export_replica_layout, read_replica
from egs_bench.errors import ConfigError
from egs_bench.geometry import Intrinsics

# Replica camera, Replica convention: u = 600 X / Z + 599.5 with pixel i centred at i.
REP_F, REP_CX, REP_CY, REP_W, REP_H = 600.0, 599.5, 339.5, 1200, 680
SIGMA = 5.0  # dot radius (px, original resolution)


def _points() -> np.ndarray:
    """Camera-frame 3-D points spread over the frame, including near the crop borders."""
    uv = np.array([[600.3, 340.1], [40.7, 30.2], [1160.2, 650.6], [1150.9, 35.35],
                   [47.1, 640.8], [333.33, 222.22], [901.5, 505.5]])
    z = np.array([1.0, 2.5, 0.7, 3.3, 1.9, 4.0, 1.2])
    x = (uv[:, 0] - REP_CX) / REP_F * z
    y = (uv[:, 1] - REP_CY) / REP_F * z
    return np.stack([x, y, z], axis=1)


def _dot_frame(points: np.ndarray) -> np.ndarray:
    """uint8 sRGB frame whose *linear* intensity is a sum of Gaussian dots (Replica convention)."""
    cols = np.arange(REP_W)[None, :]
    rows = np.arange(REP_H)[:, None]
    img = np.zeros((REP_H, REP_W))
    for x, y, z in points:
        u = REP_F * x / z + REP_CX
        v = REP_F * y / z + REP_CY
        img += np.exp(-((cols - u) ** 2 + (rows - v) ** 2) / (2 * SIGMA**2))
    srgb = linear_to_srgb(np.clip(img, 0, 1))
    return np.repeat(np.round(srgb * 255).astype(np.uint8)[..., None], 3, axis=2)


def _centroid(img: np.ndarray, u: float, v: float, radius: int = 7) -> tuple[float, float]:
    """Intensity centroid in our convention (pixel i centred at i + 0.5) near (u, v)."""
    x0, y0 = int(u) - radius, int(v) - radius
    patch = img[max(y0, 0) : y0 + 2 * radius + 1, max(x0, 0) : x0 + 2 * radius + 1]
    rows, cols = np.mgrid[0 : patch.shape[0], 0 : patch.shape[1]]
    w = patch.sum()
    return (float((patch * (cols + max(x0, 0) + 0.5)).sum() / w),
            float((patch * (rows + max(y0, 0) + 0.5)).sum() / w))


def test_points_project_onto_their_dots_after_resize_and_crop(tmp_path: Path) -> None:
    points = _points()
    frame = _dot_frame(points)
    depth = np.ones((REP_H, REP_W), np.float32)
    export_replica_layout([frame, frame], [depth, depth], [np.eye(4)] * 2, tmp_path / "dots",
                          image_format="png")
    source = ReplicaSource(read_replica(tmp_path / "dots"), fps=30.0)
    intr = source.intrinsics
    assert (intr.width, intr.height) == (448, 256)
    out = source.key_frame(0).rgb[..., 1].astype(np.float64)
    # before: the dots sit where the reader's intrinsics (our convention) project the points
    src_intr = source.scene.intrinsics
    orig = source.scene.rgb(0)[..., 1].astype(np.float64) / 255.0
    lin = np.where(orig <= 0.04045, orig / 12.92, ((orig + 0.055) / 1.055) ** 2.4)
    for (u, v), (mu, mv) in zip(src_intr.project(points),
                                (_centroid(lin, cu, cv, radius=18)
                                 for cu, cv in src_intr.project(points)),
                                strict=True):
        assert abs(mu - u) < 0.05 and abs(mv - v) < 0.05
    # after: the same points land on the same content in the resized + cropped image
    checked = 0
    for u, v in intr.project(points):
        if not (8 <= u < intr.width - 8 and 8 <= v < intr.height - 8):
            continue
        mu, mv = _centroid(out, u, v)
        assert abs(mu - u) < 0.05, (u, mu)
        assert abs(mv - v) < 0.05, (v, mv)
        checked += 1
    assert checked >= 5


def test_output_intrinsics_values() -> None:
    src = Intrinsics(600.0, 600.0, 600.0, 340.0, 1200, 680)
    out = ResizeCrop().intrinsics(src)
    sx, sy = 459 / 1200, 260 / 680
    # resize scales corner-origin coordinates; the crop offset is ((459-448)//2, (260-256)//2)
    assert out.fx == pytest.approx(600 * sx) and out.fy == pytest.approx(600 * sy)
    assert out.cx == pytest.approx(600 * sx - 5) and out.cy == pytest.approx(340 * sy - 2)


def test_depth_resampled_at_output_pixel_centres() -> None:
    """Depth = nearest source pixel to each output pixel centre: a ramp tells which one."""
    src = Intrinsics(600.0, 600.0, 600.0, 340.0, 1200, 680)
    rows, cols = np.mgrid[0:680, 0:1200]
    ramp = (1.0 + cols * 1e-3 + rows * 1e-6).astype(np.float64)  # encodes the source pixel
    out = ResizeCrop().depth(ramp, src)
    assert out.shape == (256, 448) and out.dtype == np.float32
    # output pixel (i, j) centre -> resized coordinate (j + 5 + 0.5) -> source (..) * 1200 / 459
    col_src = np.floor((np.arange(448) + 5 + 0.5) * 1200 / 459)
    row_src = np.floor((np.arange(256) + 2 + 0.5) * 680 / 260)
    expected = 1.0 + col_src[None, :] * 1e-3 + row_src[:, None] * 1e-6
    np.testing.assert_allclose(out, expected, rtol=0, atol=2e-7)
    # depth is never blended: every output value is some input value (no flying pixels)
    step = np.where(cols < 600, 1.0, 3.0).astype(np.float32)
    assert set(np.unique(ResizeCrop().depth(step, src))) <= {1.0, 3.0}


def test_crop_only_keeps_pixels(tmp_path: Path) -> None:
    src = Intrinsics(100.0, 100.0, 60.0, 36.0, 120, 72)
    rng = np.random.default_rng(0)
    img = rng.random((72, 120, 3)).astype(np.float32)
    geo = ResizeCrop(width=112, height=64, resize=None)
    np.testing.assert_array_equal(geo.rgb(img, src), img[4:68, 4:116])
    assert geo.intrinsics(src) == Intrinsics(100.0, 100.0, 56.0, 32.0, 112, 64)


def test_bad_geometry_config() -> None:
    with pytest.raises(ConfigError, match="smaller than the crop"):
        ResizeCrop(width=448, height=256, resize=(400, 260))
    with pytest.raises(ConfigError, match="larger than image"):
        ResizeCrop(width=200, height=100, resize=None).intrinsics(
            Intrinsics(100.0, 100.0, 50.0, 25.0, 100, 50))


def test_auto_resize_keeps_the_aspect_ratio_except_the_papers_replica_size() -> None:
    from egs_bench.datasets.eventreplica.resize import auto_resize

    assert auto_resize(1200, 680, 448, 256) == (459, 260)  # the paper's EventReplica setting
    assert auto_resize(640, 480, 448, 256) == (448, 336)  # 7-Scenes / TUM: one scale factor
    assert auto_resize(1200, 680, 224, 128) == (226, 128)  # other crops: cover, keep the ratio
    kinect = Intrinsics(525.0, 525.0, 320.0, 240.0, 640, 480)
    out = ResizeCrop().intrinsics(kinect)  # the default rule is "auto"
    assert (out.width, out.height) == (448, 256)
    assert out.fx == out.fy == pytest.approx(525.0 * 0.7)
    assert (out.cx, out.cy) == pytest.approx((224.0, 240.0 * 0.7 - 40))
