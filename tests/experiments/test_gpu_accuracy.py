"""``benchmarks/gpu_accuracy.py`` on the CPU: resuming from the CSV, the time limit (skip what
does not fit, stop a run that overruns and record it), and the cpu-budget table's summary over
the done rows. A fake runner with a fake clock stands in for the GPU processes."""

from pathlib import Path
from typing import Any

import pandas as pd
import pytest

from tests.helpers.bench_scripts import load_script

ga = load_script("gpu_accuracy")


class FakeRunner:
    """Pretends: ``prepare`` takes 5 s, a run ``seconds[method]``; time is a counter."""

    def __init__(self, seconds: dict[str, float]) -> None:
        self.now = 0.0
        self.seconds = seconds
        self.runs: list[tuple[str, str, int]] = []
        self.prepared: list[str] = []

    def clock(self) -> float:
        return self.now

    def prepare(self, sequence: str, timeout_s: float) -> bool:
        self.prepared.append(sequence)
        self.now += 5.0
        return True

    def run(self, req: Any, timeout_s: float) -> Any:  # the script's RunRequest, RunOutcome
        self.runs.append(req.key)
        need = self.seconds[req.method]
        if need > timeout_s:
            self.now += timeout_s
            return ga.RunOutcome("aborted", timeout_s)
        self.now += need
        ate = {"egs": 1.0, "monogs": 2.0}[req.method] + 0.1 * req.seed
        return ga.RunOutcome("done", need, {"ate_cm": ate, "psnr_db": 25.0 - ate,
                                            "slam_wall_s": need})


def _seed_csv(path: Path, rows: list[dict]) -> None:
    pd.DataFrame([{c: r.get(c) for c in ga.COLUMNS} for r in rows]).to_csv(path, index=False)


def _campaign(runner: FakeRunner, csv: Path, until_s: float, out: Path, seqs: tuple[str, ...],
              methods: tuple[str, ...], seeds: tuple[int, ...], said: list[str]) -> list[Any]:
    return ga.campaign(ga.plan(out, seqs, methods, seeds), csv, until_s, runner,
                       device="cpu", code="abc1234", clock=runner.clock, say=said.append)


def test_resume_skips_done_rows_and_runs_what_fits(tmp_path: Path) -> None:
    csv = tmp_path / "runs.csv"
    _seed_csv(csv, [{"sequence": "a", "method": "egs", "seed": 0, "ate_cm": 1.0,
                     "psnr_db": 24.0, "slam_wall_s": 100.0, "status": "done"},
                    {"sequence": "a", "method": "monogs", "seed": 0, "ate_cm": 2.0,
                     "psnr_db": 23.0, "slam_wall_s": 20.0, "status": "done"}])
    runner = FakeRunner({"egs": 100.0, "monogs": 20.0})
    said: list[str] = []
    # estimates from the done rows: egs 1.15 x 100 + 60 = 175 s, monogs 83 s
    _campaign(runner, csv, 300.0, tmp_path, ("a", "b"), ("egs", "monogs"), (0, 1), said)
    # b/egs/0 at 0-105 s (with b's preparation), b/monogs/0 to 125; a/egs/1 would need 175 of
    # the 170 left after a's preparation: skipped; the monogs runs fit
    assert runner.runs == [("b", "egs", 0), ("b", "monogs", 0), ("a", "monogs", 1),
                           ("b", "monogs", 1)]
    assert runner.prepared == ["b", "a"]
    assert "skip a/egs/seed1: needs ~175 s, 170 s left" in said
    assert runner.now <= 300.0
    rows = pd.read_csv(csv)
    assert len(rows) == 6 and set(rows["status"]) == {"done"}
    assert rows.iloc[2:][["code", "device"]].drop_duplicates().values.tolist() == [
        ["abc1234", "cpu"]]

    again = FakeRunner({"egs": 100.0, "monogs": 20.0})
    _campaign(again, csv, 1000.0, tmp_path, ("a", "b"), ("egs", "monogs"), (0, 1), [])
    assert again.runs == [("a", "egs", 1), ("b", "egs", 1)]  # only what was not done
    assert len(pd.read_csv(csv)) == 8


