"""Tracking's stopping rules (``tracking.convergence``, egs_bench/slam/convergence.py): each rule
on iteration sequences whose answer is known, and the tracker stopping where the replayed rule
says it would."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from egs_bench.geometry.lie import se3_exp
from egs_bench.render import GaussianMap
from egs_bench.slam.config import SlamConfig
from egs_bench.slam.convergence import ConvergenceRule, ConvergenceTest, stop_iteration
from egs_bench.slam.crf import CameraResponse
from egs_bench.slam.tracker import TrackRequest, TrackResult


def _poses(twists: list[np.ndarray]) -> np.ndarray:
    """World-to-camera poses after each step of ``twists`` [n, 6], from the identity."""
    pose, out = np.eye(4), []
    for xi in twists:
        pose = se3_exp(np.asarray(xi, dtype=float)) @ pose
        out.append(pose)
    return np.array(out)


def _replay(rule: ConvergenceRule, steps: list[np.ndarray], tolerance: float, patience: int,
            losses: list[float] | None = None) -> int:
    poses = _poses(steps)
    norms = np.array([np.linalg.norm(s) for s in steps])
    loss = np.array(losses if losses is not None else [1.0] * len(steps))
    return stop_iteration(loss, norms, poses, rule, tolerance, patience, len(steps))


def _track_frame_1(sequence: Path, configs: dict[str, SlamConfig]) -> dict[str, TrackResult]:
    """Frame 1's tracking result, with its per-iteration trace, under each configuration (the
    same map and start: every run is seeded alike)."""
    from egs_bench.datasets.sequence import Sequence
    from egs_bench.slam.components import SlamComponents
    from egs_bench.slam.system import SlamSystem
    from egs_bench.slam.tracker import GradientTracker

    results: dict[str, TrackResult] = {}

    def recorder(label: str) -> type[GradientTracker]:
        class Recording(GradientTracker):
            def track(self, gmap: GaussianMap, crf: CameraResponse, request: TrackRequest
                      ) -> TrackResult:
                result = super().track(gmap, crf, dataclasses.replace(request, trace=True))
                if request.obs.index == 1:
                    results[label] = result
                return result
        return Recording

    seq = Sequence.open(sequence)
    for label, cfg in configs.items():
        SlamSystem(seq, cfg.validate(), seed=0,
                   components=SlamComponents(tracker=recorder(label))).run(2)
    return results


def test_net_motion_stops_an_oscillation_and_lets_a_steady_motion_run() -> None:
    step = np.array([1e-3, 0, 0, 0, 0, 0])
    steady = [step] * 40  # 1 mm per iteration in one direction: still converging
    assert _replay("net-motion", steady, 0.3, 10) == 40
    # 15 steps towards the optimum, then back and forth around it
    oscillating = [step] * 15 + [step * (-1) ** k for k in range(25)]
    stop = _replay("net-motion", oscillating, 0.3, 10)
    assert 15 < stop <= 15 + 11  # within one window of the start of the oscillation


def test_relative_step_and_plateau_on_known_sequences() -> None:
    shrinking = [np.array([1e-3 * 0.8 ** k, 0, 0, 0, 0, 0]) for k in range(30)]
    # steps below 0.1 x the first from k = 11 (0.8^11 = 0.086); three in a row end at k = 13
    assert _replay("relative-step", shrinking, 0.1, 3) == 14
    losses = [10.0, 5.0, 3.0, 2.5, 2.4] + [2.4] * 10
    flat = [np.zeros(6)] * len(losses)
    # the best loss stops improving after iteration 5 (index 4): 5 iterations later it stops
    assert _replay("plateau", flat, 1e-3, 5, losses) == 10
    assert _replay("fixed", shrinking, 0.1, 3) == 30


def test_net_motion_needs_the_pose() -> None:
    with pytest.raises(ValueError, match="needs the pose"):
        ConvergenceTest("net-motion", 0.3, 10).update(1.0, 0.1)


def test_the_tracker_stops_where_the_replayed_rule_does(tiny_sequence: Path) -> None:
    """Frame 1 is tracked from the same map and start with the rule on and off: the run with
    the rule stops at the iteration the rule, replayed over the full budget's trace, names, at
    the pose the full budget's run had there."""
    from egs_bench.slam import methods

    base = methods.BUILTIN["monogs"].config("cpu").replace(
        resolution_scale=1.0, init_iters=20, tracking_iters=60, tracking_iters_no_prior=None,
        mapping_iters=2, converged_threshold=1e-12, tracking_lr_final=1.0,
        tracking_coarse_scale=1.0)  # the rules watch fine iterations only: all of them here
    rule = dict(convergence="net-motion", convergence_tolerance=0.3, convergence_patience=10)
    results = _track_frame_1(tiny_sequence, {"fixed": base, "rule": base.replace(**rule)})
    full, stopped = results["fixed"], results["rule"]
    assert full.iterations == 60 and full.trace is not None
    expected = stop_iteration(full.trace.losses, full.trace.step_norms, full.trace.poses1_cw,
                              "net-motion", 0.3, 10, 60)
    assert expected < 60, "the rule should stop this frame early"
    assert stopped.iterations == expected and stopped.converged
    np.testing.assert_array_equal(stopped.state.pose1_cw, full.trace.poses1_cw[expected - 1])


def test_the_coarse_level_ends_where_the_replayed_rule_says(tiny_sequence: Path) -> None:
    """``budget.tracking_coarse_patience``: frame 1 tracked with and without it from the same
    map and start. With it, the coarse level ends at the iteration the net-motion rule,
    replayed over the coarse iterations of the full run, names, at the full run's pose there,
    and all the fine iterations follow."""
    from egs_bench.slam import methods
    from egs_bench.slam.levels import coarse_iterations

    base = methods.BUILTIN["monogs"].config("cpu").replace(
        resolution_scale=1.0, init_iters=20, tracking_iters=60, tracking_iters_no_prior=None,
        mapping_iters=2, converged_threshold=1e-12, tracking_lr_final=0.5,
        tracking_coarse_scale=0.5, tracking_coarse_fraction=0.9)
    n_iters, patience = 60, 8
    n_coarse = coarse_iterations(n_iters, 0.5, 0.9)
    results = _track_frame_1(tiny_sequence, {
        "full": base,
        "early": base.replace(tracking_coarse_patience=patience, tracking_coarse_tolerance=0.3)})
    full, early = results["full"], results["early"]
    assert full.trace is not None and early.trace is not None
    assert full.iterations == n_iters  # patience 0 (the default): every coarse iteration
    ends = stop_iteration(full.trace.losses[:n_coarse], full.trace.step_norms[:n_coarse],
                          full.trace.poses1_cw[:n_coarse], "net-motion", 0.3, patience,
                          n_coarse)
    assert ends < n_coarse - 1, "the rule should end this frame's coarse level early"
    assert early.iterations == ends + (n_iters - n_coarse)
    np.testing.assert_array_equal(early.trace.poses1_cw[:ends], full.trace.poses1_cw[:ends])
    assert not np.array_equal(early.state.pose1_cw, full.state.pose1_cw)
