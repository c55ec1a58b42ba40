"""Fixtures of the regression suite for bad input, data loss and interruptions."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from egs_bench.datasets.sequence import Sequence
from egs_bench.runs.folder import RunFolder


@pytest.fixture(scope="session")
def room_sequence(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """5 frames, 48x32, of the synthetic office: a 3-D camera path (the plane sequence moves
    along a line, on which SE(3) alignment is degenerate). Read-only."""
    from egs_bench.datasets.synthetic import make_synthetic

    return make_synthetic("office", tmp_path_factory.mktemp("room") / "office", frames=5,
                          width=48, height=32, speed=0.4, seed=1, progress=False)


@pytest.fixture
def seq_copy(tiny_sequence: Path, tmp_path: Path) -> Path:
    """A writable copy of the tiny generated plane sequence (4 frames, 64x48, events)."""
    return Path(shutil.copytree(tiny_sequence, tmp_path / "seq"))


@pytest.fixture
def done_run(room_sequence: Path, tmp_path: Path) -> RunFolder:
    """A finished run folder on the room sequence: ground-truth poses, the observed (blurred)
    frames as renders (so every metric is defined and finite)."""
    seq = Sequence.open(room_sequence)
    run = RunFolder.create(tmp_path / "runs" / "gt", method="gt", sequence_name=seq.name,
                           sequence_path=seq.path)
    run.write_trajectory(seq.timestamps_s, seq.poses)
    run.write_keyframes([0])
    for i in range(len(seq)):
        run.write_render(i, seq.rgb(i))
    run.write_timing(total_wall_s=1.0, per_frame_s=np.full(len(seq), 0.25))
    run.mark_done()
    return run
