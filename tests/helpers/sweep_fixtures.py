"""Test helpers of the experiments tests: small sequences and fast fake methods.

The fake methods are real method objects (name, description, run) that write complete run
folders in milliseconds: the estimate is the ground truth plus seeded noise of a known size,
the renders are the sharp frames plus seeded noise. Worker processes import them by import path
(``tests.helpers.sweep_fixtures:GOOD``), so the tests put the repository root on ``PYTHONPATH``.

Environment knobs (read inside the worker process): ``FAKE_SLEEP_S`` seconds to sleep before
writing (for kill and timeout tests), ``FAKE_FAIL`` = ``<method>:<seed>`` pairs (comma
separated) that raise, ``FAKE_LOST`` the same for a tracking loss, ``FAKE_SLEEP_AFTER_S``
seconds to sleep after the run is marked done (to interrupt a worker before its evaluation).
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:  # worker processes import this module: no test-only imports at run time
    import pytest

    from egs_bench.datasets.sequence import Sequence
    from egs_bench.runs.folder import RunFolder

REPO_ROOT = Path(__file__).resolve().parents[2]
WIDTH, HEIGHT, FRAME_US = 48, 32, 33_333


def make_sequence(root: Path, name: str, frames: int = 10, seed: int = 0) -> Path:
    """A canonical sequence (no events) with sharp ground truth on a curved path."""
    from scipy.spatial.transform import Rotation

    from egs_bench.datasets.sequence import SequenceWriter
    from egs_bench.geometry import pose_from_tq

    path = root / name
    meta = {"name": name, "width": WIDTH, "height": HEIGHT, "fx": 40.0, "fy": 40.0,
            "cx": 24.0, "cy": 16.0, "depth_scale": 1000.0, "eps": 1e-3}
    writer = SequenceWriter(path, meta, t_offset_us=None, with_sharp=True)
    s = np.linspace(0.0, 1.0, frames)
    t = np.stack([0.5 * np.cos(2 * s), 0.5 * np.sin(2 * s), 0.1 * s + 0.01 * seed], axis=1)
    poses = pose_from_tq(t, Rotation.from_euler("xyz", np.stack([0.1 * s, 0.2 * s, 0.3 * s],
                                                                1)).as_quat())
    rng = np.random.default_rng(seed)
    base = rng.integers(20, 235, (HEIGHT, WIDTH, 3))
    for i in range(frames):
        sharp = np.clip(base + 3 * i, 0, 255).astype(np.uint8)
        writer.add_frame(i * FRAME_US, (i + 1) * FRAME_US - 1000, sharp,
                         np.full((HEIGHT, WIDTH), 2.0, np.float32), poses[i], sharp=sharp)
    writer.finish()
    return path


def _listed(var: str, method: str, seed: int) -> bool:
    return f"{method}:{seed}" in os.environ.get(var, "").split(",")


@dataclass
class FakeMethod:
    """A method with a known accuracy: position noise ``noise_m`` and render noise ``render_sd``
    (8-bit levels), both seeded."""

    name: str
    noise_m: float
    render_sd: float
    description: str = "fake method for tests"

    def run(self, sequence: Sequence, out: Path, *, preset: str = "paper", device: str = "cpu",
            seed: int = 0, max_frames: int | None = None, progress: bool = True,
            options: dict[str, Any] | None = None) -> RunFolder:
        from egs_bench.runs.folder import RunFolder

        n = len(sequence) if max_frames is None else min(len(sequence), max_frames)
        run = RunFolder.create(out, method=self.name, sequence_name=sequence.name,
                               sequence_path=sequence.path,
                               config={"method": self.name, "preset": preset, "seed": seed,
                                       "device": device, "frames": n,
                                       "fake": {"noise_m": self.noise_m}})
        with run.failure_guard():
            time.sleep(float(os.environ.get("FAKE_SLEEP_S", "0")))
            if _listed("FAKE_FAIL", self.name, seed):
                raise RuntimeError("injected failure")
            if _listed("FAKE_LOST", self.name, seed):
                run.mark_failed("injected tracking loss at frame 3", tracking_lost=True)
                return run
            rng = np.random.default_rng(1000 + seed)
            est = np.asarray(sequence.poses[:n]).copy()
            est[:, :3, 3] += rng.normal(0.0, self.noise_m, (n, 3))
            run.write_trajectory(np.asarray(sequence.timestamps_s[:n]), est)
            run.write_keyframes([0, n // 3, 2 * n // 3])  # the monogs protocol's ATE needs 3
            for i in range(n):
                sharp_img = sequence.sharp(i)
                assert sharp_img is not None
                sharp = sharp_img.astype(float)
                noisy = sharp + rng.normal(0.0, self.render_sd, sharp.shape)
                run.write_render(i, np.clip(noisy, 0, 255).astype(np.uint8))
            run.write_timing(total_wall_s=0.01 * n, per_frame_s=[0.01] * n, render_fps=100.0)
            run.mark_done()
        time.sleep(float(os.environ.get("FAKE_SLEEP_AFTER_S", "0")))
        return run


GOOD = FakeMethod("good", noise_m=0.01, render_sd=4.0)
BAD = FakeMethod("bad", noise_m=0.03, render_sd=12.0)
# named like the benchmark's two main methods (its ratios compare "egs" with "monogs")
FAKE_EGS = FakeMethod("egs", noise_m=0.01, render_sd=4.0)
FAKE_MONOGS = FakeMethod("monogs", noise_m=0.03, render_sd=12.0)

# the import paths (``module:attribute``) by which sweeps and worker processes name them
GOOD_PATH, BAD_PATH = f"{__name__}:GOOD", f"{__name__}:BAD"
FAKE_EGS_PATH, FAKE_MONOGS_PATH = f"{__name__}:FAKE_EGS", f"{__name__}:FAKE_MONOGS"


def worker_env(monkeypatch: pytest.MonkeyPatch) -> None:
    """Make this checkout's ``tests`` package importable by worker processes and keep caches in
    the test tree."""
    path = os.environ.get("PYTHONPATH", "")
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(p for p in (str(REPO_ROOT), path) if p))
    monkeypatch.setenv("OMP_WAIT_POLICY", "PASSIVE")
