"""The sweep worker in this process: failed and timed-out evaluations, a changed protocol, run
folders holding a user's files, the lock probe, and sweeps that must not generate anything."""

import fcntl
import json
import math
import os
import threading
from pathlib import Path
from typing import Any

import pytest

from egs_bench.errors import InputError
from egs_bench.experiments import worker
from egs_bench.experiments.spec import RunSpec, expand, parse_sweep
from egs_bench.experiments.sweep import run_row, run_sweep
from tests.helpers.sweep_fixtures import GOOD_PATH, make_sequence


@pytest.fixture(scope="module")
def seqs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("seqs")
    return {"a": make_sequence(root, "sa", 6, 0)}


def _run(seqs: dict[str, Path], out: Path, **extra: Any) -> RunSpec:
    spec = parse_sweep({"methods": [GOOD_PATH], "sequences": ["a"], **extra},
                       "s.yaml")
    return expand(spec, seqs, out)[0]


def _record(run: RunSpec) -> dict:
    return json.loads((Path(run.run_dir) / "sweep.json").read_text())


def test_a_failed_evaluation_fails_the_run_and_retry_evaluates_again(tmp_path: Path,
                                                                     seqs: dict[str, Path],
                                                                     monkeypatch: pytest.MonkeyPatch
                                                                     ) -> None:
    """A finished method whose evaluation raises is no result: state failed (exit code and
    summary say so, with the reason); it is kept like a failed run, and --retry-failed
    evaluates the kept outputs again instead of rerunning the method."""
    import egs_bench.eval.evaluate as evaluate

    run = _run(seqs, tmp_path)
    with monkeypatch.context() as m:
        def broken(*_args: Any, **_kwargs: Any) -> None:
            raise ValueError("degenerate alignment")

        m.setattr(evaluate, "evaluate_run", broken)
        assert worker.run_one(run, redirect=False) == worker.EXIT_FAILED
    record = _record(run)
    assert record["state"] == "failed" and "evaluated" not in record
    assert record["reason"] == "evaluation: ValueError: degenerate alignment"
    row = run_row(run)
    assert row["state"] == "failed" and math.isnan(row["ate_cm"])
    assert row["reason"] == "evaluation: ValueError: degenerate alignment"
    assert worker.decide(run).action == worker.KEEP_FAILED
    assert worker.run_one(run, redirect=False) == worker.EXIT_NOT_RUN

    trajectory = (Path(run.run_dir) / "trajectory.txt").stat()
    assert worker.run_one(run, retry_failed=True, redirect=False) == worker.EXIT_DONE
    assert (Path(run.run_dir) / "trajectory.txt").stat().st_ino == trajectory.st_ino
    row = run_row(run)
    assert row["state"] == "done" and row["ate_cm"] > 0 and row["reason"] == ""
    assert _record(run)["evaluated"] == "egs" and "evaluation_error" not in _record(run)


def test_a_timeout_during_the_evaluation_is_retried_as_an_evaluation(tmp_path: Path,
                                                                     seqs: dict[str, Path]) -> None:
    """The pool's time limit struck after the method finished: the row says timeout, nothing is
    skipped as finished, and --retry-failed only evaluates."""
    run = _run(seqs, tmp_path)
    assert worker.run_one(run, redirect=False) == worker.EXIT_DONE
    (Path(run.run_dir) / "metrics.json").unlink()  # the evaluation never got to write it
    record = _record(run)
    del record["evaluated"]
    record.update(state="timeout", reason="time limit of 1 min reached")
    worker.write_record(run.run_dir, record)
    row = run_row(run)
    assert row["state"] == "timeout" and math.isnan(row["ate_cm"])
    assert worker.decide(run).action == worker.KEEP_FAILED
    assert worker.decide(run, retry_failed=True).action == worker.EVALUATE
    assert worker.run_one(run, retry_failed=True, redirect=False) == worker.EXIT_DONE
    assert run_row(run)["state"] == "done" and run_row(run)["ate_cm"] > 0


