"""Tiny canonical sequences and run folders for evaluation tests (built with the real writers)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from egs_bench.datasets.sequence import SequenceWriter
from egs_bench.geometry import pose_from_tq
from egs_bench.runs.folder import RunFolder

WIDTH, HEIGHT, NUM_FRAMES, FRAME_US = 64, 48, 12, 33_333


def gt_poses(n: int = NUM_FRAMES) -> np.ndarray:
    """A non-degenerate curved trajectory (x-y circle arc with some z), [n, 4, 4]."""
    s = np.linspace(0.0, 1.0, n)
    t = np.stack([0.5 * np.cos(2 * s), 0.5 * np.sin(2 * s), 0.1 * s], axis=1)
    angles = np.stack([0.1 * s, 0.2 * s, 0.3 * s], axis=1)
    from scipy.spatial.transform import Rotation

    return pose_from_tq(t, Rotation.from_euler("xyz", angles).as_quat())


def frame_image(i: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed * 1000 + i)
    base = np.linspace(0, 255, WIDTH * HEIGHT * 3).reshape(HEIGHT, WIDTH, 3)
    return np.clip(base + rng.normal(0, 20, base.shape), 0, 255).astype(np.uint8)


def make_sequence(root: Path, name: str = "tiny") -> Path:
    """Write a canonical sequence (no events) with sharp GT; returns its folder."""
    path = root / name
    meta = {"name": name, "width": WIDTH, "height": HEIGHT, "fx": 50.0, "fy": 50.0,
            "cx": 32.0, "cy": 24.0, "depth_scale": 1000.0, "eps": 1e-3}
    writer = SequenceWriter(path, meta, t_offset_us=None, with_sharp=True)
    poses = gt_poses()
    for i in range(NUM_FRAMES):
        sharp = frame_image(i)
        blurred = np.clip(sharp.astype(int) // 2 + 60, 0, 255).astype(np.uint8)
        writer.add_frame(i * FRAME_US, (i + 1) * FRAME_US - 1000, blurred,
                         np.full((HEIGHT, WIDTH), 2.0, np.float32), poses[i], sharp=sharp)
    writer.finish()
    return path


def make_run(root: Path, seq_path: Path, method: str = "egs", sequence_name: str = "tiny",
             offset: float = 0.01, render_noise: float = 8.0, render_every: int = 1,
             keyframes: tuple[int, ...] = (0, 3, 7, 10)) -> RunFolder:
    """A finished run: GT trajectory with a known position error, noisy renders, timing."""
    from egs_bench.datasets.sequence import Sequence

    seq = Sequence.open(seq_path)
    run = RunFolder.create(root / sequence_name / method, method=method,
                           sequence_name=sequence_name, sequence_path=seq_path,
                           config={"iterations": 10})
    est = seq.poses.copy()
    rng = np.random.default_rng(1)
    est[:, :3, 3] += rng.normal(0, offset, (len(est), 3))
    run.write_trajectory(seq.timestamps_s, est)
    run.write_keyframes(list(keyframes))
    for i in range(0, len(seq), render_every):
        sharp = seq.sharp(i)
        assert sharp is not None
        noisy = sharp.astype(float) + rng.normal(0, render_noise, sharp.shape)
        run.write_render(i, np.clip(noisy, 0, 255).astype(np.uint8))
    run.write_timing(total_wall_s=6.0, per_frame_s=[0.5] * len(seq), render_fps=250.0)
    run.mark_done()
    return run
