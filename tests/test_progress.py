"""Progress fitted to where it is shown (egs_bench/progress.py)."""

from __future__ import annotations

import io
from pathlib import Path

import pytest

from egs_bench.progress import LOG_EVERY_S, ProgressBar, postfix_text, tracked
from tests.helpers.clock import FakeClock


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True




def test_without_a_terminal_a_run_writes_a_line_per_tenth_and_no_redraws() -> None:
    log = io.StringIO()
    with ProgressBar(24, "egs office", unit="frame", file=log) as bar:
        for i in range(24):
            bar.set_postfix(loss=0.5 / (i + 1), gaussians=100 + i)
            bar.update()
    text = log.getvalue()
    lines = text.splitlines()
    assert "\r" not in text
    assert len(lines) == 11  # the start and each tenth
    assert lines[-1].startswith("egs office: 24/24 frames (100 %)")
    assert "gaussians=123" in lines[-1]
    counts = [int(line.split(": ")[1].split("/")[0]) for line in lines]
    assert counts == sorted(set(counts))  # each line reports progress; none repeats


def test_a_long_silent_phase_gets_a_line_every_half_minute() -> None:
    log, clock = io.StringIO(), FakeClock()
    bar = ProgressBar(100, "egs office", unit="frame", file=log, clock=clock)
    bar.set_postfix_str("map init 0/150 iterations, compiling kernels…")  # the start: a line
    clock.now = 5.0
    bar.set_postfix_str("map init 1/150 iterations")
    clock.now = LOG_EVERY_S + 1
    bar.set_postfix_str("map init 3/150 iterations, ETA 90 s")
    clock.now += 1
    bar.set_postfix_str("map init 4/150 iterations, ETA 89 s")  # not again within 30 s
    assert log.getvalue().splitlines() == [
        "egs office: 0/100 frames (0 %), 0 s, map init 0/150 iterations, compiling kernels…",
        "egs office: 0/100 frames (0 %), 31 s, map init 3/150 iterations, ETA 90 s"]
    bar.close()
    bar.close()
    assert len(log.getvalue().splitlines()) == 3  # the final line, once


def test_non_finite_values_are_left_out_not_shown_as_nan() -> None:
    assert postfix_text({"loss": float("nan"), "fps": 1.23456, "gaussians": 7}) == (
        "fps=1.235, gaussians=7")
    assert postfix_text({"loss": float("inf")}) == ""
    term = _Terminal()
    with ProgressBar(3, "egs office", unit="frame", file=term) as bar:
        bar.set_postfix(loss=float("nan"), gaussians=5)
        bar.update()
    assert "nan" not in term.getvalue()
    assert "gaussians=5" in term.getvalue()


def test_on_a_terminal_it_is_a_bar_and_disabled_it_is_silent() -> None:
    term = _Terminal()
    with ProgressBar(4, "gen", unit="frame", file=term) as bar:
        bar.update(4)
    assert "\r" in term.getvalue() and "4/4" in term.getvalue()
    quiet = _Terminal()
    with ProgressBar(4, "gen", unit="frame", enabled=False, file=quiet) as bar:
        bar.update(4)
    assert quiet.getvalue() == ""
    assert list(tracked([1, 2, 3], "x", enabled=False)) == [1, 2, 3]


def test_run_quiet_also_silences_the_built_in_sequence_generation(monkeypatch: pytest.MonkeyPatch
                                                                  ) -> None:
    import egs_bench.datasets.registry as registry
    from egs_bench.cli import main

    seen: dict[str, object] = {}

    class _Stop(Exception):
        pass

    def fake_load(name: str, progress: bool = True) -> None:
        seen["progress"] = progress
        raise _Stop

    monkeypatch.setattr(registry, "load_sequence", fake_load)
    with pytest.raises(_Stop):
        main(["--debug", "run", "-m", "egs", "-s", "office-demo", "--quiet"])
    assert seen == {"progress": False}


@pytest.mark.slow
def test_make_synthetic_says_it_compiles_on_a_cold_cache_and_not_on_a_warm_one(tmp_path: Path
                                                                               ) -> None:
    import os
    import subprocess
    import sys
    from pathlib import Path

    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba"),
           "PYTHONPATH": str(Path(__file__).resolve().parents[1])}

    def make(name: str) -> str:
        done = subprocess.run([sys.executable, "-m", "egs_bench", "make-synthetic", "--scene",
                               "office", "-o", str(tmp_path / name), "--frames", "2",
                               "--width", "16", "--height", "16"],
                              env=env, capture_output=True, text=True, timeout=900)
        assert done.returncode == 0, done.stderr
        return done.stderr

    assert "compiling numba kernels" in make("cold")
    warm = make("warm")
    assert "compiling" not in warm and "generating warm: 2/2 frames" in warm
