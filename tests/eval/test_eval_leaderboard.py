"""Leaderboard formatting: direction-aware best/second, ties, missing and lost runs, formats."""

import io
import json
import shutil
import subprocess

import pandas as pd
import pytest

from egs_bench.errors import ConfigError, InputError
from egs_bench.eval.leaderboard import collect, leaderboard, render_markdown, to_frame
from egs_bench.runs.folder import RunFolder


def _run(root, method, seq, ate_m=None, psnr=None, ssim=None, lpips=None, protocol="egs"):
    run = RunFolder.create(root / seq / method, method=method, sequence_name=seq,
                           sequence_path=None, groundtruth=root / "gt.txt")
    run.mark_done()
    rendering = None if psnr is None else {"psnr_db": psnr, "ssim": ssim, "lpips": lpips}
    metrics = {"protocol": {"name": protocol}, "ate": {"rmse_m": ate_m}, "rendering": rendering}
    run.metrics_path.write_text(json.dumps(metrics))
    return run


@pytest.fixture
def runs(tmp_path):
    root = tmp_path / "runs"
    _run(root, "A", "s1", 0.010, 30.0, 0.90, 0.10)
    _run(root, "B", "s1", 0.020, 31.0, 0.95, 0.20)
    _run(root, "C", "s1", 0.030, 29.0, 0.80, 0.05)
    _run(root, "A", "s2", 0.011, 25.0, 0.85, 0.30)
    _run(root, "B", "s2", 0.0110004, 26.0, 0.86, 0.31)  # ties A at 2 decimals in cm
    lost = RunFolder.create(root / "s2" / "C", method="C", sequence_name="s2",
                            sequence_path=None, groundtruth=root / "gt.txt")
    lost.mark_failed("tracking lost at frame 120", tracking_lost=True)
    return root


def test_leaderboard_ranks_direction_aware(runs) -> None:
    board = collect(runs, evaluate_missing=False)
    numbers, markers = to_frame(board)
    assert list(numbers.index) == ["A", "B", "C"]
    assert numbers.loc["A", ("s1", "ate")] == pytest.approx(1.0)  # metres -> cm
    assert markers.loc["C", ("s2", "psnr")] == "L"
    assert numbers.loc["A", ("Avg.", "psnr")] == pytest.approx(27.5)
    assert markers.loc["C", ("Avg.", "psnr")] == "--"  # no average over an incomplete row

    md = render_markdown(board)
    rows = {line.split("|")[1].strip(): [c.strip() for c in line.split("|")[2:-1]]
            for line in md.splitlines() if line.startswith("| ") and "Method" not in line}
    # columns per group: ATE, PSNR, SSIM, LPIPS; groups s1, s2, Avg.
    a, b, c = rows["A"], rows["B"], rows["C"]
    assert a[0] == "**1.00**" and b[0] == "<u>2.00</u>" and c[0] == "3.00"      # ATE: lower
    assert b[1] == "**31.00**" and a[1] == "<u>30.00</u>" and c[1] == "29.00"   # PSNR: higher
    assert b[2] == "**0.950**" and a[2] == "<u>0.900</u>"                       # SSIM: higher
    assert c[3] == "**0.050**" and a[3] == "<u>0.100</u>" and b[3] == "0.200"   # LPIPS: lower
    assert a[4] == b[4] == "**1.10**"                                           # tie shares best
    assert c[4:8] == ["L"] * 4 and c[8:] == ["--"] * 4
    assert "L: C on s2 lost tracking (tracking lost at frame 120)" in md
    assert "--: no result; L: tracking lost" in md


def test_leaderboard_missing_failed_and_broken_runs_still_print(runs) -> None:
    _run(runs, "D", "s1", 0.005, 40.0, 0.99, 0.01)  # D has no run on s2
    failed = RunFolder.create(runs / "s1" / "E", method="E", sequence_name="s1",
                              sequence_path=None, groundtruth=runs / "gt.txt")
    failed.mark_failed("CUDA out of memory")
    (runs / "broken").mkdir()
    (runs / "broken" / "run.yaml").write_text("method: [unclosed")
    bad_metrics = _run(runs, "F", "s1", 0.01)
    bad_metrics.metrics_path.write_text("{not json")
    _run(runs, "G", "s1", 0.01, protocol="monogs")
    md = leaderboard(runs, "md", evaluate_missing=False)
    assert "--: no run of D on s2" in md
    assert "--: E on s1 failed (CUDA out of memory)" in md
    assert "broken: skipped" in md and "not valid YAML" in md
    assert "--: F on s1:" in md and "metrics.json: not valid JSON" in md
    assert "--: G on s1 not evaluated under protocol 'egs'" in md
    row_d = next(line for line in md.splitlines() if line.startswith("| D "))
    assert "**0.50**" in row_d and "**40.00**" in row_d


def test_leaderboard_latex_csv_and_by_method(runs, tmp_path) -> None:
    tex = leaderboard(runs, "latex", evaluate_missing=False)
    for token in (r"\toprule", r"\midrule", r"\bottomrule", r"\cmidrule(lr){2-5}",
                  r"\multicolumn{4}{c}{s1}", r"\textbf{1.00}", r"\underline{2.00}",
                  r"ATE [cm] $\downarrow$", r"PSNR [dB] $\uparrow$"):
        assert token in tex, token
    if shutil.which("pdflatex"):
        doc = ("\\documentclass{article}\\usepackage{booktabs}\\usepackage{graphicx}"
               "\\begin{document}\n" + tex + "\\end{document}\n")
        (tmp_path / "t.tex").write_text(doc)
        proc = subprocess.run(["pdflatex", "-interaction=nonstopmode", "t.tex"], cwd=tmp_path,
                              capture_output=True, text=True, timeout=120)
        assert proc.returncode == 0, proc.stdout[-2000:]
    else:
        pytest.skip("pdflatex not installed: LaTeX compiled check skipped")


def test_leaderboard_csv_and_layout(runs) -> None:
    csv = pd.read_csv(io.StringIO(leaderboard(runs, "csv", evaluate_missing=False)),
                      index_col=0, dtype=str)
    assert float(csv.loc["A", "s1/ate"]) == pytest.approx(1.0)
    assert csv.loc["C", "s2/ate"] == "L"
    by_method = leaderboard(runs, "md", by="method", evaluate_missing=False)
    row_s1 = next(line for line in by_method.splitlines() if line.startswith("| s1 "))
    cells = [c.strip() for c in row_s1.split("|")[2:-1]]
    # groups A, B, C with 4 metrics each: ATE of A best, B second, ranks across methods
    assert cells[0] == "**1.00**" and cells[4] == "<u>2.00</u>" and cells[8] == "3.00"
    assert cells[5] == "**31.00**" and cells[1] == "<u>30.00</u>" and cells[9] == "29.00"
    with pytest.raises(ConfigError, match="unknown format"):
        leaderboard(runs, "html")
    with pytest.raises(ConfigError, match="unknown metric"):
        leaderboard(runs, "md", metrics=["psnr", "chamfer"])


def test_leaderboard_empty_root(tmp_path) -> None:
    with pytest.raises(InputError, match="runs folder not found"):
        leaderboard(tmp_path / "nothing")
    with pytest.raises(InputError, match="holds no run folders"):
        leaderboard(tmp_path)
