"""Coarse levels with fewer sub-poses (slam/levels.py, slam/frames.py): which sub-poses a
coarse level keeps, how it merges the events of the segments between them, and that the event
loss then measures the same log change as the fine segments do."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from egs_bench.geometry import Intrinsics
from egs_bench.slam import losses
from egs_bench.slam.config import ConfigError, cpu_preset
from egs_bench.slam.frames import FrameObs, coarse_observation
from egs_bench.slam.levels import kept_subposes
from egs_bench.slam.loss_terms import EVENTS, RenderedViews, TermSetup, event_residual

W, H = 32, 16
THETA = (0.25, 0.3)
EPS = 1e-3


@pytest.mark.parametrize("k", [1, 2, 3, 4, 7, 16])
def test_kept_subposes_span_the_exposure(k: int) -> None:
    for kc in range(1, k + 1):
        keep = kept_subposes(k, kc)
        assert len(keep) == kc + 1
        assert keep[0] == 0 and keep[-1] == k  # the exposure's start and end are rendered
        assert np.all(np.diff(keep) >= 1)  # no sub-pose twice
        # evenly spread: merged segments differ by at most one fine segment
        assert np.ptp(np.diff(keep)) <= 1
    assert kept_subposes(k, None).tolist() == list(range(k + 1))
    assert kept_subposes(k, k + 5).tolist() == list(range(k + 1))


def _obs(fractions: list[float], maps: np.ndarray) -> FrameObs:
    rng = np.random.default_rng(0)
    rgb = torch.from_numpy(rng.uniform(0.1, 0.9, (H, W, 3)).astype(np.float32))
    depth = torch.from_numpy(rng.uniform(1.0, 3.0, (H, W)).astype(np.float32))
    return FrameObs(0, rgb, depth, losses.rgb_boundary_mask(rgb), losses.depth_valid_mask(depth),
                    None, np.array(fractions), torch.from_numpy(maps), 123)


def _maps(o: FrameObs) -> torch.Tensor:
    assert o.event_maps is not None
    return o.event_maps


def _cam(w: int, h: int) -> Intrinsics:
    return Intrinsics(fx=20.0 * w / W, fy=20.0 * w / W, cx=w / 2, cy=h / 2, width=w, height=h)


def test_a_coarse_level_sums_the_events_of_the_segments_it_merges() -> None:
    cfg = cpu_preset()
    rng = np.random.default_rng(1)
    maps = rng.integers(-3, 4, (3, H, W)).astype(np.float32)  # K = 3 segments
    obs = _obs([0.0, 0.2, 0.7, 1.0], maps)
    same = coarse_observation(obs, _cam(W, H), cfg, None)
    assert np.array_equal(same.fractions, obs.fractions)
    assert torch.equal(_maps(same), _maps(obs))
    one = coarse_observation(obs, _cam(W, H), cfg, None, segments=1)
    assert one.fractions.tolist() == [0.0, 1.0]
    assert torch.equal(_maps(one), torch.from_numpy(maps.sum(0, keepdims=True)))
    two = coarse_observation(obs, _cam(W, H), cfg, None, segments=2)
    assert two.fractions.tolist() == [0.0, 0.7, 1.0]
    assert torch.equal(_maps(two)[0], torch.from_numpy(maps[0] + maps[1]))
    assert torch.equal(_maps(two)[1], torch.from_numpy(maps[2]))
    # at half the resolution the area mean keeps every segment's polarity sum per area
    small = coarse_observation(obs, _cam(W // 2, H // 2), cfg, None, segments=1)
    assert _maps(small).shape == (1, H // 2, W // 2)
    assert _maps(small).sum().item() * 4 == pytest.approx(float(maps.sum()), abs=1e-3)
    assert small.n_events == obs.n_events


def test_the_event_loss_of_merged_segments_measures_the_whole_log_change() -> None:
    """Renders whose consecutive log changes match the fine event targets exactly give a zero
    event residual at the fine level, and also with the first and last sub-pose only: the
    merged target is the sum of the fine targets, the prediction telescopes to the same sum.
    (One threshold for both polarities: with two, a map that sums events of both signs is
    read through the threshold of its net sign, at the fine level as at a merged one.)"""
    cfg = cpu_preset().replace(lambda_e=1.0)
    f64 = torch.float64
    rng = np.random.default_rng(2)
    hdr = torch.from_numpy(rng.uniform(0.05, 1.0, (1, 4, H, W, 3)))  # V = 1, K + 1 = 4
    luma = torch.tensor(losses.LUMA_BT601, dtype=f64)
    change = losses.rendered_event_maps(hdr, EPS, luma)[0].numpy()  # [3, H, W]
    theta = 0.25
    obs = _obs([0.0, 0.3, 0.6, 1.0], change / theta)  # the polarity sums of these changes
    setup = TermSetup(cfg, (theta, theta), tracking=False, use_events=True)

    def residual(o: FrameObs, rendered: torch.Tensor) -> torch.Tensor:
        prepared = EVENTS.prepare(o, setup, 1.0)
        assert prepared is not None
        alpha = torch.ones(rendered.shape[:4], dtype=f64)
        views = RenderedViews(rendered, rendered.mean(1), alpha, alpha, False, EPS, luma)
        return event_residual(views, prepared)

    assert residual(obs, hdr).abs().max().item() < 1e-6  # float32 observations
    keep = torch.from_numpy(kept_subposes(3, 1))
    merged = coarse_observation(obs, _cam(W, H), cfg, None, segments=1)
    assert residual(merged, hdr[:, keep]).abs().max().item() < 1e-6  # float32 observations
    # a wrong merge (the last segment's events only) does not vanish
    wrong = FrameObs(0, merged.rgb, merged.depth, merged.rgb_mask, merged.depth_mask, None,
                     merged.fractions, _maps(obs)[-1:], 1)
    assert residual(wrong, hdr[:, keep]).abs().max().item() > 0.1


def test_coarse_segments_above_the_segments_mean_the_segments() -> None:
    cfg = cpu_preset().replace(segments=2, tracking_coarse_segments=5).validate()
    assert kept_subposes(cfg.n_segments, cfg.budget.tracking_coarse_segments).tolist() == [0, 1,
                                                                                             2]
    with pytest.raises(ConfigError, match="budget.tracking_coarse_segments"):
        cpu_preset().replace(tracking_coarse_segments=0).validate()
