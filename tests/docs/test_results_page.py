"""The Results page: numbers computed from the CSVs, provenance from the manifest, and no CSV
left without an entry."""

from __future__ import annotations

import re
import statistics
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

import pytest

from egs_bench.errors import InputError

MANIFEST = """\
runs.csv:
  title: Small table
  date: 2026-01-02
  machine: test machine
  command: egs-bench run --method M --seed S
  note: A note.
  group_by: [sequence, method]
gpu.csv:
  title: GPU table
  date: {column: date}
  machine: {column: device}
  command: make gpu-accuracy
  group_by: [sequence, method]
  where: {status: done}
absent.csv:
  title: Not measured yet
  date: x
  machine: x
  command: x
  group_by: [sequence]
"""

RUNS = """\
sequence,method,seed,ate_cm,psnr_db
a,egs,0,1.0,20.0
a,egs,1,2.0,21.0
a,egs,2,4.0,23.5
a,monogs,0,5.5,
b,egs,0,0.25,30.0
"""

GPU = """\
sequence,method,seed,ate_cm,status,device,date
a,egs,0,1.5,done,H200,2026-02-03 10:00
a,egs,1,9.9,aborted,H200,2026-02-04 11:00
a,egs,2,2.5,done,H100,2026-02-01 09:00
"""


def _notes(tmp_path: Path, manifest: str = MANIFEST) -> Path:
    (tmp_path / "results_manifest.yaml").write_text(manifest)
    (tmp_path / "runs.csv").write_text(RUNS)
    (tmp_path / "gpu.csv").write_text(GPU)
    return tmp_path


def _cells(page: str, start: str) -> list[str]:
    line = next(line for line in page.splitlines() if line.startswith(start))
    return [cell.strip() for cell in line.strip("|").split("|")]


def test_mean_std_n_and_provenance(gen: Callable[[str], ModuleType], tmp_path: Path) -> None:
    page = gen("results_page").render(_notes(tmp_path))
    ate = [1.0, 2.0, 4.0]
    psnr = [20.0, 21.0, 23.5]
    assert _cells(page, "| a ") == [
        "a", "egs", "3", "0, 1, 2",
        f"{statistics.mean(ate):.2f} ± {statistics.stdev(ate):.2f}",
        f"{statistics.mean(psnr):.2f} ± {statistics.stdev(psnr):.2f}"]
    assert re.search(r"\| a +\| monogs +\| 1 +\| 0 +\| 5\.50 +\| +\|", page)  # no PSNR
    assert re.search(r"\| b +\| egs +\| 1 +\| 0 +\| 0\.25 +\| 30\.00 +\|", page)
    assert "- **date:** 2026-01-02" in page and "- **machine:** test machine" in page
    assert "- **command:** `egs-bench run --method M --seed S`" in page
    assert "A note." in page and "Not measured yet" not in page  # absent CSV: skipped


def test_per_row_provenance_and_row_filter(gen: Callable[[str], ModuleType], tmp_path: Path
                                           ) -> None:
    page = gen("results_page").render(_notes(tmp_path))
    gpu = page.split("## GPU table", 1)[1]
    assert "- **date:** 2026-02-01 09:00 to 2026-02-03 10:00" in gpu
    assert "- **machine:** H100, H200" in gpu
    assert re.search(r"\| a +\| egs +\| 2 +\| 0, 2 +\| 2\.00 ± 0\.71 +\|", gpu)  # no aborted run


def test_csv_without_entry_or_column_fails_naming_the_file(gen: Callable[[str], ModuleType],
                                                           tmp_path: Path) -> None:
    results = gen("results_page")
    notes = _notes(tmp_path)
    (notes / "new.csv").write_text("sequence,seed,ate_cm\na,0,1\n")
    with pytest.raises(InputError, match=r"results_manifest\.yaml: no entry for new\.csv"):
        results.render(notes)
    (notes / "new.csv").unlink()
    bad = MANIFEST.replace("group_by: [sequence, method]\ngpu.csv", "group_by: [scene]\ngpu.csv")
    _notes(tmp_path, bad)
    with pytest.raises(InputError, match=r"runs\.csv: has no column 'scene'"):
        results.render(notes)
    _notes(tmp_path, "runs.csv:\n  title: t\n")
    with pytest.raises(InputError, match="entry 'runs.csv' lacks date, machine, command"):
        results.render(notes)


def test_script_prints_the_page_or_one_error_line(gen: Callable[[str], ModuleType], tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    results = gen("results_page")
    assert results.main([str(_notes(tmp_path))]) == 0
    assert capsys.readouterr().out.startswith("# Results")
    assert results.main([str(tmp_path / "missing")]) == 3
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "results manifest not found" in err


def test_committed_csvs_all_have_entries(gen: Callable[[str], ModuleType]) -> None:
    notes = Path(__file__).resolve().parents[2] / "docs" / "notes"
    page = gen("results_page").render(notes)
    for csv in notes.glob("*.csv"):
        assert f"(notes/{csv.name})" in page