def test_a_changed_protocol_re_evaluates_without_rerunning_the_method(tmp_path: Path,
                                                                      seqs: dict[str, Path]
                                                                      ) -> None:
    """The protocol does not change what the method computes, so it is not part of the
    configuration hash; but a run evaluated under another protocol has no numbers for this
    one: the summary shows none, and the next invocation evaluates it (only)."""
    egs = _run(seqs, tmp_path)
    mono = _run(seqs, tmp_path, protocol="monogs")
    assert (egs.run_id, egs.config_hash) == (mono.run_id, mono.config_hash)
    assert worker.run_one(egs, redirect=False) == worker.EXIT_DONE
    assert run_row(egs)["ate_cm"] > 0

    row = run_row(mono)
    assert row["state"] == "done" and math.isnan(row["ate_cm"]) and math.isnan(row["psnr_db"])
    assert "evaluated under protocol 'egs'" in row["reason"]
    assert worker.decide(mono).action == worker.EVALUATE
    trajectory = (Path(egs.run_dir) / "trajectory.txt").stat()
    assert worker.run_one(mono, redirect=False) == worker.EXIT_DONE
    assert (Path(egs.run_dir) / "trajectory.txt").stat().st_ino == trajectory.st_ino
    metrics = json.loads((Path(egs.run_dir) / "metrics.json").read_text())
    assert metrics["protocol"]["name"] == "monogs"
    assert run_row(mono)["ate_cm"] > 0 and worker.decide(mono).action == worker.SKIP
    assert math.isnan(run_row(egs)["ate_cm"])  # and the other way round
    assert worker.decide(egs).action == worker.EVALUATE


def _kill_after_start(run: RunSpec) -> None:
    """Make a finished run look like one whose worker died mid-run."""
    record = _record(run)
    record.update(state="running")
    worker.write_record(run.run_dir, record)
    status = Path(run.run_dir) / "status.json"
    status.write_text(json.dumps({**json.loads(status.read_text()), "state": "running"}))


def test_rerunning_a_killed_run_keeps_files_egs_bench_did_not_write(tmp_path: Path,
                                                                    seqs: dict[str, Path]) -> None:
    run = _run(seqs, tmp_path)
    assert worker.run_one(run, redirect=False) == worker.EXIT_DONE
    run_dir = Path(run.run_dir)
    _kill_after_start(run)
    (run_dir / "notes.txt").write_text("a user's notes")
    (run_dir / "renders" / "my_crop.png").write_bytes(b"user bytes")
    assert worker.decide(run).action == worker.RUN

    assert worker.run_one(run, redirect=False) == worker.EXIT_FAILED
    assert (run_dir / "notes.txt").read_text() == "a user's notes"
    assert (run_dir / "renders" / "my_crop.png").read_bytes() == b"user bytes"
    reason = _record(run)["reason"]
    assert "notes.txt" in reason and "renders/my_crop.png" in reason
    assert "egs-bench did not write" in reason
    assert not (run_dir / "run.yaml").exists()  # the killed run's own outputs are gone
    assert run_row(run)["state"] == "failed"

    (run_dir / "notes.txt").unlink()
    (run_dir / "renders" / "my_crop.png").unlink()
    decision = worker.decide(run)  # the failed start is tried again, and --dry-run says why
    assert decision.action == worker.RUN and "files egs-bench did not write" in decision.why
    assert worker.run_one(run, redirect=False) == worker.EXIT_DONE
    assert run_row(run)["state"] == "done" and run_row(run)["ate_cm"] > 0


def test_rerunning_a_killed_run_replaces_only_what_the_tool_wrote(tmp_path: Path,
                                                                  seqs: dict[str, Path]) -> None:
    run = _run(seqs, tmp_path)
    assert worker.run_one(run, redirect=False) == worker.EXIT_DONE
    before = sorted(p.relative_to(run.run_dir) for p in Path(run.run_dir).rglob("*"))
    _kill_after_start(run)
    (Path(run.run_dir) / "renders" / "000099.png").write_bytes(b"a render the run wrote")
    assert worker.run_one(run, redirect=False) == worker.EXIT_DONE
    after = sorted(p.relative_to(run.run_dir) for p in Path(run.run_dir).rglob("*"))
    assert after == before and _record(run)["state"] == "done"


