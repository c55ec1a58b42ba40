"""The ``>>>`` examples in the package's docstrings run and print what they show.

Only modules whose source holds an example are imported (found by reading the files), so the
test costs the few imports those examples need, not an import of the whole package.
"""

from __future__ import annotations

import doctest
import importlib
from pathlib import Path

import pytest

import egs_bench

PACKAGE_ROOT = Path(egs_bench.__file__).parent


def _modules_with_examples() -> list[str]:
    """Dotted names of the package's modules whose source contains a ``>>>`` prompt."""
    names = []
    for path in sorted(PACKAGE_ROOT.rglob("*.py")):
        if ">>>" in path.read_text(encoding="utf-8"):
            parts = path.relative_to(PACKAGE_ROOT.parent).with_suffix("").parts
            names.append(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    return names


MODULES = _modules_with_examples()


def test_the_package_has_docstring_examples() -> None:
    """Guards the discovery: an empty list would make the test below vacuous."""
    assert "egs_bench.render.rasterize" in MODULES


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples_print_what_they_show(name: str) -> None:
    # import_module, not attribute access: a package may re-export a function under its
    # module's name (egs_bench.render.rasterize).
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS, report=True)
    assert result.attempted > 0, f"{name}: its '>>>' lines are not in any docstring"
    assert result.failed == 0, f"{name}: {result.failed} example(s) failed (output above)"
