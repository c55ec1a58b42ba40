"""Fixtures of the report tests: the experiments' fake methods and small sequences, and a home
folder of their own (evo's settings file, the LPIPS cache)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "experiments"))


@pytest.fixture(autouse=True)
def _own_home(tmp_path_factory: pytest.TempPathFactory, monkeypatch: pytest.MonkeyPatch) -> None:
    base = tmp_path_factory.getbasetemp()
    monkeypatch.setenv("HOME", str(base / "report_home"))
    monkeypatch.setenv("EGS_BENCH_CACHE", str(base / "report_cache"))