def test_the_lock_probe_creates_nothing_and_does_not_turn_a_worker_away(tmp_path: Path,
                                                                        seqs: dict[str, Path]
                                                                        ) -> None:
    run = _run(seqs, tmp_path / "not-there")
    assert not worker.lock_is_held(run)
    assert not (tmp_path / "not-there").exists()  # works on a read-only sweep folder too

    with worker.run_lock(run) as mine:
        assert mine and worker.lock_is_held(run)
    assert not worker.lock_is_held(run)
    # a status probe (a shared lock) holds the file for a moment just as a worker starts
    fd = os.open(worker._lock_path(run), os.O_RDONLY)
    fcntl.flock(fd, fcntl.LOCK_SH)
    try:
        with worker.run_lock(run, grace_s=0.0) as mine:
            assert not mine
        threading.Timer(0.3, fcntl.flock, (fd, fcntl.LOCK_UN)).start()
        with worker.run_lock(run, grace_s=5.0) as mine:
            assert mine
    finally:
        os.close(fd)


def test_dry_run_and_status_generate_no_builtin_sequence(tmp_path: Path, seqs: dict[str, Path],
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    data = tmp_path / "data"
    data.mkdir()
    monkeypatch.setenv("EGS_BENCH_DATA", str(data))
    spec = parse_sweep({"methods": [GOOD_PATH], "sequences": ["demo", str(seqs["a"])],
                        "out": str(tmp_path / "out")}, "s.yaml")
    flag_sets: tuple[dict[str, Any], ...] = ({"dry_run": True}, {"status_only": True})
    for flags in flag_sets:
        lines: list[str] = []
        report = run_sweep(spec, say=lines.append, **flags)
        assert report.ungenerated == ["demo"]
        assert any(line.startswith("demo: built-in sequence not generated yet") for line in lines)
        assert [r.sequence_name for r in report.runs] == ["sa"]
        assert report.summary["state"].tolist() == ["pending"]
        assert not any(data.iterdir())
    typo = parse_sweep({"methods": [GOOD_PATH], "sequences": ["demo-fats"]},
                       "s.yaml")
    with pytest.raises(InputError, match="demo-fats"):
        run_sweep(typo, out=tmp_path / "out2", dry_run=True, say=lambda m: None)


def test_temporary_files_of_a_killed_writer_do_not_block_the_rerun(tmp_path: Path,
                                                                   seqs: dict[str, Path]) -> None:
    """SIGKILL between writing a file and renaming it leaves ``.<name>.<hex>.part<suffix>``
    (``fileio.atomic_path``): egs-bench's own, deleted with the run, not a user's file."""
    run = _run(seqs, tmp_path)
    assert worker.run_one(run, redirect=False) == worker.EXIT_DONE
    run_dir = Path(run.run_dir)
    _kill_after_start(run)
    for name in (".status.json.0123456789ab.part.json", "renders/.000003.png.a1b2c3d4e5f6.part.png",
                 ".map.0123456789ab.part"):
        (run_dir / name).write_bytes(b"half written")
    (run_dir / ".notes.txt.swp").write_text("an editor's file, not ours")
    assert worker.run_one(run, redirect=False) == worker.EXIT_FAILED
    assert _record(run)["reason"].count(".part") == 0
    assert ".notes.txt.swp" in _record(run)["reason"]
    (run_dir / ".notes.txt.swp").unlink()
    assert worker.run_one(run, redirect=False) == worker.EXIT_DONE
    assert not [p for p in run_dir.rglob("*.part*")]


def test_symbolic_links_are_never_followed_when_a_run_is_replaced(tmp_path: Path,
                                                                  seqs: dict[str, Path]) -> None:
    run = _run(seqs, tmp_path)
    assert worker.run_one(run, redirect=False) == worker.EXIT_DONE
    run_dir = Path(run.run_dir)
    elsewhere = tmp_path / "my_renders"
    elsewhere.mkdir()
    (elsewhere / "000001.png").write_bytes(b"a user's image named like a render")
    _kill_after_start(run)
    for f in (run_dir / "renders").iterdir():
        f.unlink()
    (run_dir / "renders").rmdir()
    (run_dir / "renders").symlink_to(elsewhere)
    assert worker.run_one(run, redirect=False) == worker.EXIT_FAILED
    assert (elsewhere / "000001.png").read_bytes() == b"a user's image named like a render"
    assert "renders" in _record(run)["reason"]

    linked = _run(seqs, tmp_path / "linked")  # the whole run folder is a link
    target = tmp_path / "real_run"
    assert worker.run_one(_run(seqs, target), redirect=False) == worker.EXIT_DONE
    Path(linked.run_dir).parent.mkdir(parents=True)
    Path(linked.run_dir).symlink_to(Path(target) / "runs" / linked.run_id)
    _kill_after_start(linked)  # its record and status, read through the link
    before = sorted(p.name for p in (Path(target) / "runs" / linked.run_id).iterdir())
    assert worker.run_one(linked, redirect=False) == worker.EXIT_FAILED
    assert sorted(p.name for p in (Path(target) / "runs" / linked.run_id).iterdir()) == before
    assert "symbolic link" in _record(linked)["reason"]


def test_metrics_replaced_or_removed_after_the_sweep_are_evaluated_again(tmp_path: Path,
                                                                         seqs: dict[str, Path]
                                                                         ) -> None:
    """``egs-bench eval --protocol monogs`` on a sweep's run (or a deleted metrics.json) leaves
    the sweep without numbers for its protocol: evaluated again, not skipped as finished."""
    from egs_bench.eval.evaluate import evaluate_run

    run = _run(seqs, tmp_path)
    assert worker.run_one(run, redirect=False) == worker.EXIT_DONE
    evaluate_run(run.run_dir, "monogs", write=True)
    assert worker.decide(run).action == worker.EVALUATE
    assert "evaluated under protocol 'monogs'" in run_row(run)["reason"]
    (Path(run.run_dir) / "metrics.json").unlink()
    assert worker.decide(run).action == worker.EVALUATE
    assert run_row(run)["reason"] == "metrics.json is missing"
    assert worker.run_one(run, redirect=False) == worker.EXIT_DONE
    assert worker.decide(run).action == worker.SKIP and run_row(run)["ate_cm"] > 0


def test_an_evaluation_failed_under_older_code_shows_failed(tmp_path: Path, seqs: dict[str, Path]
                                                            ) -> None:
    """Records written before evaluation failures failed the run: state done, an
    ``evaluation_error``, no ``evaluated``. The row and the exit status must agree with
    ``decide`` (kept as failed), not show done."""
    run = _run(seqs, tmp_path)
    assert worker.run_one(run, redirect=False) == worker.EXIT_DONE
    (Path(run.run_dir) / "metrics.json").unlink()
    record = _record(run)
    del record["evaluated"]
    record["evaluation_error"] = "ValueError: degenerate"
    worker.write_record(run.run_dir, record)
    row = run_row(run)
    assert worker.decide(run).action == worker.KEEP_FAILED
    assert row["state"] == "failed" and row["reason"] == "evaluation: ValueError: degenerate"


def test_a_run_killed_at_its_time_limit_is_not_rerun_unasked(tmp_path: Path, seqs: dict[str, Path]
                                                             ) -> None:
    """SIGKILL at the time limit leaves status.json running under a timeout record: kept like
    a failed run (rerunning would hit the limit again), rerun with --retry-failed."""
    run = _run(seqs, tmp_path)
    assert worker.run_one(run, redirect=False) == worker.EXIT_DONE
    _kill_after_start(run)
    worker.write_record(run.run_dir, {**_record(run), "state": "timeout"})
    assert worker.decide(run).action == worker.KEEP_FAILED
    assert worker.decide(run, retry_failed=True).action == worker.RUN
    assert run_row(run)["state"] == "timeout"
