"""``mapping_mode=concurrent``: a keyframe's mapping round runs in fixed slices beside the next
frames' tracking (egs_bench/slam/scheduling.py). The schedule decides what is computed, so a
run is deterministic; tracking reads a snapshot; a signal stops the run cleanly."""

from __future__ import annotations

import os
import signal
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from egs_bench.datasets.sequence import Sequence
from egs_bench.errors import ConfigError, Interrupted
from egs_bench.render import GaussianMap
from egs_bench.runs.folder import RunFolder
from egs_bench.slam import methods
from egs_bench.slam.components import SlamComponents
from egs_bench.slam.config import SlamConfig
from egs_bench.slam.context import SlamContext
from egs_bench.slam.crf import CameraResponse
from egs_bench.slam.keyframes import KeyframeCandidate, MonoGSKeyframes
from egs_bench.slam.mapper import Mapper, MappingRound
from egs_bench.slam.runner import RunSettings, run_slam
from egs_bench.slam.scheduling import iterations_per_frame
from egs_bench.slam.system import SlamSystem
from egs_bench.slam.tracker import TrackRequest, TrackResult

FAST = dict(resolution_scale=1.0, init_iters=4, tracking_iters=3, mapping_iters=6,
            views_per_iter=2, kf_interval=2, pcd_downsample_init=2, pcd_downsample=4)


class EverySecondFrame(MonoGSKeyframes):
    """Keyframes at frames 2, 4, ... whatever the overlap (so the schedule is known)."""

    def __init__(self, ctx: SlamContext) -> None:
        super().__init__(ctx.cfg.keyframes, ctx.cfg.budget.window_size)

    def is_keyframe(self, candidate: KeyframeCandidate) -> bool:
        return candidate.frame_idx - candidate.last_kf_idx >= 2


PARTS = SlamComponents(keyframes=EverySecondFrame)


