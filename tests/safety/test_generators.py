"""Generators that stop half-way leave no hidden staging folder behind: removed on an error or a
signal, and, after SIGKILL (no clean-up possible), by the next run."""

from __future__ import annotations

import signal
import subprocess
from pathlib import Path

import pytest

from egs_bench.cli import main
from egs_bench.datasets.sequence import Sequence
from egs_bench.fileio import FileLock, atomic_dir, clean_stale_staging
from tests.helpers.safety_helpers import python_subprocess, wait_for


def _staging(out: Path) -> list[Path]:
    return sorted(out.parent.glob(f".{out.name}.*.tmp"))


def _start_generator(out: Path, cwd: Path) -> subprocess.Popen:
    """``make-synthetic`` in another process, long enough to be caught mid-way."""
    argv = ["make-synthetic", "--scene", "office", "--out", str(out), "--frames", "400",
            "--width", "32", "--height", "24", "--no-progress"]
    proc = python_subprocess(f"import sys; from egs_bench.cli import main; "
                             f"sys.exit(main({argv!r}))", cwd)
    # Wait until frames are being written (start-up and kernel compilation done), not only the
    # folder made: in one fresh-clone CI run a SIGTERM sent right after the folder appeared
    # was reported but exited 0.
    wait_for(lambda: any(len(list((s / out.name / "rgb").glob("*.png"))) >= 3
                         for s in _staging(out)), proc)
    return proc


def test_sigterm_removes_the_staging_folder(tmp_path: Path) -> None:
    out = tmp_path / "seq"
    proc = _start_generator(out, tmp_path)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 128 + signal.SIGTERM and "interrupted by SIGTERM" in err, err
    assert list(tmp_path.iterdir()) == []  # neither the output nor a hidden staging folder


def test_a_killed_generators_staging_folder_is_removed_by_the_next_run(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "seq"
    proc = _start_generator(out, tmp_path)
    proc.send_signal(signal.SIGKILL)
    proc.communicate(timeout=60)
    left = _staging(out)
    assert len(left) == 1 and not out.exists()  # what SIGKILL leaves
    code = main(["make-synthetic", "--scene", "office", "--out", str(out), "--frames", "2",
                 "--width", "32", "--height", "24", "--no-progress"])
    assert code == 0, capsys.readouterr().err
    assert _staging(out) == [] and len(Sequence.open(out)) == 2


def test_a_live_staging_folder_is_left_alone(tmp_path: Path) -> None:
    out = tmp_path / "seq"
    live = tmp_path / ".seq.abc.tmp"
    live.mkdir()
    owner = FileLock(live / ".owner")
    assert owner.acquire()
    try:
        assert clean_stale_staging(out) == [] and live.is_dir()
    finally:
        owner.release()
    assert clean_stale_staging(out) == [live] and not live.exists()


def test_a_failed_build_leaves_nothing_and_keeps_the_old_folder(tmp_path: Path) -> None:
    out = tmp_path / "seq"
    out.mkdir()
    (out / "old.txt").write_text("old")
    with pytest.raises(RuntimeError), atomic_dir(out, replace=True) as tmp:
        tmp.mkdir()
        (tmp / "new.txt").write_text("half")
        raise RuntimeError("generator failed")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["seq"]
    assert [p.name for p in out.iterdir()] == ["old.txt"]
    with atomic_dir(out, replace=True) as tmp:
        tmp.mkdir()
        (tmp / "new.txt").write_text("complete")
    assert [p.name for p in out.iterdir()] == ["new.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["seq"]
