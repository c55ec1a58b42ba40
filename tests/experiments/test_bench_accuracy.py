"""``benchmarks/bench_slam_accuracy.py`` end to end with fast fake methods: a relative
``--out``, ``--status`` before anything ran (pending rows, nothing started), the run and its
egs/monogs ratio, and a second invocation that resumes instead of rerunning."""

import importlib.util
import os
import subprocess
import sys
from pathlib import Path
from types import ModuleType

import numpy as np
import pandas as pd
import pytest

from egs_bench.provenance import code_revision
from tests.helpers.sweep_fixtures import FAKE_EGS_PATH, FAKE_MONOGS_PATH, make_sequence, worker_env

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_slam_accuracy.py"
METHODS = f"{FAKE_EGS_PATH},{FAKE_MONOGS_PATH}"


def _bench(*extra: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(SCRIPT), "--seq", "data/sa", "--methods", METHODS,
                           "--out", "out", *extra], cwd=cwd, capture_output=True, text=True,
                          timeout=300)


@pytest.mark.slow
def test_status_run_and_resume(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    worker_env(monkeypatch)
    make_sequence(tmp_path / "data", "sa", 8, 0)

    status = _bench("--status", cwd=tmp_path)
    assert status.returncode == 0, status.stderr
    pending = pd.read_csv(tmp_path / "out/runs.csv")
    assert list(pending["error"]) == ["pending: not started"] * 2
    assert not (tmp_path / "out/runs").exists() or not any((tmp_path / "out/runs").rglob("*.json"))
    assert "ATE(egs)/ATE(monogs)" not in status.stdout

    first = _bench(cwd=tmp_path)
    assert first.returncode == 0, first.stderr
    runs = pd.read_csv(tmp_path / "out/runs.csv", dtype={"code": str}).set_index("method")
    assert set(runs.index) == {"egs", "monogs"}
    rev = code_revision()  # both runs name the commit this checkout is at
    assert set(runs["code"]) == {"?" if rev is None else
                                 str(rev["commit"])[:7] + ("+" if rev["modified"] else "")}
    assert runs["ate_cm"].notna().all() and "error" not in runs
    # the fake estimates are the ground truth plus 1 cm / 3 cm of noise per axis
    assert runs.loc["egs", "ate_cm"] < runs.loc["monogs", "ate_cm"]
    ratio = runs.loc["egs", "ate_cm"] / runs.loc["monogs", "ate_cm"]
    assert f"sa: ATE(egs)/ATE(monogs) = {ratio:.3f}" in first.stdout
    # the summary lines are kept beside the table, not only printed
    summary = (tmp_path / "out/accuracy_summary.txt").read_text().splitlines()
    assert summary[0].startswith(f"sa: ATE(egs)/ATE(monogs) = {ratio:.3f}")
    assert all(line in first.stdout for line in summary)
    assert (tmp_path / "out/accuracy.md").read_text().count("| sa ") == 2

    first_csv = (tmp_path / "out/runs.csv").read_text()
    again = _bench(cwd=tmp_path)
    assert again.returncode == 0, again.stderr
    assert "2 runs, 2 in this invocation, 0 to run" in again.stdout
    assert (tmp_path / "out/runs.csv").read_text() == first_csv


def _load_bench() -> ModuleType:
    spec = importlib.util.spec_from_file_location("bench_slam_accuracy", SCRIPT)
    assert spec is not None and spec.loader is not None
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    return bench


def test_seed_summary_counts_only_finished_runs() -> None:
    """With several seeds, a row's mean is over the finished seeds and says how many of how
    many finished; every unfinished seed is named with its state; the egs/monogs line says
    how many seeds each side's mean has."""
    bench = _load_bench()
    runs = pd.DataFrame([
        {"sequence": "s", "method": "egs", "seed": 0, "ate_cm": 2.0, "psnr_db": 30.0,
         "code": "d9f4d77"},
        {"sequence": "s", "method": "egs", "seed": 1, "ate_cm": 4.0, "psnr_db": 28.0,
         "code": "9609709+"},
        {"sequence": "s", "method": "egs", "seed": 2, "error": "running: status is 'running'",
         "code": "9609709+"},
        {"sequence": "s", "method": "monogs", "seed": 0, "ate_cm": 5.0, "psnr_db": 26.0,
         "code": "?"},
        {"sequence": "s", "method": "monogs", "seed": 1, "error": "pending: not started"},
        {"sequence": "s", "method": "monogs", "seed": 2, "error": "pending: not started"},
    ])
    table = bench.summarise_seeds(runs).set_index("method")
    assert table.loc["egs", "ate_cm"] == 3.0 and table.loc["egs", "seeds"] == "2/3"
    assert table.loc["egs", "error"] == "seed 2: running: status is 'running'"
    assert table.loc["monogs", "seeds"] == "1/3"
    # the commits of the finished seeds, in seed order, each once
    assert table.loc["egs", "code"] == "d9f4d77, 9609709+" and table.loc["monogs", "code"] == "?"
    assert table.loc["monogs", "error"] == ("seed 1: pending: not started; "
                                            "seed 2: pending: not started")
    lines = bench.ratio_lines(table.reset_index(), [], "preset cpu")
    assert lines[0] == ("s: ATE(egs)/ATE(monogs) = 0.600, PSNR(egs) - PSNR(monogs) = +3.00 dB "
                        "(seeds finished: egs 2/3, monogs 1/3)")
    assert lines[1] == ("mean over the blurred sequences (s): ATE ratio 0.600, "
                        "PSNR gain +3.00 dB (preset cpu)")
    # monogs has one finished seed: no interval of the mean can be drawn yet
    assert bench.seed_intervals(runs, [], ["s"]) == [
        "no 95 % seed-bootstrap interval of the mean yet: it needs two finished seeds of egs "
        "and monogs on every blurred sequence"]


def _seed_runs(cells: dict[tuple[str, str], list[tuple[float, float]]]) -> pd.DataFrame:
    return pd.DataFrame([{"sequence": seq, "method": method, "seed": k, "ate_cm": ate,
                          "psnr_db": psnr}
                         for (seq, method), values in cells.items()
                         for k, (ate, psnr) in enumerate(values)])


def test_seed_bootstrap_draws_a_runs_metrics_together() -> None:
    """One replicate mean takes ATE and PSNR from the same drawn runs: with ATE + PSNR = 32 on
    every run, every replicate keeps that sum (independent draws would not)."""
    bench = _load_bench()
    runs = _seed_runs({("s", "egs"): [(2.0, 30.0), (4.0, 28.0), (3.5, 28.5)],
                       ("s", "monogs"): [(5.0, 26.0)]})
    means = bench.resample_seed_means(runs, 500, np.random.default_rng(1))
    assert set(means) == {("s", "egs")}  # one seed has no spread to resample
    egs = means["s", "egs"]
    assert egs.shape == (500, 2)
    np.testing.assert_allclose(egs.sum(axis=1), 32.0)
    assert len(np.unique(egs[:, 0])) > 3  # it did resample


def test_seed_intervals_match_the_two_seed_case() -> None:
    """Two seeds per cell: a replicate's mean is seed a's, the midpoint or seed b's with
    chances 1/4, 1/2, 1/4, so the 95 % percentile interval runs from one seed's value to the
    other's. monogs's seeds are equal, so the ratio's bounds are egs's ATE over 5 cm; the
    ablation row's difference bounds come from both rows' draws (2.5 - 4 and 3.5 - 2)."""
    bench = _load_bench()
    runs = _seed_runs({("s", "egs"): [(2.0, 30.0), (4.0, 28.0)],
                       ("s", "monogs"): [(5.0, 26.0), (5.0, 26.0)],
                       ("s", "egs-no-event-mapping"): [(2.5, 29.0), (3.5, 29.0)],
                       ("s", "egs-no-events"): [(9.0, 20.0)],
                       ("t", "egs"): [(1.0, 30.0), (1.0, 30.0)]})
    lines = bench.seed_intervals(runs, ["t"], ["s"])
    assert lines == [
        "95 % seed-bootstrap interval of the mean over the blurred sequences: ATE ratio "
        "[0.400, 0.800], PSNR gain [+2.00, +4.00] dB",
        "s: egs-no-event-mapping - egs (95 % seed-bootstrap interval): ATE [-1.50, +1.50] cm, "
        "PSNR [-1.00, +1.00] dB"]


@pytest.mark.slow
def test_numbers_come_only_from_runs_of_this_configuration(tmp_path: Path,
                                                           monkeypatch: pytest.MonkeyPatch) -> None:
    """Run folders made with another configuration (here another frame limit; the folder names
    are the same) are reported stale, not tabulated under the new label; ``--status``
    evaluates nothing."""
    worker_env(monkeypatch)
    make_sequence(tmp_path / "data", "sa", 8, 0)
    assert _bench(cwd=tmp_path).returncode == 0

    changed = _bench("--max-frames", "5", cwd=tmp_path)
    assert changed.returncode == 0, changed.stderr
    runs = pd.read_csv(tmp_path / "out/runs.csv")
    assert runs["error"].str.startswith("stale: finished with another configuration").all()
    assert "ate_cm" not in runs or runs["ate_cm"].isna().all()
    assert "ATE(egs)/ATE(monogs)" not in changed.stdout

    metrics = tmp_path / "out/runs/sa/egs/seed0/metrics.json"
    metrics.unlink()
    status = _bench("--status", cwd=tmp_path)
    assert status.returncode == 0, status.stderr
    assert not metrics.exists()
    runs = pd.read_csv(tmp_path / "out/runs.csv").set_index("method")
    assert runs.loc["egs", "error"].startswith("not_evaluated")
    assert runs.loc["monogs", "ate_cm"] > 0


@pytest.mark.slow
def test_bad_arguments_get_one_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    worker_env(monkeypatch)
    make_sequence(tmp_path / "data", "sa", 8, 0)

    def bench(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, str(SCRIPT), "--methods", METHODS, "--out", "out",
                               *args], cwd=tmp_path, capture_output=True, text=True, timeout=300,
                              env={**os.environ, "EGS_BENCH_DATA": str(tmp_path / "data")})

    for args, code, message in [
            (("--seq", "nosuch"), 1, "nosuch: no such sequence folder"),
            (("--seq", "sa", "--seed", "1", "--seed", "1"), 2, "--seed names 1 more than once"),
            (("--seq", "sa", "--device", "gpu"), 2, "invalid choice: 'gpu'"),
            (("--seq", "sa", "--set", "lambda_d=0.1"), 2, "--set applies to built-in methods"),
            (("--seq", "sa", "--methods", "nosuch"), 1, "nosuch"),
            (("--seq", "sa", "--ablation-seq", "sb"), 2,
             "--ablation-seq sb is not among the --seq sequences")]:
        result = bench(*args)
        assert result.returncode == code, (args, result.stderr)
        last = result.stderr.strip().splitlines()[-1]  # after argparse's usage, if any
        assert last.startswith("bench_slam_accuracy.py: error: ") and message in last, last
        assert "Traceback" not in result.stderr, result.stderr

    # a built-in sequence not generated yet: --status lists its runs, generates nothing
    status = bench("--seq", "demo", "--seq", "sa", "--status")
    assert status.returncode == 0, status.stderr
    runs = pd.read_csv(tmp_path / "out/runs.csv")
    assert runs.set_index("sequence").loc["demo", "error"].tolist() == [
        "pending: sequence not generated yet"] * 2
    assert sorted(p.name for p in (tmp_path / "data").iterdir()) == ["sa"]


