"""Fixtures shared by the SLAM tests."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def tiny_room(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """6 frames, 64x48, of the synthetic office (a 3-D room, unlike the plane): ~0.5 cm and
    0.6 deg per frame, 20 ms exposure, events. Generation takes ~10 s on 2 cores."""
    from egs_bench.datasets.synthetic import make_synthetic

    return make_synthetic("office", tmp_path_factory.mktemp("room") / "office", frames=6,
                          width=64, height=48, speed=0.4, seed=1, progress=False)
