"""`demo --seed`: the seed reaches the runs, and a finished demo run of another seed or other
settings is kept."""

from __future__ import annotations

from pathlib import Path

import pytest

from egs_bench.datasets.sequence import Sequence
from egs_bench.demo import run_demo
from egs_bench.errors import InputError, OutputError
from egs_bench.runs.folder import RunFolder
from egs_bench.slam.methods import BUILTIN


def _finished_run(run_dir: Path, seq: Path, seed: int, **changes: object) -> None:
    """A stand-in for a finished demo run: the configuration this code's cpu preset resolves
    for ``egs`` on ``seq`` (with ``changes``), but no results."""
    slam = BUILTIN["egs"].config("cpu", Sequence.open(seq).meta).replace(**changes)
    run = RunFolder.create(run_dir, method="egs", sequence_name=seq.name, sequence_path=seq,
                           config={"seed": seed, "preset": "cpu", "slam": slam.to_dict()})
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


def test_a_finished_run_of_other_settings_is_refused_and_kept(tmp_path: Path,
                                                              tiny_sequence: Path) -> None:
    """A demo folder from an earlier version, whose preset differed, is not reported as this
    version's result."""
    out = tmp_path / "demo"
    run_dir = out / "runs" / tiny_sequence.name / "egs"
    _finished_run(run_dir, tiny_sequence, seed=0, tracking_iters=7)
    before = sorted(p.name for p in run_dir.iterdir())
    with pytest.raises(OutputError, match=r"egs: is a finished demo run made with other "
                                          r"settings \(slam\.budget\.tracking_iters\)"):
        run_demo(out, sequence=str(tiny_sequence), methods=("egs",), seed=0,
                 say=lambda _t: None, progress=False)
    assert sorted(p.name for p in run_dir.iterdir()) == before
    assert RunFolder.open(run_dir).read_status().state == "done"
