"""Regression checks that could pass while checking nothing: frame counts, unknown metrics,
unparsable or empty baselines; the committed CI baseline with 12- and 6-frame runs."""

import json
from pathlib import Path

import pandas as pd
import pytest

from egs_bench.cli import main
from egs_bench.errors import ConfigError
from egs_bench.experiments.regress import compare, failed, render, summary_of
from egs_bench.runs.folder import RunFolder
from tests.helpers.cli import assert_cli_error

BASELINE = Path(__file__).resolve().parents[2] / "benchmarks" / "regress" / "baseline.csv"


def _run(root: Path, method: str, frames: int, ate: float, psnr: float, ssim: float,
         lpips: float, seed: int = 0, sequence: str = "demo", total: int = 40) -> None:
    """A finished, evaluated run that covers ``frames`` of the sequence's ``total`` frames."""
    run = RunFolder.create(root / sequence / method / f"seed{seed}", method=method,
                           sequence_name=sequence, sequence_path=None,
                           groundtruth=root / "gt.txt", config={"seed": seed})
    run.mark_done()
    run.metrics_path.write_text(json.dumps({
        "protocol": {"name": "egs"}, "ate": {"rmse_m": ate},
        "rendering": {"psnr_db": psnr, "ssim": ssim, "lpips": lpips},
        "coverage": {"frames_processed": frames, "frames_in_sequence": total}}))


def _like_baseline(root: Path, frames: int) -> Path:
    """Runs of the CI sweep's methods with the committed baseline's means."""
    base = pd.read_csv(BASELINE)
    for _, r in base.iterrows():
        _run(root, r["method"], frames, r["ate_rmse_m_mean"], r["psnr_db_mean"],
             r["ssim_mean"], r["lpips_mean"])
    return root


def test_committed_baseline_matches_runs_over_its_12_frames(tmp_path: Path,
                                                            capsys: pytest.CaptureFixture[str]
                                                            ) -> None:
    runs = _like_baseline(tmp_path / "runs12", 12)
    assert main(["regress", str(BASELINE), str(runs)]) == 0
    assert "passed: 8 checks, no regression" in capsys.readouterr().out


def test_runs_over_other_frames_are_not_compared_and_say_so(tmp_path: Path,
                                                            capsys: pytest.CaptureFixture[str]
                                                            ) -> None:
    runs = _like_baseline(tmp_path / "runs6", 6)
    assert main(["regress", str(BASELINE), str(runs)]) == 1
    out = capsys.readouterr().out
    assert "REGRESSION" not in out and "FAILED: 8 regression(s) in 8 checks" in out
    table = compare(summary_of(BASELINE), summary_of(runs))
    missing = table[table["verdict"] == "missing"]
    assert len(missing) == 8 and set(missing["frames"]) == {"12"}
    assert set(missing["note"]) == {"no run over 12 frames; the runs cover 6 frames "
                                    "(incomplete)"}
    new = table[table["verdict"] == "new"]
    assert set(new["frames"]) == {"6"} and set(new["note"]) == {
        "the baseline has 12 frames (incomplete)"}


def test_summary_records_the_frames_and_mixed_counts(tmp_path: Path) -> None:
    root = tmp_path / "runs"
    _run(root, "egs", 6, 0.01, 20, 0.8, 0.2, seed=0)
    _run(root, "egs", 12, 0.01, 20, 0.8, 0.2, seed=1)
    _run(root, "monogs", 40, 0.01, 20, 0.8, 0.2)
    df = summary_of(root).set_index("method")
    assert df.loc["egs", "frames"] == "6/12" and not df.loc["egs", "complete"]
    assert df.loc["monogs", "frames"] == "40" and df.loc["monogs", "complete"]
    csv = tmp_path / "s.csv"
    csv.write_text(df.reset_index().to_csv(index=False))
    again = summary_of(csv).set_index("method")
    assert again.loc["egs", "frames"] == "6/12" and again.loc["monogs", "frames"] == "40"


def test_unparsable_baseline_cells_are_an_error_not_new(tmp_path: Path,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    runs = _like_baseline(tmp_path / "runs12", 12)
    bad = tmp_path / "abc.csv"
    text = BASELINE.read_text().splitlines()
    cells = text[2].split(",")
    cells[text[0].split(",").index("ate_rmse_m_mean")] = "abc"
    bad.write_text("\n".join([*text[:2], ",".join(cells)]) + "\n")
    code = main(["regress", str(bad), str(runs)])
    assert_cli_error(code, capsys.readouterr().err, 3,
                     f"{bad}: line 3: ate_rmse_m_mean is 'abc', not a number")
    ate = text[1].split(",")[text[0].split(",").index("ate_rmse_m_mean")]  # line 2's value
    for value in ("nan", "inf"):
        bad.write_text(BASELINE.read_text().replace(ate, value, 1))
        code = main(["regress", str(bad), str(runs)])
        assert_cli_error(code, capsys.readouterr().err, 3, f"line 2: ate_rmse_m_mean is '{value}'")


def test_unknown_or_unchecked_metrics_are_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                                  ) -> None:
    runs = _like_baseline(tmp_path / "runs12", 12)
    for metrics, message in (("foo", "unknown metric 'foo' to check"),
                             ("ate,foo", "unknown metric 'foo' to check"),
                             ("fps", "metric 'fps' has no tolerance"),
                             (",", "no metric to check")):
        code = main(["regress", str(BASELINE), str(runs), "--metrics", metrics])
        assert_cli_error(code, capsys.readouterr().err, 2, message)
    tol = tmp_path / "tol.yaml"
    tol.write_text("ate: null\n")
    code = main(["regress", str(BASELINE), str(runs), "--metrics", "ate", "-t", str(tol)])
    assert_cli_error(code, capsys.readouterr().err, 2, "metric 'ate' has no tolerance")
    with pytest.raises(ConfigError, match="unknown metric 'foo'"):
        compare(summary_of(BASELINE), summary_of(runs), metrics=["foo"])


def test_a_check_that_compares_nothing_fails(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                             ) -> None:
    runs = _like_baseline(tmp_path / "runs12", 12)
    empty = tmp_path / "empty.csv"
    df = pd.read_csv(BASELINE)
    for col in df.columns:
        if col.endswith(("_mean", "_std")):
            df[col] = float("nan")
    empty.write_text(df.to_csv(index=False))
    code = main(["regress", str(empty), str(runs)])
    assert_cli_error(code, capsys.readouterr().err, 3,
                     f"{empty}: holds no value of ate, psnr, ssim, lpips")
    # only new rows: nothing was compared, which is no pass
    table = compare(summary_of(BASELINE).iloc[0:0], summary_of(runs))
    assert set(table["verdict"]) == {"new"} and failed(table)
    assert "FAILED: nothing compared with the baseline" in render(table)


def test_baseline_without_frames_column_asks_for_a_refresh(tmp_path: Path,
                                                           capsys: pytest.CaptureFixture[str]
                                                           ) -> None:
    runs = _like_baseline(tmp_path / "runs12", 12)
    old = tmp_path / "old.csv"
    old.write_text(pd.read_csv(BASELINE).drop(columns="frames").to_csv(index=False))
    code = main(["regress", str(old), str(runs)])
    assert_cli_error(code, capsys.readouterr().err, 3, f"{old}: has no 'frames' column",
                     "--update")
