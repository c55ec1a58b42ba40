"""Leaderboards: direction-aware ranks, seeds as mean +- std, partial runs, broken folders,
formats (long CSV with units, LaTeX compiled with pdflatex where installed)."""

import io
import json
import re
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest

from egs_bench.errors import ConfigError, InputError
from egs_bench.eval.leaderboard import (
    collect,
    leaderboard,
    render_latex,
    render_markdown,
    summary_frame,
    to_frame,
)
from egs_bench.runs.folder import RunFolder


def _run(root: Path, method: str, seq: str, ate_m: float | None = None, psnr: float | None = None,
         ssim: float | None = None, lpips: float | None = None, protocol: str = "egs",
         seed: int | None = None, config: dict[str, Any] | None = None,
         coverage: tuple[int, int] | None = None, folder: str | None = None) -> RunFolder:
    cfg = dict(config or {})
    if seed is not None:
        cfg["seed"] = seed
    path = root / seq / (folder or method) / (f"seed{seed}" if seed is not None else "")
    run = RunFolder.create(path, method=method, sequence_name=seq, sequence_path=None,
                           groundtruth=root / "gt.txt", config=cfg)
    run.mark_done()
    rendering = None if psnr is None else {"psnr_db": psnr, "ssim": ssim, "lpips": lpips}
    metrics = {"protocol": {"name": protocol}, "ate": {"rmse_m": ate_m}, "rendering": rendering}
    if coverage:
        metrics["coverage"] = {"frames_processed": coverage[0], "frames_in_sequence": coverage[1]}
    run.metrics_path.write_text(json.dumps(metrics))
    return run


def _table_rows(md: str) -> dict[str, list[str]]:
    return {line.split("|")[1].strip(): [c.strip() for c in line.split("|")[2:-1]]
            for line in md.splitlines()
            if line.startswith("| ") and not line.startswith(("| Method", "| Sequence"))}


@pytest.fixture
def runs(tmp_path: Path) -> Path:
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


def test_leaderboard_ranks_direction_aware(runs: Path) -> None:
    board = collect(runs, evaluate_missing=False)
    data = to_frame(board)
    assert list(data.mean.index) == ["A", "B", "C"]
    assert data.mean.loc["A", ("s1", "ate")] == pytest.approx(0.01)  # stored unit: metres
    assert data.marker.loc["C", ("s2", "psnr")] == "L"
    assert data.mean.loc["A", ("Avg.", "psnr")] == pytest.approx(27.5)
    assert data.marker.loc["C", ("Avg.", "psnr")] == "--"  # no average over an incomplete row

    md = render_markdown(board)
    rows = _table_rows(md)
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
    assert "±" not in md  # one run per cell: no spread claimed


def test_leaderboard_seeds_mean_std_and_counts(tmp_path: Path) -> None:
    root = tmp_path / "runs"
    ates = {"A": [0.010, 0.012, 0.014], "B": [0.020, 0.030]}
    for method, values in ates.items():
        for seed, v in enumerate(values):
            _run(root, method, "s1", v, 30.0 + seed, 0.9, 0.1, seed=seed)
    _run(root, "B", "s1", None, seed=7).mark_failed("CUDA out of memory")
    board = collect(root, evaluate_missing=False)
    md = render_markdown(board)
    rows = _table_rows(md)
    std_a = 100 * np.std(ates["A"], ddof=1)  # sample std, in cm
    assert rows["A"][0] == f"**1.20** ± {std_a:.2f}"
    # B has 2 evaluated runs of 3; the usual count is 3, so B's cell says n=2
    assert rows["B"][0] == f"<u>2.50</u> ± {100 * np.std(ates['B'], ddof=1):.2f} (n=2)"
    assert "mean ± std over 3 runs (seeds)" in md
    assert "--: B on s1 (seed 7) failed (CUDA out of memory)" in md
    assert "B on s1: mean over 2 of 3 runs" in md
    summary = summary_frame(board).set_index("method")
    assert summary.loc["A", "n_runs"] == 3 and summary.loc["B", "n_failed"] == 1
    assert summary.loc["A", "ate_rmse_m_mean"] == pytest.approx(0.012)
    assert summary.loc["A", "ate_rmse_m_std"] == pytest.approx(0.002)


