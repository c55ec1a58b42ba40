"""The built site works from ``file://`` as the README says to open it: its search box is
there and finds pages (Material's ``offline`` plugin embeds the index), in headless Chromium
that, like a user's browser, may not read other local files. Also: the API reference is
rendered from the docstrings, the changelog is a page, and the notes sit under one entry."""

from __future__ import annotations

import importlib.util
import re
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.docs.test_site_build import REPO, _build
from tests.helpers.bench_scripts import load_script

pytestmark = pytest.mark.skipif(importlib.util.find_spec("mkdocs") is None,
                                reason="mkdocs is not installed (the `docs` extra)")


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("site") / "site"
    result = _build(REPO, out)
    assert result.returncode == 0, result.stderr
    return out


@pytest.fixture(scope="module")
def chromium() -> Iterator[Any]:
    scale = load_script("report_scale")
    missing = scale.chromium_missing()
    if missing:
        pytest.skip(f"headless Chromium unavailable: {missing}")
    with scale.open_chromium(file_access=False) as driver:
        yield driver


def test_search_works_from_file_urls(site: Path, chromium: Any) -> None:
    from selenium.webdriver.common.by import By

    chromium.get((site / "index.html").resolve().as_uri())
    box = chromium.find_element(By.CSS_SELECTOR, "input.md-search__input")
    # Material keeps the search hidden until its worker starts, which from file:// needs the
    # iframe-worker shim that the site ships
    assert box.is_displayed() and box.is_enabled()
    box.click()
    box.send_keys("leaderboard")
    hits: list = []
    for _ in range(100):  # the search worker answers asynchronously
        hits = chromium.find_elements(By.CSS_SELECTOR, ".md-search-result__item")
        if hits:
            break
        time.sleep(0.1)
    assert hits, chromium.find_element(By.CSS_SELECTOR, ".md-search-result__meta").text


def test_the_api_reference_renders_the_extension_points(site: Path) -> None:
    api = (site / "reference" / "api.html").read_text(encoding="utf-8")
    for name in ("slam.components.SlamComponents", "runs.registry.register_method",
                 "slam.loss_terms.LossTerm", "datasets.replica.export_replica_layout",
                 "slam.methods.ConfiguredSlamMethod", "runs.folder.RunFolder"):
        assert f'id="egs_bench.{name}"' in api, name
    # a docstring's text, not only the name: rendered from the code
    assert "Parameters:" in api or "Attributes:" in api


def test_changelog_and_records(site: Path) -> None:
    changelog = (site / "changelog.html").read_text(encoding="utf-8")
    first = (REPO / "CHANGELOG.md").read_text(encoding="utf-8").splitlines()[0].lstrip("# ")
    assert first in changelog
    index = (site / "index.html").read_text(encoding="utf-8")
    labels = re.findall(r'<span class="md-ellipsis">\s*([^<]*?)\s*</span>', index)
    assert "Records" in labels and "Notes" not in labels
    assert "javascripts/iframe-worker/shim.js" in index and "unpkg.com" not in index
