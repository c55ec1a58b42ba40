"""``benchmarks/oracle_tracking.py``: its pose errors against analytic offsets, and the tracker
wrapper that substitutes ground truth only up to ``--oracle-until`` while recording the
tracker's own errors."""

import csv
import importlib.util
import io
import math
from collections.abc import Callable
from pathlib import Path
from types import ModuleType, SimpleNamespace
from typing import Any

import numpy as np
import pytest

from egs_bench.geometry import invert_pose
from egs_bench.geometry.lie import se3_exp
from egs_bench.slam.frames import FrameState
from egs_bench.slam.tracker import TrackRequest, TrackResult

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "oracle_tracking.py"


def _script() -> ModuleType:
    spec = importlib.util.spec_from_file_location("oracle_tracking", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _camera_to_world(x: float, yaw_deg: float) -> np.ndarray:
    pose = np.eye(4)
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    pose[:3, :3] = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    pose[:3, 3] = [x, 0.3, -1.2]
    return pose


def _fake_sequence(exposure: Callable[[int], tuple[int, int]]
                   ) -> tuple[SimpleNamespace, np.ndarray]:
    """A sequence moving 0.1 m along x and turning 5 deg over 1 s (dense poses every 0.1 s),
    with the given ``exposure(i) -> (start_us, end_us)``; returns it and its poses
    (camera-to-world [11, 4, 4])."""
    times = np.linspace(0.0, 1.0, 11)
    truth_wc = np.stack([_camera_to_world(0.1 * t, 5.0 * t) for t in times])
    seq = SimpleNamespace(
        path=Path("fake"), dense_trajectory=SimpleNamespace(timestamps=times, poses=truth_wc),
        exposure=exposure)
    return seq, truth_wc


def test_pose_error_matches_analytic_offsets() -> None:
    oracle = _script()
    truth_cw = invert_pose(_camera_to_world(0.50, 10.0))
    # Camera centre 3 cm further along x, camera turned 7 degrees further about y.
    estimate_cw = invert_pose(_camera_to_world(0.53, 17.0))
    cm, deg = oracle.pose_error(estimate_cw, truth_cw)
    assert cm == pytest.approx(3.0, abs=1e-9)
    assert deg == pytest.approx(7.0, abs=1e-9)
    assert oracle.pose_error(truth_cw, truth_cw) == pytest.approx((0.0, 0.0), abs=1e-6)


class _FakeTracker:
    """A tracker that returns the truth offset by ``offset`` (a fixed camera-frame motion)."""

    def __init__(self, truth_wc: np.ndarray, offset: np.ndarray) -> None:
        self.truth_wc, self.offset = truth_wc, offset

    def track(self, gmap: Any, crf: Any, request: TrackRequest) -> TrackResult:
        i = request.obs.index
        truth_cw = invert_pose(self.truth_wc[i + 1])
        start_cw = invert_pose(self.truth_wc[i])
        return TrackResult(FrameState(i, self.offset @ start_cw, self.offset @ truth_cw,
                                      0.1, 0.2), 0.0, 5, True)


def test_oracle_until_keeps_the_trackers_estimates_after_n_and_records_errors() -> None:
    oracle = _script()
    seq, truth_wc = _fake_sequence(lambda i: (100_000 * i, 100_000 * (i + 1)))
    offset = se3_exp(np.array([0.02, 0.0, 0.0, 0.0, 0.0, 0.0]))  # 2 cm along camera x
    errors: list[tuple[float, ...]] = []
    tracker = oracle.OracleTracker(_FakeTracker(truth_wc, offset), seq, until=1, errors=errors)
    for i in range(3):
        obs = SimpleNamespace(index=i, fractions=np.linspace(0, 1, 4))
        init = FrameState(i, invert_pose(truth_wc[i]), invert_pose(truth_wc[i]))
        state = tracker.track(None, None, TrackRequest(obs, init)).state  # type: ignore[arg-type]
        substituted = np.allclose(state.pose1_cw, invert_pose(truth_wc[i + 1]), atol=1e-9)
        assert substituted == (i <= 1), i
        assert (state.exp_a, state.exp_b) == (0.1, 0.2)  # exposure stays the tracker's
    rows = list(csv.DictReader(io.StringIO(oracle.errors_csv(errors))))
    assert [int(r["frame"]) for r in rows] == [0, 1, 2]
    for r in rows:
        assert float(r["tau_cm"]) == pytest.approx(2.0, abs=1e-5)
        assert float(r["start_cm"]) == pytest.approx(2.0, abs=1e-5)
        assert float(r["tau_deg"]) == pytest.approx(0.0, abs=1e-4)
        # The prediction is the previous exposure end: one step of the true motion away.
        assert float(r["predicted_cm"]) == pytest.approx(1.0, abs=1e-4)
        assert float(r["predicted_deg"]) == pytest.approx(0.5, abs=1e-4)


class _EmptyRound:
    """A mapping round with no iterations."""

    def __init__(self, window: list[int]) -> None:
        self.window = window
        self.remaining = 0

    def advance(self, n: int) -> None:
        pass

    def close(self) -> float:
        return 0.0


class _RecordingMapper:
    """A map optimiser that records frame 0's exposure start at each round."""

    def __init__(self) -> None:
        self.seen: list[np.ndarray] = []

    def optimise(self, states: dict[int, FrameState], observations: dict[int, Any],
                 window: list[int], all_keyframes: list[int], iterations: int, *,
                 initial: bool = False, fixed_end_pose: int | None = 0,
                 report: Any = None) -> float:
        return self.begin_round(states, observations, window, all_keyframes, iterations).close()

    def begin_round(self, states: dict[int, FrameState], observations: dict[int, Any],
                    window: list[int], all_keyframes: list[int], iterations: int, *,
                    initial: bool = False, fixed_end_pose: int | None = 0,
                    report: Any = None) -> _EmptyRound:
        self.seen.append(states[0].pose0_cw.copy())
        return _EmptyRound(window)

    def refine(self, states: dict[int, FrameState], observations: dict[int, Any],
               keyframes: list[int], iterations: int) -> float:
        return 0.0


def test_exposure0_oracle_moves_frame0_start_only_for_the_blur_models_map_initialisation(
        ) -> None:
    oracle = _script()
    # Frame 0's exposure runs from t = 0.05 s (between two dense poses) to t = 0.1 s.
    seq, truth_wc = _fake_sequence(lambda i: (50_000, 100_000))
    end_cw = invert_pose(truth_wc[1])
    seen: list[np.ndarray] = []
    for blur, initial in ((True, True), (True, False), (False, True)):
        inner = _RecordingMapper()
        mapper = oracle.TrueExposure0Mapper(inner, seq, blur_model=blur)
        mapper.optimise({0: FrameState(0, end_cw.copy(), end_cw.copy())}, {}, [0], [0], 1,
                        initial=initial)
        seen += inner.seen
    moved, refinement, no_blur = seen
    # Halfway between the poses at t = 0 and 0.1: camera centre x = 0.005 m, yaw 0.25 deg.
    assert oracle.pose_error(moved, invert_pose(_camera_to_world(0.005, 0.25))) == \
        pytest.approx((0.0, 0.0), abs=1e-4)
    assert np.array_equal(refinement, end_cw) and np.array_equal(no_blur, end_cw)


def test_oracle_components_satisfy_the_slam_protocols() -> None:
    from egs_bench.slam.components import MapOptimiser, Tracker

    oracle = _script()
    seq, truth_wc = _fake_sequence(lambda i: (50_000, 100_000))
    assert isinstance(oracle.OracleTracker(_FakeTracker(truth_wc, np.eye(4)), seq), Tracker)
    assert isinstance(oracle.TrueExposure0Mapper(_RecordingMapper(), seq, True), MapOptimiser)