def test_leaderboard_settings_rows_and_partial_runs_never_ranked(tmp_path: Path) -> None:
    root = tmp_path / "runs"
    base = {"preset": "cpu", "slam": {"lambda_d": 0.1, "iters": 10}}
    low = {"preset": "cpu", "slam": {"lambda_d": 0.05, "iters": 10}}
    _run(root, "egs", "s1", 0.020, 30.0, 0.9, 0.1, seed=0, config=base)
    _run(root, "egs", "s1", 0.030, 29.0, 0.9, 0.1, seed=0, config=low, folder="egs_low")
    # a run over 6 of 40 frames is far better, but must not be ranked with complete runs
    _run(root, "monogs", "s1", 0.001, 40.0, 0.99, 0.01, seed=0, config=base,
         coverage=(6, 40))
    _run(root, "monogs", "s1", 0.050, 25.0, 0.8, 0.3, seed=1, config=base, folder="monogs_full",
         coverage=(40, 40))
    md = render_markdown(collect(root, evaluate_missing=False))
    rows = _table_rows(md)
    assert set(rows) == {"egs (lambda_d=0.1)", "egs (lambda_d=0.05)", "monogs",
                         "monogs [partial]"}
    assert rows["egs (lambda_d=0.1)"][0] == "**2.00**"
    assert rows["egs (lambda_d=0.05)"][0] == "<u>3.00</u>"
    assert rows["monogs [partial]"][0] == "0.10"  # best number, no bold
    assert rows["monogs"][0] == "5.00"
    assert "monogs [partial] on s1: covers 6 of 40 frames; never ranked against complete " \
        "runs" in md
    order = [line.split("|")[1].strip() for line in md.splitlines()
             if line.startswith("| ") and "Method" not in line]
    assert order[-1] == "monogs [partial]"  # partial rows come last


def test_leaderboard_broken_run_folders_are_footnotes(runs: Path) -> None:
    """Binary run.yaml / status.json / trajectory.txt and wrongly typed
    metrics.json each become a footnote naming the file; the table still prints."""
    _run(runs, "D", "s1", 0.005, 40.0, 0.99, 0.01)  # D has no run on s2
    failed = RunFolder.create(runs / "s1" / "E", method="E", sequence_name="s1",
                              sequence_path=None, groundtruth=runs / "gt.txt")
    failed.mark_failed("CUDA out of memory")
    (runs / "broken").mkdir()
    (runs / "broken" / "run.yaml").write_text("method: [unclosed")
    (runs / "binary_yaml").mkdir()
    (runs / "binary_yaml" / "run.yaml").write_bytes(b"\x89PNG\r\n\x1a\n\x00\xff")
    _run(runs, "F", "s1", 0.01).metrics_path.write_text("{not json")
    _run(runs, "G", "s1", 0.01, protocol="monogs")
    _run(runs, "H", "s1", 0.01).metrics_path.write_text(json.dumps(
        {"protocol": {"name": "egs"}, "ate": {"rmse_m": "0.01"}, "rendering": None}))
    _run(runs, "I", "s1", 0.01).metrics_path.write_text(json.dumps(
        {"protocol": "egs", "ate": 5}))
    (_run(runs, "J", "s1", 0.01).path / "status.json").write_bytes(b"\xff\xfe\x00binary")
    traj = _run(runs, "K", "s1", None)
    traj.metrics_path.unlink()
    traj.trajectory_path.write_bytes(b"\x00\x01\x02\xff" * 10)
    md = leaderboard(runs, "md", evaluate_missing=True)
    assert "--: no run of D on s2" in md
    assert "--: E on s1 failed (CUDA out of memory)" in md
    assert "broken: skipped" in md and "not valid YAML" in md
    assert re.search(r"binary_yaml: skipped \(.*binary_yaml/run\.yaml: not a text file", md)
    assert "--: F on s1:" in md and "metrics.json: not valid JSON" in md
    assert "--: G on s1: not evaluated under protocol 'egs'" not in md  # evaluation attempted
    assert re.search(r"--: H on s1: .*metrics\.json: 'rmse_m' must be a number", md)
    assert re.search(r"--: I on s1: .*metrics\.json: 'protocol' must be a mapping", md)
    assert re.search(r"--: J on s1: .*status\.json: not a text file", md)
    assert re.search(r"--: K on s1: .*trajectory\.txt: not a text file", md)
    rows = _table_rows(md)
    assert "**0.50**" in rows["D"][0] and "**40.00**" in rows["D"][1]
    no_eval = leaderboard(runs, "md", evaluate_missing=False)
    assert "--: G on s1: not evaluated under protocol 'egs'" in no_eval


