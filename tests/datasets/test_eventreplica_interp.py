"""Temporal interpolators: exact at the key frames, close to a direct render in between.

The reference is the analytic scene (``replica_testscene``) rendered directly at the
interpolated pose: a static Lambertian scene, so that render is the true in-between frame.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from egs_bench.datasets.eventreplica import (
    DepthWarpInterpolator,
    FlowInterpolator,
    KeyFrame,
    make_interpolator,
)
from egs_bench.errors import ConfigError
from egs_bench.geometry import Intrinsics, interpolate_pose
from tests.helpers import replica_testscene as scene

INTR = Intrinsics(fx=160.0, fy=160.0, cx=128.0, cy=80.0, width=256, height=160)


def _render(pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return scene.render(pose, INTR.fx, INTR.fy, INTR.cx, INTR.cy, INTR.width, INTR.height)


def _make_pair(translation: list[float]
               ) -> tuple[KeyFrame, KeyFrame, np.ndarray, np.ndarray]:
    pose_a = scene.look_pose([0.0, 0.0, 0.0])
    pose_b = scene.look_pose(translation, yaw_deg=3.0, pitch_deg=-1.5, roll_deg=1.0)
    a = KeyFrame(*_render(pose_a), pose_a)
    b = KeyFrame(*_render(pose_b), pose_b)
    mid_pose = interpolate_pose(pose_a, pose_b, 0.5)
    mid_rgb, mid_depth = _render(mid_pose)
    return a, b, mid_rgb, mid_depth


@pytest.fixture(scope="module")
def pair() -> tuple[KeyFrame, KeyFrame, np.ndarray, np.ndarray]:
    """Moderate motion: about 10 px between the key frames."""
    return _make_pair([0.10, -0.04, 0.06])


@pytest.fixture(scope="module")
def wide_pair() -> tuple[KeyFrame, KeyFrame, np.ndarray, np.ndarray]:
    """Larger translation: about 7 px of parallax between the box and the wall at mid-time."""
    return _make_pair([0.25, -0.05, 0.08])


def _psnr(x: np.ndarray, y: np.ndarray, mask: np.ndarray | None = None) -> float:
    err = (np.clip(x, 0, 1) - np.clip(y, 0, 1)) ** 2
    if mask is not None:
        err = err[mask]
    return float(10 * np.log10(1.0 / err.mean()))


@pytest.mark.parametrize("make", [DepthWarpInterpolator, FlowInterpolator], ids=["depth", "flow"])
def test_exact_at_key_frames(pair: tuple[KeyFrame, KeyFrame, np.ndarray, np.ndarray], make: Any
                             ) -> None:
    a, b, _, _ = pair
    interp = make().prepare(a, b, INTR)
    rgb0, d0 = interp(0.0)
    rgb1, d1 = interp(1.0)
    np.testing.assert_array_equal(rgb0, a.rgb)
    np.testing.assert_array_equal(d0, a.depth)
    np.testing.assert_array_equal(rgb1, b.rgb)
    np.testing.assert_array_equal(d1, b.depth)


def test_depth_warp_is_continuous_at_the_ends(
        pair: tuple[KeyFrame, KeyFrame, np.ndarray, np.ndarray]
) -> None:
    """Just inside the interval the warp (not the key-frame shortcut) already matches."""
    a, b, _, _ = pair
    interp = DepthWarpInterpolator().prepare(a, b, INTR)
    assert _psnr(interp(1e-3)[0], a.rgb) > 40.0
    assert _psnr(interp(1 - 1e-3)[0], b.rgb) > 40.0


def test_depth_warp_middle_frame_beats_naive_blending(
        pair: tuple[KeyFrame, KeyFrame, np.ndarray, np.ndarray]
) -> None:
    a, b, mid_rgb, mid_depth = pair
    naive = _psnr(0.5 * a.rgb + 0.5 * b.rgb, mid_rgb)
    rgb, depth = DepthWarpInterpolator().prepare(a, b, INTR)(0.5)
    warped = _psnr(rgb, mid_rgb)
    # measured: naive ~19 dB, depth warp ~35 dB at this resolution and motion
    assert warped > 30.0 and warped > naive + 10.0, (warped, naive)
    valid = depth > 0
    assert valid.mean() > 0.97
    rel = np.abs(depth[valid] - mid_depth[valid]) / mid_depth[valid]
    assert np.median(rel) < 1e-3 and (rel < 0.02).mean() > 0.97


def test_z_buffer_resolves_occlusions(wide_pair: tuple[KeyFrame, KeyFrame, np.ndarray, np.ndarray]
                                      ) -> None:
    """On the floating box the z-test matters: without it the wall behind bleeds through."""
    a, b, mid_rgb, mid_depth = wide_pair
    box = mid_depth < 3.0  # the box is nearer than every wall seen by this camera
    assert box.sum() > 2000
    with_z = DepthWarpInterpolator().prepare(a, b, INTR)(0.5)[0]
    without_z = DepthWarpInterpolator(rel_depth_tol=1e9).prepare(a, b, INTR)(0.5)[0]
    # measured: ~46 dB with the z-buffer, ~35 dB without (ghost of the wall on the box)
    assert _psnr(with_z, mid_rgb, box) > _psnr(without_z, mid_rgb, box) + 5.0


def test_flow_fallback_beats_naive_blending(pair: tuple[KeyFrame, KeyFrame, np.ndarray, np.ndarray]
                                            ) -> None:
    a, b, mid_rgb, mid_depth = pair
    naive = _psnr(0.5 * a.rgb + 0.5 * b.rgb, mid_rgb)
    rgb, depth = FlowInterpolator().prepare(a, b, INTR)(0.5)
    flow = _psnr(rgb, mid_rgb)
    # measured: flow ~28 dB (no occlusion reasoning; DIS on 8-bit grey)
    assert flow > naive + 5.0, (flow, naive)
    assert depth.shape == mid_depth.shape and (depth > 0).all()
    assert np.median(np.abs(depth - mid_depth) / mid_depth) < 0.05


def test_holes_without_depth_are_filled(pair: tuple[KeyFrame, KeyFrame, np.ndarray, np.ndarray]
                                        ) -> None:
    """Key frames with invalid depth (0) leave holes that are inpainted, not left black."""
    a, b, mid_rgb, _ = pair
    depth_a = a.depth.copy()
    depth_b = b.depth.copy()
    depth_a[60:80, 100:130] = 0.0
    depth_b[60:80, 100:130] = 0.0
    holed = DepthWarpInterpolator().prepare(
        KeyFrame(a.rgb, depth_a, a.pose), KeyFrame(b.rgb, depth_b, b.pose), INTR)
    rgb, depth = holed(0.5)
    assert np.isfinite(rgb).all() and (rgb >= 0).all()
    hole = depth == 0
    assert hole.sum() > 100  # the region without depth stays marked invalid
    # inpainted colour is plausible (close to the scene's local mean), not zero
    assert abs(rgb[hole].mean() - mid_rgb[hole].mean()) < 0.5 * mid_rgb[hole].mean()


def test_registry_and_errors() -> None:
    assert make_interpolator("depth").name == "depth"
    assert make_interpolator("flow").name == "flow"
    with pytest.raises(ConfigError, match="unknown interpolator 'film'"):
        make_interpolator("film")  # type: ignore[arg-type]  # the runtime check
    with pytest.raises(ConfigError, match="DIS preset"):
        FlowInterpolator(preset="slow")
