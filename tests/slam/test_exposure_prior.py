"""The exposure prior ``loss.lambda_exposure_prior * (a^2 + b^2)`` (slam/losses.py): its
gradient against finite differences, and that tracking and mapping add exactly it to the
exposure gradients their host Adam steps with, and nothing to the poses."""

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


def _first_tracking_gradient(seq_path: Path, weight: float, monkeypatch: pytest.MonkeyPatch
                             ) -> np.ndarray:
    """Frame 1's first host-Adam gradient [6 n_free + 2], tracked from the exposure
    ``(0.2, -0.1)`` with the prior's weight ``weight``."""
    from egs_bench.datasets.sequence import Sequence
    from egs_bench.slam import methods, tracker
    from egs_bench.slam.components import SlamComponents
    from egs_bench.slam.system import SlamSystem

    class Recording(_RecordingAdam):
        recorded: list[np.ndarray] = []

    class StartExposed(tracker.GradientTracker):
        def track(self, gmap: Any, crf: Any, request: tracker.TrackRequest
                  ) -> tracker.TrackResult:
            if request.obs.index != 1:
                return super().track(gmap, crf, request)
            init = dataclasses.replace(request.init, exp_a=0.2, exp_b=-0.1)
            monkeypatch.setattr(tracker, "HostAdam", Recording)
            try:
                return super().track(gmap, crf, dataclasses.replace(request, init=init))
            finally:
                monkeypatch.setattr(tracker, "HostAdam", HostAdam)

    cfg = methods.BUILTIN["egs"].config("cpu").replace(
        resolution_scale=1.0, init_iters=5, tracking_iters=2, tracking_iters_no_prior=None,
        tracking_coarse_scale=1.0, mapping_iters=1, lambda_exposure_prior=weight)
    SlamSystem(Sequence.open(seq_path), cfg.validate(), seed=0,
               components=SlamComponents(tracker=StartExposed)).run(2)
    return Recording.recorded[0]


def test_tracking_adds_the_prior_to_the_exposure_gradient_only(
        tiny_sequence: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    off = _first_tracking_gradient(tiny_sequence, 0.0, monkeypatch)
    on = _first_tracking_gradient(tiny_sequence, 0.5, monkeypatch)
    np.testing.assert_array_equal(on[:-2], off[:-2])  # the same map and start: same pose grads
    np.testing.assert_allclose(on[-2:] - off[-2:], [2 * 0.5 * 0.2, 2 * 0.5 * -0.1], atol=1e-12)


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
        loss=SimpleNamespace(lambda_exposure_prior=weight),
        method=SimpleNamespace(blur_model=True)))
    photometric = np.array([0.03, -0.04])  # d loss / d (a, b) of the one drawn view
    Mapper._host_step(owner, plan, states, [3], {}, photometric, 1)  # type: ignore[arg-type]
    np.testing.assert_allclose(_RecordingAdam.recorded[0],
                               [0.03 + 2 * weight * 0.1, -0.04 + 2 * weight * -0.2, 0.0, 0.0],
                               atol=1e-15)