def test_leaderboard_long_csv_has_units_and_stays_numeric(runs: Path) -> None:
    text = leaderboard(runs, "csv", evaluate_missing=False)
    df = pd.read_csv(io.StringIO(text))
    assert list(df.columns[:7]) == ["method", "settings", "sequence", "seed", "status",
                                    "frames_processed", "frames_in_sequence"]
    for col in ("ate_rmse_m", "psnr_db", "ssim", "lpips"):
        assert df[col].dtype == float, col  # a lost run does not turn the column into text
    a1 = df[(df.method == "A") & (df.sequence == "s1")].iloc[0]
    assert a1.ate_rmse_m == pytest.approx(0.010) and a1.status == "ok"  # metres, as metrics.json
    c2 = df[(df.method == "C") & (df.sequence == "s2")].iloc[0]
    assert c2.status == "tracking_lost" and np.isnan(c2.ate_rmse_m)
    summary = pd.read_csv(io.StringIO(leaderboard(runs, "csv-summary", evaluate_missing=False)))
    assert {"ate_rmse_m_mean", "ate_rmse_m_std", "n_runs", "status"} <= set(summary.columns)
    assert summary["ate_rmse_m_mean"].dtype == float


def test_leaderboard_by_method_and_errors(runs: Path) -> None:
    by_method = leaderboard(runs, "md", by="method", evaluate_missing=False)
    cells = _table_rows(by_method)["s1"]
    # groups A, B, C with 4 metrics each: ATE of A best, B second, ranks across methods
    assert cells[0] == "**1.00**" and cells[4] == "<u>2.00</u>" and cells[8] == "3.00"
    assert cells[5] == "**31.00**" and cells[1] == "<u>30.00</u>" and cells[9] == "29.00"
    with pytest.raises(ConfigError, match="unknown format"):
        leaderboard(runs, "html")  # type: ignore[arg-type]  # the runtime check
    with pytest.raises(ConfigError, match="unknown metric"):
        leaderboard(runs, "md", metrics=["psnr", "chamfer"])
    with pytest.raises(ConfigError, match="unknown LaTeX width"):
        render_latex(collect(runs, evaluate_missing=False), width="huge")  # type: ignore[arg-type]


def test_leaderboard_empty_root(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="runs folder not found"):
        leaderboard(tmp_path / "nothing")
    with pytest.raises(InputError, match="holds no run folders"):
        leaderboard(tmp_path)


def _three_sequence_runs(root: Path) -> Path:
    for s in ("office_sequence_1", "office_sequence_2", "livingroom_3"):
        for m, base in (("egs-no-event-tracking", 0.03), ("monogs", 0.05)):
            for seed in (0, 1):
                _run(root, m, s, base + 0.001 * seed, 30.0 - seed, 0.9, 0.1, seed=seed)
    return root