def test_a_run_that_overruns_is_stopped_recorded_and_retried_when_it_fits(tmp_path: Path
                                                                          ) -> None:
    csv = tmp_path / "runs.csv"
    _seed_csv(csv, [{"sequence": "a", "method": "egs", "seed": 0, "ate_cm": 1.0,
                     "psnr_db": 24.0, "slam_wall_s": 10.0, "status": "done"}])
    runner = FakeRunner({"egs": 200.0})  # estimate 71.5 s, needs 200
    said: list[str] = []
    _campaign(runner, csv, 100.0, tmp_path, ("a",), ("egs",), (0, 1, 2), said)
    assert runner.runs == [("a", "egs", 1)]  # stopped at the limit: seed 2 not started
    assert runner.now == pytest.approx(100.0)
    last = pd.read_csv(csv).iloc[-1]
    assert (last["seed"], last["status"], last["slam_wall_s"]) == (1, "aborted", 95.0)

    # the aborted attempt raises its estimate to 1.15 x 95 s: it does not fit 100 s again
    second = FakeRunner({"egs": 200.0})
    said = []
    _campaign(second, csv, 100.0, tmp_path, ("a",), ("egs",), (0, 1, 2), said)
    assert said[0].startswith("skip a/egs/seed1: needs ~109 s")
    assert second.runs == [("a", "egs", 2)]

    third = FakeRunner({"egs": 200.0})
    _campaign(third, csv, 1000.0, tmp_path, ("a",), ("egs",), (0, 1, 2), [])
    assert third.runs == [("a", "egs", 1), ("a", "egs", 2)]
    rows = pd.read_csv(csv)
    assert sorted(rows.loc[rows["status"] == "done", "seed"]) == [0, 1, 2]


def test_summary_is_the_cpu_budget_tables_over_done_rows(tmp_path: Path,
                                                         capsys: pytest.CaptureFixture[str]
                                                         ) -> None:
    csv = tmp_path / "runs.csv"
    rows = [{"sequence": s, "method": m, "seed": k, "ate_cm": a * (1 + 0.1 * k),
             "psnr_db": p + 0.2 * k, "status": "done"}
            for s in ("office-l", "corridor-l") for k in (0, 1)
            for m, a, p in (("egs", 1.0, 25.0), ("monogs", 2.0, 23.0))]
    rows.append({"sequence": "office-l", "method": "egs", "seed": 2, "ate_cm": 99.0,
                 "psnr_db": 1.0, "status": "aborted"})
    _seed_csv(csv, rows)
    assert ga.main(["--summary-only", "--csv", str(csv), "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert "office-l: ATE(egs)/ATE(monogs) = 0.500, PSNR(egs) - PSNR(monogs) = +2.00 dB " \
           "(seeds finished: egs 2/2, monogs 2/2)" in out  # the aborted seed is not counted
    assert "95 % seed-bootstrap interval of the mean over the blurred sequences" in out
    assert (tmp_path / "o/accuracy_summary.txt").read_text().startswith("corridor-l: ATE")


def test_the_committed_csv_is_a_table_of_this_script() -> None:
    assert list(ga.read_rows(ga.DEFAULT_CSV).columns) == ga.COLUMNS


def test_a_csv_without_the_columns_is_one_line_naming_it(tmp_path: Path,
                                                         capsys: pytest.CaptureFixture[str]
                                                         ) -> None:
    bad = tmp_path / "bad.csv"
    bad.write_text("sequence,method\na,egs\n")
    assert ga.main(["--summary-only", "--csv", str(bad)]) == 3
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(bad) in err[0] and "no column" in err[0]
