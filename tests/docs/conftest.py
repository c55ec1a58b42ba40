"""The site's page generators (``docs/gen/``), loaded from their files: they are build
scripts beside the pages, not part of the package."""

from __future__ import annotations

import importlib.util
import sys
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

import pytest

GEN = Path(__file__).resolve().parents[2] / "docs" / "gen"


def _load(name: str) -> ModuleType:
    qualified = f"egs_bench_docs_gen_{name}"
    if qualified not in sys.modules:
        spec = importlib.util.spec_from_file_location(qualified, GEN / f"{name}.py")
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules[qualified] = module
        spec.loader.exec_module(module)
    return sys.modules[qualified]


@pytest.fixture(scope="session")
def gen() -> Callable[[str], ModuleType]:
    """``gen("cli_reference")``: the generator module of that name."""
    return _load
