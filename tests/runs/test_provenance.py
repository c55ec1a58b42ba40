import shutil
import subprocess
from pathlib import Path

import pytest
import yaml

from egs_bench import provenance
from egs_bench.provenance import code_revision
from egs_bench.runs.folder import RunFolder

needs_git = pytest.mark.skipif(shutil.which("git") is None, reason="git is not installed")


def _git(repo: Path, *args: str) -> str:
    return subprocess.run(["git", "-C", str(repo), "-c", "user.name=t", "-c", "user.email=t@t",
                           *args], check=True, capture_output=True, text=True).stdout.strip()


@needs_git
def test_commit_and_modified_flag_of_a_checkout(tmp_path: Path) -> None:
    repo = tmp_path / "repo"
    pkg = repo / "pkg"
    pkg.mkdir(parents=True)
    (pkg / "code.py").write_text("x = 1\n")
    _git(repo, "init", "-q")
    _git(repo, "add", ".")
    _git(repo, "commit", "-q", "-m", "first")
    first = _git(repo, "rev-parse", "HEAD")
    provenance._code_revision_cached.cache_clear()
    assert code_revision(pkg) == {"commit": first, "modified": False}

    (repo / "outputs").mkdir()  # untracked files (run outputs, caches) are not modifications
    (repo / "outputs" / "run.txt").write_text("result\n")
    provenance._code_revision_cached.cache_clear()
    assert code_revision(pkg) == {"commit": first, "modified": False}

    (pkg / "code.py").write_text("x = 2\n")  # a tracked file edited after the commit
    provenance._code_revision_cached.cache_clear()
    assert code_revision(pkg) == {"commit": first, "modified": True}

    _git(repo, "commit", "-q", "-am", "second")
    provenance._code_revision_cached.cache_clear()
    second = code_revision(pkg)
    assert second is not None and second["commit"] != first and second["modified"] is False


@needs_git
def test_outside_a_checkout_there_is_no_revision(tmp_path: Path) -> None:
    (tmp_path / "site-packages").mkdir()
    provenance._code_revision_cached.cache_clear()
    assert code_revision(tmp_path / "site-packages") is None


def test_without_git_there_is_no_revision(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("PATH", str(tmp_path))  # no git executable on the path
    provenance._code_revision_cached.cache_clear()
    assert code_revision(tmp_path) is None
    provenance._code_revision_cached.cache_clear()


def test_run_yaml_records_the_code_revision(tmp_path: Path) -> None:
    provenance._code_revision_cached.cache_clear()
    expected = code_revision()
    RunFolder.create(tmp_path / "r", method="m", sequence_name="s", sequence_path=tmp_path)
    info = yaml.safe_load((tmp_path / "r" / "run.yaml").read_text())
    assert info["code"] == expected
    assert RunFolder.open(tmp_path / "r").code_revision == expected
