"""The SLAM package's shape, read from its source: the frame loop stays short, no function
takes a dozen positional pieces of context, and nothing in the tests or benchmarks replaces a
SLAM function to change what the system does (the seams in :mod:`egs_bench.slam.components`
exist for that)."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SLAM = ROOT / "egs_bench" / "slam"
MAX_PARAMETERS = 8
MAX_RUN_LINES = 60


def _functions(path: Path) -> list[ast.FunctionDef | ast.AsyncFunctionDef]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return [n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef)]


def parameter_count(fn: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    """Positional, keyword-only and variadic parameters, not counting ``self`` / ``cls``."""
    a = fn.args
    names = [p.arg for p in a.posonlyargs + a.args + a.kwonlyargs]
    if names and names[0] in ("self", "cls"):
        names = names[1:]
    return len(names) + (a.vararg is not None) + (a.kwarg is not None)


def test_parameter_count_counts_what_a_caller_passes() -> None:
    fn = ast.parse("def f(self, a, b=1, *c, d, **e): pass").body[0]
    assert isinstance(fn, ast.FunctionDef) and parameter_count(fn) == 5


def test_no_slam_function_takes_more_than_eight_parameters() -> None:
    wide = [f"{path.name}:{fn.lineno} {fn.name} ({parameter_count(fn)})"
            for path in sorted(SLAM.glob("*.py")) for fn in _functions(path)
            if parameter_count(fn) > MAX_PARAMETERS]
    assert not wide, wide


def test_the_frame_loop_is_at_most_sixty_lines() -> None:
    runs = [fn for fn in _functions(SLAM / "system.py") if fn.name == "run"]
    assert len(runs) == 1
    length = (runs[0].end_lineno or 0) - runs[0].lineno + 1
    assert length <= MAX_RUN_LINES, length


def _replaced_slam_attributes(path: Path) -> list[str]:
    """``monkeypatch.setattr`` calls, and assignments to module or class attributes, that
    target something in ``egs_bench.slam``."""
    text = path.read_text(encoding="utf-8")
    tree = ast.parse(text)
    slam_names = {alias.asname or alias.name.split(".")[-1]
                  for node in ast.walk(tree) if isinstance(node, ast.ImportFrom | ast.Import)
                  for alias in node.names
                  if (getattr(node, "module", None) or alias.name).startswith("egs_bench.slam")}
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) \
                and node.func.attr == "setattr" and node.args:
            target = node.args[0]
            literal = isinstance(target, ast.Constant) and str(target.value).startswith(
                "egs_bench.slam")
            named = isinstance(target, ast.Name | ast.Attribute) and \
                ast.unparse(target).split(".")[0] in slam_names
            if literal or named:
                found.append(f"{path.name}:{node.lineno} {ast.unparse(node)[:80]}")
        if isinstance(node, ast.Assign):
            for t in node.targets:
                if isinstance(t, ast.Attribute) and ast.unparse(t).split(".")[0] in slam_names:
                    found.append(f"{path.name}:{node.lineno} {ast.unparse(t)}")
    return found


def test_the_finder_sees_a_replaced_slam_function(tmp_path: Path) -> None:
    sample = tmp_path / "sample.py"
    sample.write_text("from egs_bench.slam import system\n"
                      "import egs_bench.slam.mapper as mapper\n"
                      "def test(monkeypatch):\n"
                      "    monkeypatch.setattr(system, 'track_frame', None)\n"
                      "    monkeypatch.setattr('egs_bench.slam.system.x', None)\n"
                      "    mapper.Mapper.optimise = None\n"
                      "    system.value = 1\n")
    assert len(_replaced_slam_attributes(sample)) == 4


def test_no_test_or_benchmark_replaces_a_slam_function() -> None:
    files = sorted((ROOT / "tests").rglob("*.py")) + sorted((ROOT / "benchmarks").rglob("*.py"))
    found = [hit for path in files if path.name != Path(__file__).name
             for hit in _replaced_slam_attributes(path)]
    assert not found, found
