"""Generation pipeline: blur, sharp GT, depth, events and the adaptive sampling rule, checked
against direct renders of the latent source (independent of the pipeline's sample grid)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from egs_bench.color import LdrResponse, linear_to_srgb, srgb_to_linear
from egs_bench.datasets.esim import log_luma
from egs_bench.datasets.pipeline import SamplingConfig, generate_sequence, max_flow_px
from egs_bench.datasets.sequence import Sequence
from egs_bench.errors import ConfigError, OutputError
from tests.helpers.plane_scene import PlaneSource, make_plane_sequence


def test_blur_sharp_depth_against_direct_renders(tmp_path: Path) -> None:
    # the test plane is not anti-aliased, so its pixels are far from linear in time over a
    # 1 px step; a fine sampling isolates the check of the blur integral itself
    source = PlaneSource()
    t_end = np.array([20_000, 53_333])
    out = generate_sequence(source, t_end - 15_000, t_end, tmp_path / "fine",
                            sampling=SamplingConfig(max_flow_px=0.02), progress=False)
    seq = Sequence.open(out)
    response = LdrResponse.from_dict(seq.meta["crf"])
    for i in (0, 1):
        t0, t1 = seq.exposure(i)
        # independent reference: mean of 400 uniform latent renders over the exposure
        times = np.linspace(t0, t1, 400).astype(np.int64)
        mean_rgb = np.mean([source.render(int(t)).rgb for t in times], axis=0)
        expected = response.to_ldr(mean_rgb).astype(int)
        diff = np.abs(seq.rgb(i).astype(int) - expected)
        # the pipeline integrates on its adaptive sample grid (trapezoid rule); where a pixel's
        # radiance is far from linear in time over one step, a few pixels may differ by 2-3 DN
        assert diff.mean() < 0.1, diff.mean()
        assert (diff <= 1).mean() > 0.995
        assert diff.max() <= 4
        np.testing.assert_array_equal(seq.sharp(i), response.to_ldr(source.render(t1).rgb))
        np.testing.assert_allclose(seq.depth(i), source.render(t1).depth, atol=1 / 5000)
        np.testing.assert_allclose(seq.poses[i], source.pose(t1), atol=1e-8)
    # the observed frame is blurred: it differs from the sharp one
    sharp1 = seq.sharp(1)
    assert sharp1 is not None
    assert np.abs(seq.rgb(1).astype(int) - sharp1.astype(int)).mean() > 1.0


def test_events_track_log_change(tiny_sequence: Path) -> None:
    """Sum of polarities * theta follows log(B + eps) within one threshold at every pixel."""
    seq = Sequence.open(tiny_sequence)
    source = PlaneSource()
    t_first, t_last = int(seq.t_start_us[0]), int(seq.t_end_us[-1])
    change = log_luma(source.render(t_last).rgb, seq.eps) - log_luma(
        source.render(t_first).rgb, seq.eps)
    counts = seq.events.event_maps(np.array([t_first, t_last]))[0]
    err = counts * seq.pos_threshold - change
    assert np.abs(err).max() < seq.pos_threshold + 1e-9
    assert np.abs(counts).max() >= 2


def test_adaptive_sampling_bounds_flow(tmp_path: Path) -> None:
    """A fast camera: consecutive latent samples move the image by at most max_flow_px."""
    fast = PlaneSource(speed_mps=20.0)
    out = generate_sequence(fast, np.array([0]), np.array([10_000]), tmp_path / "fast",
                            sampling=SamplingConfig(max_flow_px=0.5),
                            progress=False)
    seq = Sequence.open(out)
    dense = seq.dense_trajectory
    assert dense is not None
    step_px = np.abs(np.diff(dense.positions[:, 0])) * fast.intrinsics.fx / fast.distance
    assert step_px.max() <= 0.5 + 1e-6
    total_px = 20.0 * 0.01 * fast.intrinsics.fx / fast.distance
    assert len(dense) - 1 >= total_px / 0.5
    assert seq.meta["sampling"]["num_samples"] == len(dense)


def test_log_step_refinement_bisects(tmp_path: Path) -> None:
    """With a log-change bound, steps are halved until the bound (or the bisection cap) holds."""
    source = PlaneSource(speed_mps=5.0)
    sampling = SamplingConfig(max_flow_px=4.0, max_log_step=0.2, max_bisections=3)
    out = generate_sequence(source, np.array([0]), np.array([10_000]), tmp_path / "log",
                            sampling=sampling, progress=False)
    dense = Sequence.open(out).dense_trajectory
    assert dense is not None
    times = dense.timestamps
    coarse_steps = int(np.ceil(5.0 * 0.01 * source.intrinsics.fx / source.distance / 4.0))
    assert len(times) - 1 > coarse_steps  # refinement added samples
    for t0, t1 in zip(times[:-1], times[1:], strict=True):
        change = np.abs(log_luma(source.render(round(t1 * 1e6)).rgb, 1e-3)
                        - log_luma(source.render(round(t0 * 1e6)).rgb, 1e-3))
        step_is_minimal = (t1 - t0) * 1e6 <= 10_000 / coarse_steps / 2**3 + 1
        assert np.percentile(change, 99) <= 0.2 or step_is_minimal


def test_fixed_steps(tmp_path: Path) -> None:
    out = generate_sequence(PlaneSource(), np.array([0]), np.array([9_000]), tmp_path / "f",
                            sampling=SamplingConfig(fixed_step_us=1000), progress=False)
    dense = Sequence.open(out).dense_trajectory
    assert dense is not None and len(dense) == 10


def test_max_flow_px_pure_translation() -> None:
    source = PlaneSource()
    a, b = source.render(0), source.render(100_000)
    expected = 0.5 * 0.1 * source.intrinsics.fx / source.distance
    assert max_flow_px(a, b, source.intrinsics, stride=1) == pytest.approx(expected, rel=1e-6)


def test_refuses_to_overwrite_and_bad_windows(tmp_path: Path) -> None:
    out = make_plane_sequence(tmp_path / "s", frames=1)
    with pytest.raises(OutputError, match="already exists; pass --overwrite"):
        make_plane_sequence(out, frames=1)
    with pytest.raises(ValueError, match="must not overlap"):  # the caller's windows: a bug
        generate_sequence(PlaneSource(), np.array([0, 5]), np.array([10, 20]), tmp_path / "x",
                          progress=False)
    assert not (tmp_path / "x").exists()


def test_srgb_roundtrip_and_response() -> None:
    x = np.linspace(0, 1, 1001, dtype=np.float32)
    np.testing.assert_allclose(linear_to_srgb(srgb_to_linear(x)), x, atol=1e-6)
    # IEC 61966-2-1 reference points
    assert float(linear_to_srgb(np.array(0.0031308, np.float32))) == pytest.approx(0.04045,
                                                                                  abs=1e-5)
    assert float(srgb_to_linear(np.array(0.5, np.float32))) == pytest.approx(0.214041, abs=1e-5)
    response = LdrResponse(gain=2.0)
    rad = np.array([[0.1, 0.2, 0.6]], np.float32)
    ldr = response.to_ldr(rad)
    assert ldr[0, 2] == 255  # 0.6 * 2 saturates
    np.testing.assert_allclose(response.inverse(ldr)[0, :2], rad[0, :2], rtol=0.02)
    with pytest.raises(ConfigError):
        LdrResponse(kind="log")  # type: ignore[arg-type]  # the runtime check
