"""Estimate / ground-truth trajectory pairs for the evo-parity tests: one made here, so the tests
run on a fresh clone, and the real TUM RGB-D pairs of ``../shared/data/trajectories``."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from egs_bench.geometry import pose_from_tq, write_tum

#: the generated pair's (estimate, ground truth) names; the real pairs follow
SYNTHETIC = ("synthetic-est.txt", "synthetic-gt.txt")
REAL = [("freiburg1_xyz-rgbdslam.txt", "freiburg1_xyz-groundtruth.txt"),
        ("fr2_desk_ORB.txt", "fr2_desk_groundtruth.txt")]
PAIRS = [SYNTHETIC, *REAL]


def write_synthetic_pair(folder: Path, seed: int = 0) -> tuple[Path, Path]:
    """Write an estimate and its ground truth as TUM files in ``folder``; returns (estimate,
    ground truth).

    The ground truth: 900 poses at 30 Hz on a 3-D loop about 1.5 m across (about 8 m of path),
    turning up to two full turns about the vertical and tilting. The estimate: every ground-truth
    pose but every seventh, stamped 3 ms late (so both tools must associate by time, within
    their default 10 ms), in another frame (rotated, shifted and scaled by 0.7, as a monocular
    estimate would be), with a random walk of 2 mm per step in position and 0.2 degrees of
    orientation noise per pose.
    """
    rng = np.random.default_rng(seed)
    n = 900
    stamps = 1_700_000_000.0 + np.arange(n) / 30.0
    s = np.linspace(0.0, 2 * np.pi, n)
    t = np.stack([0.8 * np.cos(s), 0.5 * np.sin(2 * s), 0.3 * np.sin(s) + 1.0], axis=1)
    rot = Rotation.from_euler("zyx", np.stack([2 * s, 0.3 * np.sin(s), 0.2 * np.cos(3 * s)], 1))
    gt = pose_from_tq(t, rot.as_quat())
    keep = np.arange(n) % 7 != 3
    frame = Rotation.from_euler("zyx", [0.7, -0.2, 0.4])
    scale, shift = 0.7, np.array([0.3, -1.2, 0.5])
    walk = np.cumsum(rng.normal(0.0, 0.002, (n, 3)), axis=0)
    t_est = scale * frame.apply(t + walk) + shift
    wobble = Rotation.from_rotvec(rng.normal(0.0, np.deg2rad(0.2), (n, 3)))
    est = pose_from_tq(t_est, (frame * rot * wobble).as_quat())
    folder.mkdir(parents=True, exist_ok=True)
    est_path, gt_path = folder / SYNTHETIC[0], folder / SYNTHETIC[1]
    write_tum(gt_path, stamps, gt)
    write_tum(est_path, stamps[keep] + 0.003, est[keep])
    return est_path, gt_path


def pair_paths(request: pytest.FixtureRequest, folder: Path, est_name: str, gt_name: str
               ) -> tuple[Path, Path]:
    """(estimate, ground truth) of a pair of :data:`PAIRS`: the generated one is written to
    ``folder``; a real one comes from ``../shared/data`` (the test skips when it is absent)."""
    if (est_name, gt_name) == SYNTHETIC:
        return write_synthetic_pair(folder)
    data = request.getfixturevalue("shared_data") / "trajectories"
    return data / est_name, data / gt_name