@pytest.mark.slow
def test_from_runs_tabulates_earlier_invocations_together(tmp_path: Path) -> None:
    """Two invocations' runs.csv (seeds run apart, one run in both) give one table and one
    summary; unfinished rows are left out; a run the files disagree on, a file that is not a
    runs.csv, and no --seq / --from-runs at all each get one error line."""
    first = _seed_runs({("s", "egs"): [(2.0, 30.0)], ("s", "monogs"): [(5.0, 26.0)]})
    second = _seed_runs({("s", "egs"): [(2.0, 30.0), (4.0, 28.0)],
                         ("s", "monogs"): [(5.0, 26.0), (5.0, 26.0)]})
    second.loc[len(second)] = {"sequence": "s", "method": "egs", "seed": 2,
                               "error": "running: status is 'running'"}
    first.to_csv(tmp_path / "a.csv", index=False)
    second.to_csv(tmp_path / "b.csv", index=False)

    def bench(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, str(SCRIPT), *args], cwd=tmp_path,
                              capture_output=True, text=True, timeout=120)

    both = bench("--from-runs", "a.csv", "--from-runs", "b.csv")
    assert both.returncode == 0, both.stderr
    assert ("s: ATE(egs)/ATE(monogs) = 0.600, PSNR(egs) - PSNR(monogs) = +3.00 dB "
            "(seeds finished: egs 2/2, monogs 2/2)") in both.stdout
    assert ("interval of the mean over the blurred sequences: ATE ratio [0.400, 0.800], "
            "PSNR gain [+2.00, +4.00] dB") in both.stdout
    assert not (tmp_path / "bench_out").exists()

    first.loc[0, "ate_cm"] = 2.5
    first.to_csv(tmp_path / "a.csv", index=False)
    (tmp_path / "c.csv").write_text("sequence,method\ns,egs\n")
    # a bad input file exits 1 (sys.exit with the message), a usage error 2 (argparse)
    for args, code, message in [(("--from-runs", "a.csv", "--from-runs", "b.csv"), 1,
                                 "s/egs/seed0: a.csv and b.csv give it different numbers"),
                                (("--from-runs", "c.csv"), 1,
                                 "c.csv: not a runs.csv of this benchmark"),
                                (("--from-runs", "nosuch.csv"), 1, "nosuch.csv: cannot read it"),
                                ((), 2, "give --seq (run the benchmark) or --from-runs")]:
        result = bench(*args)
        assert result.returncode == code, (args, result.stderr)
        last = result.stderr.strip().splitlines()[-1]
        assert last.startswith("bench_slam_accuracy.py: error: ") and message in last, last


def test_documented_paper_scale_summary_is_what_the_benchmark_prints() -> None:
    """The paper-scale summary lines (BENCHMARKS.md keeps the command, its benchmark history
    note the printed lines) are the benchmark's own output on the runs it lists
    (docs/notes/paper_scale_runs.csv): the documented numbers cannot drift from the table's
    rows or from the code that summarises them."""
    root = SCRIPT.parents[1]
    assert "--from-runs docs/notes/paper_scale_runs.csv" in (root / "BENCHMARKS.md").read_text()
    text = (root / "docs/notes/benchmarks_history.md").read_text()
    command = "--from-runs docs/notes/paper_scale_runs.csv \\\n      --unblurred office-l-sharp"
    assert command in text
    block = text.split(command, 1)[1].split("\n\n", 2)[1]
    documented = [line.strip() for line in block.splitlines()]
    bench = _load_bench()
    runs = bench.combine_runs([root / "docs/notes/paper_scale_runs.csv"])
    _, printed = bench.report(runs, ["office-l-sharp"], ["office-l"], "combined runs.csv files")
    assert documented == printed
