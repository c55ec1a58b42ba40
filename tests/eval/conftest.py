"""Fixtures of the evaluation tests."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture(autouse=True)
def _isolated_eval_env(tmp_path_factory: pytest.TempPathFactory, monkeypatch: pytest.MonkeyPatch
                       ) -> None:
    """Keep evo's settings file and the LPIPS cache out of the user's home."""
    home = tmp_path_factory.getbasetemp() / "eval_home"
    home.mkdir(exist_ok=True)
    monkeypatch.setenv("HOME", str(home))
    monkeypatch.delenv("EGS_BENCH_LPIPS_WEIGHTS", raising=False)
    monkeypatch.setenv("EGS_BENCH_CACHE", str(tmp_path_factory.getbasetemp() / "egs_cache"))
    monkeypatch.setenv("TORCH_HOME", str(home / "torch"))


@pytest.fixture(scope="session")
def eval_sequence(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 12-frame 64x48 canonical sequence with known poses and images (no events); see
    ``tests.helpers.eval_fixtures.make_sequence``."""
    from tests.helpers.eval_fixtures import make_sequence

    return make_sequence(tmp_path_factory.mktemp("seqs"))
