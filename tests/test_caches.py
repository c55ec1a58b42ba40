"""One cache rule (egs_bench/caches.py) for the CLI, the Makefile's warm-up and the tests."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from egs_bench.caches import cache_root, check_numba_cache_dir, numba_cache_dir
from egs_bench.cli import main
from egs_bench.errors import EXIT_USAGE, ConfigError

REPO_ROOT = Path(__file__).resolve().parents[1]


def test_the_variables_win_and_the_kernels_sit_in_the_egs_bench_cache(tmp_path: Path) -> None:
    assert numba_cache_dir({"NUMBA_CACHE_DIR": str(tmp_path / "n")}) == tmp_path / "n"
    assert cache_root({"EGS_BENCH_CACHE": str(tmp_path / "c")}) == tmp_path / "c"
    assert numba_cache_dir({"EGS_BENCH_CACHE": str(tmp_path / "c")}) == tmp_path / "c" / "numba"
    # an empty variable is unset, as numba reads it
    assert numba_cache_dir({"NUMBA_CACHE_DIR": "", "EGS_BENCH_CACHE": str(tmp_path)}) == (
        tmp_path / "numba")


def test_inside_a_writable_venv_the_default_is_in_the_venv(monkeypatch: pytest.MonkeyPatch,
                                                           tmp_path: Path) -> None:
    monkeypatch.setattr(sys, "prefix", str(tmp_path / "venv"))
    monkeypatch.setattr(sys, "base_prefix", "/usr")
    assert numba_cache_dir({}) == tmp_path / "venv" / "var" / "cache" / "egs_bench" / "numba"
    monkeypatch.setattr(sys, "base_prefix", str(tmp_path / "venv"))  # not a venv
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert cache_root({}) == tmp_path / "home" / ".cache" / "egs_bench"


def test_the_makefile_leaves_the_rule_to_the_library() -> None:
    makefile = (REPO_ROOT / "Makefile").read_text(encoding="utf-8")
    assert "export NUMBA_CACHE_DIR" not in makefile
    assert "export EGS_BENCH_CACHE" not in makefile
    assert "egs-bench warm-up" in makefile


def test_a_regular_file_as_the_kernel_cache_is_one_usage_error(monkeypatch: pytest.MonkeyPatch,
                                                               tmp_path: Path,
                                                               capsys: pytest.CaptureFixture[str]
                                                               ) -> None:
    not_a_folder = tmp_path / "numba"
    not_a_folder.write_text("x")
    with pytest.raises(ConfigError, match="is not a folder"):
        check_numba_cache_dir({"NUMBA_CACHE_DIR": str(not_a_folder)})
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(not_a_folder))
    assert main(["warm-up"]) == EXIT_USAGE
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and str(not_a_folder) in lines[0] and "NUMBA_CACHE_DIR" in lines[0]


def test_a_kernel_cache_under_a_file_is_refused(tmp_path: Path) -> None:
    (tmp_path / "f").write_text("x")
    with pytest.raises(ConfigError, match="cannot be created"):
        check_numba_cache_dir({"NUMBA_CACHE_DIR": str(tmp_path / "f" / "numba")})


def _snapshot(folder: Path) -> dict[str, tuple[int, int]]:
    return {str(p.relative_to(folder)): (p.stat().st_size, p.stat().st_mtime_ns)
            for p in folder.rglob("*") if p.is_file()}


@pytest.mark.slow
def test_after_the_warm_up_a_command_typed_by_hand_compiles_nothing(tmp_path: Path) -> None:
    # the environment of a shell with .venv/bin on PATH: none of the cache variables set
    env = {"PATH": os.environ.get("PATH", ""), "HOME": str(tmp_path / "home"),
           "PYTHONPATH": str(REPO_ROOT), "EGS_BENCH_DATA": str(tmp_path / "data"),
           "MPLBACKEND": "Agg", "OMP_WAIT_POLICY": "PASSIVE"}
    cmd = [sys.executable, "-m", "egs_bench"]
    warm = subprocess.run([*cmd, "warm-up"], env=env, capture_output=True, text=True,
                          timeout=1800)
    assert warm.returncode == 0, warm.stderr
    cache = Path(subprocess.run([sys.executable, "-c",
                                 "from egs_bench.caches import numba_cache_dir; "
                                 "print(numba_cache_dir())"],
                                env=env, capture_output=True, text=True, check=True)
                 .stdout.strip())
    before = _snapshot(cache)
    assert any(name.endswith(".nbi") for name in before)  # the warm-up wrote its index here
    first = subprocess.run([*cmd, "make-synthetic", "--scene", "office", "-o",
                            str(tmp_path / "seq"), "--frames", "2", "--width", "32",
                            "--height", "24", "--quiet"],
                           env=env, capture_output=True, text=True, timeout=600)
    assert first.returncode == 0, first.stderr
    # numba rewrites a kernel's index file whenever it compiles (and saves) a new version
    assert _snapshot(cache) == before
