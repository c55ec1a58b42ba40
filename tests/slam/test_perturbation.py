"""The noise floor's perturbation seed (runtime.perturbation): a floating-point-sized move of
frame 0's pose, reproducible per seed, none at 0."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from egs_bench.datasets.sequence import Sequence
from egs_bench.geometry import invert_pose
from egs_bench.geometry.lie import so3_log
from egs_bench.slam import methods
from egs_bench.slam.system import SlamSystem, perturbed_pose


def _moved(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    rel = a @ invert_pose(b)
    return float(np.linalg.norm(so3_log(rel[:3, :3]))), float(np.linalg.norm(rel[:3, 3]))


def test_perturbation_zero_leaves_the_pose_and_a_seed_moves_it_by_its_size() -> None:
    pose = np.eye(4)
    assert perturbed_pose(pose, 0) is pose
    angle, shift = _moved(perturbed_pose(pose, 3), pose)
    assert angle == pytest.approx(1e-6, rel=1e-6) and shift == pytest.approx(1e-6, rel=1e-3)
    np.testing.assert_array_equal(perturbed_pose(pose, 3), perturbed_pose(pose, 3))
    assert not np.array_equal(perturbed_pose(pose, 3), perturbed_pose(pose, 4))


def test_a_run_starts_from_the_perturbed_pose(tiny_room: Path) -> None:
    seq = Sequence.open(tiny_room)
    base = methods.BUILTIN["monogs"].config("cpu").replace(init_iters=1, tracking_iters=1)
    gt0 = invert_pose(np.asarray(seq.poses[0], dtype=np.float64))
    for seed, moved in ((0, False), (2, True)):
        system = SlamSystem(seq, base.replace(**{"runtime.perturbation": seed}).validate())
        system.run(1)
        angle, shift = _moved(system.states[0].pose1_cw, gt0)
        assert (angle > 0) == moved and angle < 2e-6 and shift < 1e-5
