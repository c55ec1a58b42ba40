"""``benchmarks/frontier.py``: budget labels (a perturbation run joins its budget's row), the
table's mean and half-range over a budget's runs, and the figure."""

from __future__ import annotations

from pathlib import Path

from tests.helpers.bench_scripts import load_script

fr = load_script("frontier")


def _row(budget: str, seed: int, perturbation: int, ate: float, blends: float,
         measured: str = "here") -> dict:
    return {"sequence": "demo-blur", "method": "egs", "budget": budget, "seed": seed,
            "perturbation": perturbation, "frames": 24, "ate_cm": ate, "psnr_db": 25.0,
            "ssim": 0.8, "lpips": 0.2, "blends_m_per_frame": blends,
            "pixels_m_per_frame": 1.0, "cameras_per_frame": 100.0, "gaussians": 1000,
            "keyframes": 5, "s_per_frame_after_init": 1.0, "measured": measured}


def test_a_perturbation_run_joins_its_budget() -> None:
    assert fr._budget(Path("runs/demo/egs__e1/seed0"), {}) == "e1"
    assert fr._budget(Path("runs/demo/egs__e1_p2/seed0"), {}) == "e1"
    assert fr._budget(Path("runs/demo/egs/seed0"), {"preset": "cpu"}) == "cpu"


def test_table_is_the_mean_and_half_range_over_runs(tmp_path: Path) -> None:
    rows = [_row("e1", 0, 0, 1.0, 70.0), _row("e1", 0, 1, 2.0, 72.0),
            _row("b05", 0, 0, 3.0, 80.0)]
    lines = fr.table(rows).splitlines()
    assert lines[2].startswith("| demo-blur | egs | e1 | 2 | 71.0 ± 1.0 | 1.50 ± 0.50 |")
    assert lines[3].startswith("| demo-blur | egs | b05 | 1 | 80.0 | 3.00 |")
    assert lines[2].endswith("| here |")
    fr.figure(rows, tmp_path / "f.png")
    assert (tmp_path / "f.png").stat().st_size > 10_000


def test_an_existing_output_is_kept_without_overwrite(tmp_path: Path) -> None:
    import subprocess
    import sys

    out = tmp_path / "mine.csv"
    out.write_text("a user's file\n")
    assert fr.__file__ is not None
    script = Path(fr.__file__)
    done = subprocess.run([sys.executable, str(script), "collect", str(tmp_path), "--out",
                           str(out), "--measured", "here"], capture_output=True, text=True)
    assert done.returncode == 2 and f"{out} exists; give --overwrite" in done.stderr
    assert out.read_text() == "a user's file\n"
    done = subprocess.run([sys.executable, str(script), "collect", str(tmp_path), "--out",
                           str(out), "--overwrite"], capture_output=True, text=True)
    assert done.returncode == 2 and "--measured" in done.stderr  # where the runs were made
    assert out.read_text() == "a user's file\n"
    done = subprocess.run([sys.executable, str(script), "collect", str(tmp_path), "--out",
                           str(out), "--overwrite", "--measured", "here"], capture_output=True,
                          text=True)
    assert done.returncode == 0, done.stderr
    assert out.read_text().startswith("sequence,method,budget,seed,perturbation")


def test_table_lists_only_the_budgets_asked_for(tmp_path: Path) -> None:
    import csv
    import subprocess
    import sys

    table = tmp_path / "runs.csv"
    with table.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=fr.COLUMNS)
        writer.writeheader()
        for row in (_row("e1", 0, 0, 1.0, 70.0), _row("b05", 0, 0, 3.0, 80.0),
                    _row("d1", 0, 0, 2.0, 75.0)):
            writer.writerow(row)
    assert fr.__file__ is not None
    done = subprocess.run([sys.executable, fr.__file__, "table", str(table), "--budgets",
                           "e1,d1"], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    budgets = [line.split(" | ")[2] for line in done.stdout.splitlines()[2:]]
    assert sorted(budgets) == ["d1", "e1"]


def test_runs_measured_elsewhere_are_never_averaged_together() -> None:
    rows = [_row("e1", 0, 0, 1.0, 70.0, "machine A"), _row("e1", 1, 0, 1.2, 70.0, "machine A"),
            _row("e1", 0, 0, 2.0, 72.0, "machine B")]
    lines = fr.table(rows).splitlines()[2:]
    assert len(lines) == 2
    assert any(" | 2 | 70.0 ± 0.0 | 1.10 ± 0.10 |" in line and "machine A" in line
               for line in lines)
    assert any(" | 1 | 72.0 | 2.00 |" in line and "machine B" in line for line in lines)


def test_append_keeps_the_rows_already_there(tmp_path: Path) -> None:
    import csv

    out = tmp_path / "runs.csv"
    with out.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=fr.COLUMNS)
        writer.writeheader()
        writer.writerow(_row("b05", 0, 0, 3.0, 80.0, "earlier"))
    new = fr.collect([tmp_path / "no_runs_here"], out, "now", append=True)
    assert new == []
    kept = fr.read_rows(out)
    assert [(r["budget"], r["measured"]) for r in kept] == [("b05", "earlier")]
