"""Regression checks: direction-aware tolerances, missing / failed runs, planted regressions,
baseline refresh, the CLI's exit code."""

import json
from collections.abc import Mapping
from pathlib import Path

import pandas as pd
import pytest

from egs_bench.cli import main
from egs_bench.errors import InputError, OutputError
from egs_bench.experiments.regress import (
    Tolerance,
    compare,
    failed,
    load_tolerances,
    render,
    summary_of,
    update_baseline,
)
from egs_bench.runs.folder import RunFolder
from tests.helpers.cli import assert_cli_error


def _runs(root: Path, values: Mapping[tuple[str, str, int], tuple[float, float] | str]) -> Path:
    """values[(method, sequence, seed)] = (ate_m, psnr_db) or a failure kind."""
    for (method, seq, seed), v in values.items():
        run = RunFolder.create(root / seq / method / f"seed{seed}", method=method,
                               sequence_name=seq, sequence_path=None,
                               groundtruth=root / "gt.txt", config={"seed": seed})
        if v == "lost":
            run.mark_failed("lost at frame 4", tracking_lost=True)
            continue
        run.mark_done()
        run.metrics_path.write_text(json.dumps({
            "protocol": {"name": "egs"}, "ate": {"rmse_m": v[0]},
            "rendering": {"psnr_db": v[1], "ssim": 0.9, "lpips": 0.1}}))
    return root


BASE: dict[tuple[str, str, int], tuple[float, float] | str] = {
    ("egs", "s1", 0): (0.010, 30.0), ("egs", "s1", 1): (0.012, 30.2),
    ("monogs", "s1", 0): (0.020, 28.0), ("egs", "s2", 0): (0.015, 25.0)}


def test_regress_passes_on_identical_and_small_changes(tmp_path: Path) -> None:
    base = summary_of(_runs(tmp_path / "base", BASE))
    table = compare(base, base)
    assert not failed(table) and set(table["verdict"]) == {"ok"}
    assert len(table) == 3 * 4  # 3 (method, sequence) rows x ate/psnr/ssim/lpips
    small = dict(BASE)
    small[("egs", "s1", 0)] = (0.0105, 29.8)  # ATE mean +2.3 %, PSNR -0.1 dB: inside
    table = compare(base, summary_of(_runs(tmp_path / "small", small)))
    assert not failed(table)


def test_regress_fails_on_planted_regressions_direction_aware(tmp_path: Path) -> None:
    base = summary_of(_runs(tmp_path / "base", BASE))
    worse = dict(BASE)
    worse[("egs", "s1", 0)] = (0.016, 30.0)     # egs/s1 ATE mean 1.1 -> 1.4 cm: +27 %
    worse[("egs", "s2", 0)] = (0.015, 24.0)     # PSNR -1 dB
    worse[("monogs", "s1", 0)] = (0.010, 31.0)  # better on both: not a regression
    table = compare(base, summary_of(_runs(tmp_path / "worse", worse)))
    v = table.set_index(["method", "sequence", "metric"])["verdict"]
    assert v[("egs", "s1", "ate")] == "REGRESSION"
    assert v[("egs", "s2", "psnr")] == "REGRESSION"
    assert v[("monogs", "s1", "ate")] == "better" and v[("monogs", "s1", "psnr")] == "better"
    assert v[("egs", "s2", "ate")] == "ok"
    assert failed(table)
    row = table.set_index(["method", "sequence", "metric"]).loc[("egs", "s1", "ate")]
    assert row["worse_by"] == pytest.approx(0.003) and row["allowed"] == pytest.approx(0.00275)
    text = render(table)
    assert "FAILED: 2 regression(s) in 12 checks" in text
    assert "ATE [cm]" in text and "1.1000" in text and "1.4000" in text  # display unit: cm


def test_regress_missing_and_lost_runs_fail(tmp_path: Path) -> None:
    base = summary_of(_runs(tmp_path / "base", BASE))
    cur = {k: v for k, v in BASE.items() if k[1] != "s2"}  # egs on s2 did not run
    cur[("monogs", "s1", 0)] = "lost"
    cur[("new-method", "s1", 0)] = (0.01, 30.0)
    table = compare(base, summary_of(_runs(tmp_path / "cur", cur)))
    v = table.set_index(["method", "sequence", "metric"])
    assert v.loc[("egs", "s2", "ate"), "verdict"] == "missing"
    assert v.loc[("monogs", "s1", "ate"), "verdict"] == "REGRESSION"
    assert v.loc[("monogs", "s1", "ate"), "note"] == "runs tracking_lost"
    assert v.loc[("new-method", "s1", "ate"), "verdict"] == "new"
    assert failed(table)


def test_tolerance_file_and_errors(tmp_path: Path) -> None:
    tol = tmp_path / "tol.yaml"
    tol.write_text("ate: {abs: 0.01}\nlpips: null\nfps: {rel: 0.5}\n")
    loaded = load_tolerances(tol)
    assert loaded["ate"] == Tolerance(0.01, 0.0) and "lpips" not in loaded
    assert loaded["fps"].allowed(10.0) == 5.0
    for text, msg in (("chamfer: {abs: 1}", "unknown metric 'chamfer'"),
                      ("ate: {abs: -1}", "ate.abs must be a number >= 0"),
                      ("ate: {tol: 1}", "expected {abs: X, rel: Y}"),
                      ("[1]", "expected a mapping")):
        tol.write_text(text)
        with pytest.raises(InputError, match=msg.replace("{", r"\{").replace("}", r"\}")):
            load_tolerances(tol)
    with pytest.raises(InputError, match="not a results summary"):
        bad = tmp_path / "bad.csv"
        bad.write_text("a,b\n1,2\n")
        summary_of(bad)


def test_regress_cli_update_and_exit_codes(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                           ) -> None:
    base_runs = _runs(tmp_path / "base", BASE)
    baseline = tmp_path / "baseline.csv"
    assert main(["regress", str(baseline), str(base_runs), "--update"]) == 0
    saved = pd.read_csv(baseline)
    assert {"ate_rmse_m_mean", "psnr_db_mean", "n_runs"} <= set(saved.columns)
    assert main(["regress", str(baseline), str(base_runs)]) == 0
    assert "passed: 12 checks, no regression" in capsys.readouterr().out
    worse = dict(BASE)
    worse[("egs", "s2", 0)] = (0.030, 25.0)
    cur = _runs(tmp_path / "cur", worse)
    assert main(["regress", str(baseline), str(cur), "-o", str(tmp_path / "r.csv")]) == 1
    assert "FAILED: 1 regression(s)" in capsys.readouterr().out
    assert pd.read_csv(tmp_path / "r.csv")["verdict"].tolist().count("REGRESSION") == 1
    # only ATE checked, with a wide tolerance: passes
    (tmp_path / "wide.yaml").write_text("ate: {abs: 0.05}\n")
    assert main(["regress", str(baseline), str(cur), "--metrics", "ate",
                 "--tolerances", str(tmp_path / "wide.yaml")]) == 0
    (tmp_path / "folder").mkdir()
    code = main(["regress", str(tmp_path / "folder"), str(cur), "--update"])
    assert_cli_error(code, capsys.readouterr().err, 2, f"{tmp_path / 'folder'}: ", "is a folder")
    with pytest.raises(OutputError, match="is a folder"):
        update_baseline(cur, tmp_path / "folder")
