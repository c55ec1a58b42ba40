"""mkdocs hooks (``mkdocs.yml``: ``hooks``): add the generated pages to the site at build time.

The pages are rendered from the code and the committed CSVs on every build and exist only in
memory and in ``site/``, so they cannot fall out of date and are never committed.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import cli_reference
import config_reference
import formats_reference
import results_page
from mkdocs.structure.files import File, Files

NOTES = Path(__file__).resolve().parents[1] / "notes"
CHANGELOG = Path(__file__).resolve().parents[2] / "CHANGELOG.md"

#: site path -> the function that renders its Markdown
PAGES: dict[str, Callable[[], str]] = {
    "reference/cli.md": lambda: cli_reference.render(cli_reference.egs_bench_app()),
    "reference/config.md": config_reference.render,
    "reference/formats.md": formats_reference.render,
    "results.md": lambda: results_page.render(NOTES),
    # the repository's CHANGELOG.md, as it is (one file, shown on the site too)
    "changelog.md": lambda: CHANGELOG.read_text(encoding="utf-8"),
}


def on_files(files: Files, config: Any) -> Files:
    """Append every generated page to the site's files."""
    for uri, render in PAGES.items():
        files.append(File.generated(config, uri, content=render()))
    return files


def on_config(config: Any) -> Any:
    """Fill the nav's empty ``Records`` section with every note (``docs/notes/*.md``), by
    name."""
    notes = [f"notes/{path.name}" for path in sorted(NOTES.glob("*.md"))]
    for item in config["nav"]:
        if isinstance(item, dict) and item.get("Records") == []:
            item["Records"] = notes
    return config
