"""One broken run among good ones is footnoted and changes nothing else: its unreadable
``status.json`` or ``config.yaml`` must not make every other row's settings look different
(leaderboard labels, the report's settings columns, paper-tables headers)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
import yaml

from egs_bench.runs.folder import RunFolder
from tests.helpers.cli import run_cli

BINARY = bytes(range(256)) * 4
CONFIG = {"method": "gt", "preset": "cpu", "device": "cpu", "seed": 0,
          "slam": {"loss": {"lambda_d": 0.1, "lambda_e": 0.05}}}


@pytest.fixture
def root_with_a_broken_run(done_run: RunFolder, tmp_path: Path, request: pytest.FixtureRequest
                           ) -> Path:
    root = tmp_path / "root"
    for name in ("good", "bad"):
        shutil.copytree(done_run.path, root / name)
        (root / name / "config.yaml").write_text(yaml.safe_dump(CONFIG))
    (root / "bad" / request.param).write_bytes(BINARY)
    return root


pytestmark = pytest.mark.parametrize("root_with_a_broken_run", ["status.json", "config.yaml"],
                                     indirect=True)


def test_leaderboard_labels_only_the_broken_run(root_with_a_broken_run: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run_cli(capsys, "leaderboard", root_with_a_broken_run, "--metrics", "ate")
    assert code == 0, err
    rows = [line.split("|")[1].strip() for line in out.splitlines()
            if line.startswith("|") and not line.startswith("|:")][1:]
    assert "gt" in rows, out  # the good run's row carries no settings label
    assert not [r for r in rows if "lambda" in r or "device=" in r or "more)" in r], out
    assert f"{root_with_a_broken_run.name}/bad/" in out  # the broken run is footnoted


def test_report_has_no_settings_columns_from_a_broken_run(root_with_a_broken_run: Path,
                                                          tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]
                                                          ) -> None:
    code, _, err = run_cli(capsys, "report", root_with_a_broken_run, "-o", tmp_path / "rep")
    assert code == 0, err
    page = (tmp_path / "rep" / "index.html").read_text()
    assert "lambda_d" not in page and "device=" not in page


def test_paper_tables_headers_do_not_list_settings(root_with_a_broken_run: Path, tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run_cli(capsys, "paper-tables", root_with_a_broken_run, "--tables", "ate",
                           "-o", tmp_path / "tables")
    assert code == 0, err
    tex = "".join(p.read_text() for p in (tmp_path / "tables").glob("*.tex"))
    header = next(line for line in tex.splitlines() if "multicolumn" in line and "gt" in line)
    assert "lambda" not in header and "device" not in header, header
    assert r"{c}{gt}" in header, header