@pytest.fixture(scope="module")
def six_frames(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The plane scene, 6 frames: keyframes at frames 2 and 4 under :class:`EverySecondFrame`."""
    from tests.helpers.plane_scene import make_plane_sequence

    return make_plane_sequence(tmp_path_factory.mktemp("six") / "plane", frames=6)


def _config(mode: str, **changes: Any) -> SlamConfig:
    return methods.BUILTIN["egs"].config("cpu").replace(
        **{**FAST, "mapping_mode": mode, **changes}).validate()


def test_slice_defaults_to_the_round_over_the_keyframe_interval() -> None:
    assert iterations_per_frame(150, 4, None) == 38
    assert iterations_per_frame(30, 4, None) == 8
    assert iterations_per_frame(6, 2, None) == 3
    assert iterations_per_frame(30, 4, 5) == 5


def _mapping_iterations_after_each_frame(seq: Sequence, cfg: SlamConfig) -> list[int]:
    system = SlamSystem(seq, cfg, seed=0, components=PARTS)
    seen: list[int] = []
    mapper = system.mapper
    assert isinstance(mapper, Mapper)
    system.run(len(seq), on_frame=lambda _r: seen.append(mapper.iteration))
    return seen


def test_rounds_run_in_slices_beside_the_next_frames(six_frames: Path) -> None:
    """Keyframes at frames 2 and 4, rounds of 6 mapping iterations. Sequential maps each round
    at its keyframe; concurrent in slices of 3 beside frames 3 and 4 (and 5), the last round
    finished at the last frame. With slices of 2, keyframe 4 first finishes the round of
    keyframe 2 (2 + 2 + 2)."""
    seq = Sequence.open(six_frames)
    i = FAST["init_iters"]
    assert _mapping_iterations_after_each_frame(seq, _config("sequential")) == \
        [i, i, i + 6, i + 6, i + 12, i + 12]
    assert _mapping_iterations_after_each_frame(seq, _config("concurrent")) == \
        [i, i, i, i + 3, i + 6, i + 12]
    sliced = _mapping_iterations_after_each_frame(
        seq, _config("concurrent", mapping_iters_per_frame=2))
    assert sliced == [i, i, i, i + 2, i + 6, i + 12]


def test_concurrent_runs_are_deterministic_and_differ_from_sequential(six_frames: Path,
                                                                      tmp_path: Path) -> None:
    seq = Sequence.open(six_frames)
    runs = {}
    for name, mode in (("a", "concurrent"), ("b", "concurrent"), ("s", "sequential")):
        runs[name] = run_slam(seq, tmp_path / name, method_name="egs", config=_config(mode),
                              settings=RunSettings(progress=False), components=PARTS)
    a, b, s = (runs[k].read_trajectory().poses for k in "abs")
    np.testing.assert_array_equal(a, b)
    assert (runs["a"].path / "map.ply").read_bytes() == (runs["b"].path / "map.ply").read_bytes()
    # frame 3 is tracked against the map before its keyframe round ended: another estimate
    assert not np.array_equal(a[3], s[3])
    np.testing.assert_array_equal(a[:3], s[:3])  # nothing was mapping before frame 3


def test_tracking_reads_a_snapshot_not_the_live_map(six_frames: Path) -> None:
    """The tracker of frame 3 gets a copy, unchanged while the mapping slice runs; frames with
    nothing queued read the live map."""
    from egs_bench.slam.tracker import GradientTracker

    seq = Sequence.open(six_frames)
    seen: dict[int, tuple[bool, bool]] = {}

    class SnapshotCheck(GradientTracker):
        def track(self, gmap: GaussianMap, crf: CameraResponse, request: TrackRequest
                  ) -> TrackResult:
            before = gmap.means.detach().clone()
            result = super().track(gmap, crf, request)
            seen[request.obs.index] = (gmap is system.gmap,
                                       bool((gmap.means == before).all()))
            return result

    system = SlamSystem(seq, _config("concurrent"), seed=0,
                        components=SlamComponents(tracker=SnapshotCheck,
                                                  keyframes=EverySecondFrame))
    system.run(len(seq))
    assert seen[1] == (True, True) and seen[2] == (True, True)  # nothing queued: live map
    assert seen[3] == (False, True)  # a snapshot, unchanged while mapping ran


def test_a_mapper_without_rounds_is_refused_before_the_run(tiny_sequence: Path) -> None:
    """Concurrent mapping runs a mapper's rounds in slices: a mapper without begin_round is
    not a MapOptimiser and is refused when the system is built, in either mode."""
    class Plain:
        def __init__(self, *args: Any) -> None:
            pass

        def optimise(self, *args: Any, **kwargs: Any) -> float:
            return 0.0

        def refine(self, *args: Any, **kwargs: Any) -> float:
            return 0.0

    for mode in ("concurrent", "sequential"):
        with pytest.raises(ConfigError, match=r"the mapper Plain is not a MapOptimiser: it "
                                              r"has no begin_round\(\)"):
            SlamSystem(Sequence.open(tiny_sequence), _config(mode),
                       components=SlamComponents(mapper=Plain))  # type: ignore[arg-type]


def test_a_signal_during_a_mapping_slice_stops_the_run_marked_interrupted(
        six_frames: Path, tmp_path: Path) -> None:
    """SIGTERM sent while the worker maps beside frame 3: the frame loop stops, the worker is
    stopped and joined, and the run folder says interrupted with the frames it finished."""
    from egs_bench.interrupts import signals_interrupt

    class SignalInSlice(Mapper):
        def begin_round(self, *args: Any, **kwargs: Any) -> MappingRound:
            round_ = super().begin_round(*args, **kwargs)
            if round_.initial:  # map initialisation runs before any frame is tracked
                return round_
            advance = round_.advance

            def advance_then_signal(n: int) -> None:
                os.kill(os.getpid(), signal.SIGTERM)
                advance(n)

            round_.advance = advance_then_signal  # type: ignore[method-assign]
            return round_

    seq = Sequence.open(six_frames)
    out = tmp_path / "run"
    with signals_interrupt(), pytest.raises(Interrupted):
        run_slam(seq, out, method_name="egs", config=_config("concurrent"),
                 settings=RunSettings(progress=False),
                 components=SlamComponents(mapper=SignalInSlice, keyframes=EverySecondFrame))
    status = RunFolder.open(out).read_status()
    assert status.state == "interrupted" and "SIGTERM" in (status.reason or "")
    assert len(RunFolder.open(out).read_trajectory().poses) >= 3
