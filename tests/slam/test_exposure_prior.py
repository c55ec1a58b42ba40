"""The exposure prior ``budget.lambda_exposure_prior * (a^2 + b^2)`` (slam/losses.py): its
gradient against finite differences, mapping adding exactly it to the exposure gradients of
the keyframes it draws, and tracking stepping the exposure with it."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from egs_bench.slam.frames import FrameState
from egs_bench.slam.host_adam import HostAdam
from egs_bench.slam.losses import exposure_prior_gradient


def test_gradient_matches_finite_differences_of_the_prior() -> None:
    weight = 0.7
    ab = np.array([[0.3, -0.12], [-0.05, 0.4]])

    def energy(x: np.ndarray) -> float:
        return float(weight * (x ** 2).sum())

    h = 1e-6
    numeric = np.zeros_like(ab)
    for idx in np.ndindex(ab.shape):
        step = np.zeros_like(ab)
        step[idx] = h
        numeric[idx] = (energy(ab + step) - energy(ab - step)) / (2 * h)
    np.testing.assert_allclose(exposure_prior_gradient(ab, weight), numeric, rtol=1e-8)
    assert not exposure_prior_gradient(ab, 0.0).any()


class _RecordingAdam(HostAdam):
    """A host Adam that records every gradient it is stepped with."""

    recorded: list[np.ndarray] = []

    def step(self, grad: np.ndarray) -> np.ndarray:
        type(self).recorded.append(np.array(grad, dtype=np.float64))
        return super().step(grad)


def _frame1_exposure_after_one_step(seq_path: Path, weight: float) -> tuple[float, float]:
    """Frame 1's exposure ``(a, b)`` after one tracking iteration from ``(0.2, 0)``, with its
    observed colours brightened by exp(0.4): the photometric gradient then raises ``a``, a
    prior of weight ``weight`` lowers it."""
    from egs_bench.datasets.sequence import Sequence
    from egs_bench.slam import methods, tracker
    from egs_bench.slam.components import SlamComponents
    from egs_bench.slam.system import SlamSystem

    got: list[tuple[float, float]] = []

    class Brightened(tracker.GradientTracker):
        def track(self, gmap: Any, crf: Any, request: tracker.TrackRequest
                  ) -> tracker.TrackResult:
            if request.obs.index != 1:
                return super().track(gmap, crf, request)
            obs = dataclasses.replace(request.obs,
                                      rgb=(request.obs.rgb * np.exp(0.4)).clamp(0.0, 1.0))
            init = dataclasses.replace(request.init, exp_a=0.2, exp_b=0.0)
            result = super().track(gmap, crf, dataclasses.replace(
                request, obs=obs, init=init, iterations=1))
            got.append((result.state.exp_a, result.state.exp_b))
            return result

    cfg = methods.BUILTIN["egs"].config("cpu").replace(
        resolution_scale=1.0, init_iters=5, tracking_iters=1, tracking_iters_no_prior=None,
        tracking_coarse_scale=1.0, mapping_iters=1, lambda_exposure_prior=weight)
    SlamSystem(Sequence.open(seq_path), cfg.validate(), seed=0,
               components=SlamComponents(tracker=Brightened)).run(2)
    return got[0]


def test_tracking_steps_the_exposure_against_the_prior_gradient(tiny_sequence: Path) -> None:
    """Adam's first step is ``-lr sign(g)`` per parameter: without the prior the brightened
    frame raises ``a`` by lr (0.01); with a prior whose gradient ``2 w a`` outweighs the
    photometric one it lowers ``a`` by lr."""
    lr = 0.01  # tracking.lr_exposure
    a_free, _ = _frame1_exposure_after_one_step(tiny_sequence, 0.0)
    a_held, _ = _frame1_exposure_after_one_step(tiny_sequence, 1e4)
    assert a_free == pytest.approx(0.2 + lr, abs=1e-6)
    assert a_held == pytest.approx(0.2 - lr, abs=1e-6)


def test_mapping_adds_the_prior_for_the_drawn_keyframes_only() -> None:
    """``Mapper._host_step`` with keyframes 3 and 5 free and only 3 drawn: 3's gradient gains
    ``2 w (a, b)``, 5 gets none (it was not rendered this iteration)."""
    from egs_bench.slam.mapper import Mapper, _HostPlan

    weight = 0.25
    states = {3: FrameState(3, np.eye(4), np.eye(4), 0.1, -0.2),
              5: FrameState(5, np.eye(4), np.eye(4), -0.3, 0.05)}
    adam = _RecordingAdam(np.full(4, 0.01))
    _RecordingAdam.recorded = []
    plan = _HostPlan(refine=[], free_exposure=[3, 5], slot_mask=np.zeros(0), adam=adam)
    owner = SimpleNamespace(cfg=SimpleNamespace(
        budget=SimpleNamespace(lambda_exposure_prior=weight),
        method=SimpleNamespace(blur_model=True)))
    photometric = np.array([0.03, -0.04])  # d loss / d (a, b) of the one drawn view
    Mapper._host_step(owner, plan, states, [3], {}, photometric, 1)  # type: ignore[arg-type]
    np.testing.assert_allclose(_RecordingAdam.recorded[0],
                               [0.03 + 2 * weight * 0.1, -0.04 + 2 * weight * -0.2, 0.0, 0.0],
                               atol=1e-15)