def test_leaderboard_latex_options(tmp_path: Path) -> None:
    root = _three_sequence_runs(tmp_path / "my_sweep")
    tex = leaderboard(root, "latex", evaluate_missing=False)
    for token in (r"\toprule", r"\midrule", r"\bottomrule", r"\cmidrule(lr){2-5}",
                  r"\multicolumn{4}{c}{office\_sequence\_1}", r"\textbf{3.05}",
                  r"ATE [cm]$\downarrow$", r"PSNR [dB]$\uparrow$", r"{\scriptsize$\pm$0.07}"):
        assert token in tex, token
    assert r"\label{tab:my-sweep}" in tex and "tab:results" not in tex
    assert r"\begin{table*}" in tex and r"\resizebox{\ifdim\width>\textwidth" in tex
    custom = leaderboard(root, "latex", evaluate_missing=False, caption="ATE & more",
                         label="tab:mine", width="natural")
    assert r"\caption{ATE \& more}" in custom and r"\label{tab:mine}" in custom
    assert r"\resizebox" not in custom and r"\begin{table}" in custom


@pytest.mark.skipif(shutil.which("pdflatex") is None, reason="pdflatex not installed")
def test_leaderboard_latex_compiles_without_overflow(tmp_path: Path) -> None:
    """A 3-sequence table (4 groups x 4 metrics) compiles and fits the page in a two-column
    document (the old fixed `table` overflowed by 745 pt)."""
    root = _three_sequence_runs(tmp_path / "runs")
    tex = leaderboard(root, "latex", evaluate_missing=False)
    from egs_bench.experiments.latex_check import compile_latex

    log = compile_latex([tex], tmp_path / "doc", twocolumn=True)
    assert "Overfull \\hbox" not in log
    natural = leaderboard(root, "latex", evaluate_missing=False, width="natural")
    log = compile_latex([natural], tmp_path / "doc2", twocolumn=True)
    assert "Overfull \\hbox" in log  # the check can fail: the unscaled table does overflow


def test_a_signal_surfacing_inside_an_evaluation_stops_the_leaderboard(
        runs: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A SIGTERM that arrives while numba evaluates a run surfaces as a ``SystemError`` whose
    cause is the interruption; it must stop the command, not become a "broken" footnote."""
    from egs_bench.errors import Interrupted
    from egs_bench.eval import results
    from tests.helpers.interrupt_helpers import raise_sigterm_as_numba_does

    monkeypatch.setattr(results, "_load_metrics", raise_sigterm_as_numba_does)
    with pytest.raises(Interrupted):
        leaderboard(runs, "md")


def test_leaderboard_reports_frame_zero_apart_from_the_frame_rate(tmp_path: Path) -> None:
    """``--metrics fps,fps_after_init,init_s``: the loop's FPS (compile time excluded), the FPS
    without frame 0 and frame 0's seconds, from metrics.json's speed section; a run whose file
    predates the split has no value there."""
    new = _run(tmp_path, "A", "s1", ate_m=0.01)
    old = _run(tmp_path, "B", "s1", ate_m=0.02)
    data = json.loads(new.metrics_path.read_text())
    data["speed"] = {"fps": 0.5, "render_fps": 30.0, "init_s": 12.0, "fps_after_init": 0.8,
                     "compile_s": 40.0}
    new.metrics_path.write_text(json.dumps(data))
    data = json.loads(old.metrics_path.read_text())
    data["speed"] = {"fps": 0.25, "render_fps": 30.0}
    old.metrics_path.write_text(json.dumps(data))
    text = leaderboard(tmp_path, "csv", metrics=["fps", "fps_after_init", "init_s"],
                       evaluate_missing=False)
    df = pd.read_csv(io.StringIO(text)).set_index("method")
    assert df.loc["A", "fps"] == 0.5 and df.loc["A", "fps_after_init"] == 0.8
    assert df.loc["A", "init_s"] == 12.0
    assert df.loc["B", "fps"] == 0.25 and np.isnan(df.loc["B", "init_s"])
    md = leaderboard(tmp_path, "md", metrics=["fps_after_init", "init_s"], evaluate_missing=False)
    assert "FPS after frame 0" in md and "Frame 0 [s]" in md
