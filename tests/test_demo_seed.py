"""`demo --seed`: the seed reaches the runs, and a finished demo run of another seed is kept."""

from __future__ import annotations

from pathlib import Path

import pytest

from egs_bench.demo import run_demo
from egs_bench.errors import InputError, OutputError
from egs_bench.runs.folder import RunFolder


def _finished_run(run_dir: Path, seq: Path, seed: int) -> None:
    run = RunFolder.create(run_dir, method="egs", sequence_name=seq.name, sequence_path=seq,
                           config={"seed": seed})
    run.mark_done()


def test_a_finished_run_of_another_seed_is_refused_and_kept(tmp_path: Path, tiny_sequence: Path
                                                            ) -> None:
    out = tmp_path / "demo"
    run_dir = out / "runs" / tiny_sequence.name / "egs"
    _finished_run(run_dir, tiny_sequence, seed=0)
    before = sorted(p.name for p in run_dir.iterdir())
    with pytest.raises(OutputError, match=r"egs: is a finished demo run with seed 0, not 1"):
        run_demo(out, sequence=str(tiny_sequence), methods=("egs",), seed=1,
                 say=lambda _t: None, progress=False)
    assert sorted(p.name for p in run_dir.iterdir()) == before
    assert RunFolder.open(run_dir).read_status().state == "done"


def test_a_finished_run_of_the_same_seed_is_reused(tmp_path: Path, tiny_sequence: Path) -> None:
    out = tmp_path / "demo"
    run_dir = out / "runs" / tiny_sequence.name / "egs"
    _finished_run(run_dir, tiny_sequence, seed=2)
    said: list[str] = []
    # reused, not rerun: the stand-in run has no trajectory, so the evaluation after it fails
    with pytest.raises(InputError, match="trajectory.txt: estimated trajectory not found"):
        run_demo(out, sequence=str(tiny_sequence), methods=("egs",), seed=2,
                 say=said.append, progress=False)
    assert f"      egs: reusing finished run {run_dir}" in said
