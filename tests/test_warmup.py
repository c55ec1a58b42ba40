"""`egs-bench warm-up` compiles every cached numba kernel the library calls."""

from __future__ import annotations

import importlib
import importlib.abc
import re

import pytest

from egs_bench.cli import main
from egs_bench.kernel_cache import KERNEL_MODULES, cached_kernels
from egs_bench.warmup import warm_up

# a cached kernel's decorator and the name it is bound to, read from the source
_DECORATED = re.compile(r"^@njit\((?P<options>[^)]*)\)\s*\ndef (?P<name>\w+)\(", re.MULTILINE)


def _entry_kernels_in_source() -> set[str]:
    names = set()
    for module_name in KERNEL_MODULES:
        loader = importlib.import_module(module_name).__loader__
        assert isinstance(loader, importlib.abc.InspectLoader)
        source = loader.get_source(module_name)
        for m in _DECORATED.finditer(source or ""):
            options = m["options"]
            if ("cache=True" in options and 'inline="always"' not in options
                    and not m["name"].startswith("_")):
                names.add(f"{module_name}.{m['name']}")
    return names


def test_the_kernel_list_is_every_cached_entry_kernel_of_the_sources() -> None:
    assert set(cached_kernels()) == _entry_kernels_in_source()
    assert "egs_bench.render.numba_kernels.raster_bwd" in cached_kernels()


def test_no_module_outside_the_list_defines_cached_kernels() -> None:
    from pathlib import Path

    import egs_bench

    root = Path(egs_bench.__file__).parent
    holders = {".".join(("egs_bench", *p.relative_to(root).with_suffix("").parts))
               for p in root.rglob("*.py") if "cache=True" in p.read_text(encoding="utf-8")
               and p.name not in ("warmup.py", "kernel_cache.py")}
    assert holders == set(KERNEL_MODULES)


@pytest.mark.slow
def test_warm_up_reaches_every_kernel(capsys: pytest.CaptureFixture[str]) -> None:
    said: list[str] = []
    report = warm_up(say=said.append)
    assert report.missing == ()
    assert set(report.compiled) | set(report.loaded) == set(cached_kernels())
    assert len(said) == 3
    # the command reports the same counts (the process's counters add up) and exits 0
    assert main(["warm-up"]) == 0
    out = capsys.readouterr().out
    counts = re.search(r"numba kernels: (\d+) compiled, (\d+) already cached", out)
    assert counts is not None and int(counts[1]) + int(counts[2]) == len(cached_kernels())
