"""``mkdocs build --strict`` builds the site with the generated pages, and fails on a broken
link or a page missing from the nav (skipped where mkdocs is not installed)."""

from __future__ import annotations

import importlib.util
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.skipif(importlib.util.find_spec("mkdocs") is None,
                                reason="mkdocs is not installed (the `docs` extra)")


def _build(project: Path, site: Path) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1",
               PYTHONPATH=os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")]))
    return subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir",
                           str(site), "--config-file", str(project / "mkdocs.yml")],
                          capture_output=True, text=True, env=env, timeout=600)


def _copy(tmp_path: Path) -> Path:
    project = tmp_path / "project"
    shutil.copytree(REPO / "docs", project / "docs")
    shutil.copy(REPO / "mkdocs.yml", project / "mkdocs.yml")
    shutil.copy(REPO / "CHANGELOG.md", project / "CHANGELOG.md")  # a page of the site
    return project


def test_strict_build_has_the_generated_pages(tmp_path: Path) -> None:
    site = tmp_path / "site"
    result = _build(REPO, site)
    assert result.returncode == 0, result.stderr
    for page in ("reference/cli.html", "reference/config.html", "reference/formats.html",
                 "results.html", "index.html", "guide/running.html"):
        assert (site / page).is_file(), page
    assert "egs-bench run" in (site / "reference" / "cli.html").read_text()
    assert not (site / "gen").exists()  # the generators are not published
    for note in (REPO / "docs" / "notes").glob("*.md"):
        assert f'href="notes/{note.stem}.html"' in (site / "index.html").read_text(), note


def test_strict_build_fails_on_a_broken_link(tmp_path: Path) -> None:
    project = _copy(tmp_path)
    index = project / "docs" / "index.md"
    index.write_text(index.read_text() + "\n[gone](guide/no-such-page.md)\n")
    result = _build(project, tmp_path / "site")
    assert result.returncode != 0 and "no-such-page.md" in result.stderr


def test_strict_build_fails_on_a_page_missing_from_the_nav(tmp_path: Path) -> None:
    project = _copy(tmp_path)
    (project / "docs" / "guide" / "orphan.md").write_text("# Orphan\n")
    result = _build(project, tmp_path / "site")
    assert result.returncode != 0 and "orphan.md" in result.stderr
