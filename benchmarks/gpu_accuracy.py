"""Paper-budget accuracy on one GPU, resumable and time-bounded (``make gpu-accuracy``).

The paper-budget counterpart of the cpu-budget table of ``bench_slam_accuracy.py``: ``egs`` and
``monogs`` with the ``paper`` preset on the 448x256 x 300-frame built-ins, seeds 0-2, one run at
a time on the GPU. Every finished run is appended to a committed CSV (default
``docs/notes/paper_budget_gpu_runs.csv``, the columns of ``docs/notes/paper_scale_runs.csv``
plus ``status, code, device, date``), so the table grows with every GPU session:

* **resume**: a (sequence, method, seed) with a ``done`` row in the CSV is not run again;
* **time limit** (``--until-s``, seconds from the start of this invocation): before each run its
  duration is estimated (:func:`estimate_s`: the longest earlier ``done`` run of the method, or
  before any the cost model's 300-frame prediction, ``gpu_cost_model.paper_scale``; never below
  the wall time of an earlier aborted attempt of the same run); a run that would not fit is
  skipped and a shorter one tried; a started run gets the time left as its limit and is stopped
  (SIGTERM: its folder is marked ``interrupted``) and recorded ``aborted`` when it overruns;
* the summary is ``bench_slam_accuracy.report`` over the ``done`` rows: the same table, ratio,
  PSNR gain and seed intervals as the cpu-budget table.

Built-in sequences are generated on first use (minutes each on the CPU side of the machine),
as a separate step before the first run that needs them, bounded by the same limit.

    python benchmarks/gpu_accuracy.py [--until-s 540] [--csv docs/notes/paper_budget_gpu_runs.csv]
        [--out bench_out/gpu_accuracy] [--device cuda] [--summary-only]
"""

from __future__ import annotations

import argparse
import datetime as _dt
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import bench_slam_accuracy  # noqa: E402 (the cpu-budget table: one implementation)
import gpu_cost_model  # noqa: E402

from egs_bench.errors import InputError  # noqa: E402
from egs_bench.fileio import read_text, write_text_atomic  # noqa: E402

SEQUENCES = ("office-l", "livingroom-l", "studio-l", "corridor-l", "office-l-sharp")
UNBLURRED = ("office-l-sharp",)
METHODS = ("egs", "monogs")
SEEDS = (0, 1, 2)
DEFAULT_CSV = ROOT / "docs" / "notes" / "paper_budget_gpu_runs.csv"
COLUMNS = ["sequence", "method", "seed", "ate_cm", "psnr_db", "ssim", "lpips", "keyframes",
           "gaussians", "slam_wall_s", "status", "code", "device", "date"]
KEY = ["sequence", "method", "seed"]
#: margin on an estimate, and the fixed cost around a run (process start, CUDA and gsplat
#: initialisation, renders and evaluation), seconds: not measured on a GPU yet, chosen generous
ESTIMATE_MARGIN = 1.15
RUN_OVERHEAD_S = 60.0
#: seconds a stopped run gets to mark its folder before it is killed
STOP_GRACE_S = 30.0


@dataclass(frozen=True)
class RunRequest:
    """One run of the campaign and its run folder."""

    sequence: str
    method: str
    seed: int
    out: Path

    @property
    def key(self) -> tuple[str, str, int]:
        return (self.sequence, self.method, self.seed)


@dataclass
class RunOutcome:
    """What a run gave: ``status`` ``done``, ``aborted`` (stopped at the time limit) or
    ``failed``; ``values`` the CSV's metric columns; ``wall_s`` the seconds it took."""

    status: str
    wall_s: float
    values: dict[str, Any] = field(default_factory=dict)


class Runner(Protocol):
    """Runs the campaign's work; the real one starts processes, the tests inject a fake."""

    def prepare(self, sequence: str, timeout_s: float) -> bool:
        """Make ``sequence`` available within ``timeout_s``; False if it could not."""

    def run(self, req: RunRequest, timeout_s: float) -> RunOutcome:
        """Run ``req``, stopping it (``aborted``) after ``timeout_s`` seconds."""


def plan(out: Path, sequences: tuple[str, ...] = SEQUENCES, methods: tuple[str, ...] = METHODS,
         seeds: tuple[int, ...] = SEEDS) -> list[RunRequest]:
    """The campaign's runs, seed by seed so that each session adds whole seeds, both methods
    of a sequence next to each other (a ratio needs both)."""
    return [RunRequest(s, m, k, out / "runs" / s / m / f"seed{k}")
            for k in seeds for s in sequences for m in methods]


def read_rows(path: Path) -> pd.DataFrame:
    """The CSV's rows (an absent file has none).

    Raises:
        InputError: the file cannot be read or lacks a column.
    """
    if not path.exists():
        return pd.DataFrame(columns=COLUMNS)
    read_text(path, "run table")  # one line naming the file when unreadable or not text
    try:
        rows = pd.read_csv(path, dtype={"code": str, "status": str})
    except (OSError, ValueError) as exc:
        raise InputError(path, f"not a CSV table ({exc})") from None
    missing = [c for c in COLUMNS if c not in rows]
    if missing:
        raise InputError(path, f"no column {', '.join(missing)}")
    return rows


def append_row(path: Path, row: dict[str, Any]) -> None:
    """Append one row, rewriting the file atomically (a reader never sees half a row)."""
    rows = read_rows(path)
    new = pd.DataFrame([{c: row.get(c) for c in COLUMNS}])
    table = new if rows.empty else pd.concat([rows, new], ignore_index=True)
    write_text_atomic(path, table[COLUMNS].to_csv(index=False))


def _is_done(rows: pd.DataFrame) -> pd.Series:
    return rows["status"].astype(str) == "done"


def estimate_s(req: RunRequest, rows: pd.DataFrame) -> float:
    """Seconds ``req`` is expected to take (module docstring)."""
    same_method = rows[(rows["method"] == req.method) & _is_done(rows)]
    if len(same_method):
        slam = float(same_method["slam_wall_s"].max())
    else:
        schedule = gpu_cost_model.paper_scale(req.method)
        slam = gpu_cost_model.predict(schedule).total_s
    estimate = ESTIMATE_MARGIN * slam + RUN_OVERHEAD_S
    tried = rows[(rows["sequence"] == req.sequence) & (rows["method"] == req.method)
                 & (rows["seed"] == req.seed) & (rows["status"].astype(str) == "aborted")]
    if len(tried):  # it ran this long and did not finish
        estimate = max(estimate, ESTIMATE_MARGIN * float(tried["slam_wall_s"].max()))
    return estimate


def campaign(requests: list[RunRequest], csv: Path, until_s: float, runner: Runner, *,
             device: str, code: str, clock: Callable[[], float] = time.monotonic,
             say: Callable[[str], None] = print) -> list[RunOutcome]:
    """Run what is not done yet, within ``until_s`` seconds from now; append each run to
    ``csv``. Returns this invocation's outcomes."""
    start = clock()
    prepared: set[str] = set()
    outcomes = []
    for req in requests:
        rows = read_rows(csv)
        done = rows[_is_done(rows)]
        if req.key in set(zip(done["sequence"], done["method"], done["seed"], strict=True)):
            continue
        left = until_s - (clock() - start)
        estimate = estimate_s(req, rows)
        name = f"{req.sequence}/{req.method}/seed{req.seed}"
        if estimate > left:
            say(f"skip {name}: needs ~{estimate:.0f} s, {left:.0f} s left")
            continue
        if req.sequence not in prepared:
            if not runner.prepare(req.sequence, left):
                say(f"stop: {req.sequence} could not be made ready in the {left:.0f} s left")
                break
            prepared.add(req.sequence)
            left = until_s - (clock() - start)
            if estimate > left:
                say(f"skip {name}: needs ~{estimate:.0f} s, {left:.0f} s left")
                continue
        say(f"run {name} (~{estimate:.0f} s, {left:.0f} s left)")
        outcome = runner.run(req, left)
        outcomes.append(outcome)
        append_row(csv, {"sequence": req.sequence, "method": req.method, "seed": req.seed,
                         **outcome.values, "slam_wall_s": outcome.values.get(
                             "slam_wall_s", round(outcome.wall_s, 1)),
                         "status": outcome.status, "code": code, "device": device,
                         "date": _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M")})
        say(f"{name}: {outcome.status} after {outcome.wall_s:.0f} s")
        if outcome.status == "aborted":
            break  # the time is up
    return outcomes


def summary(csv: Path, out: Path | None) -> list[str]:
    """Print the cpu-budget table's summary (bench_slam_accuracy.report) over the CSV's done
    rows; write it to ``out/accuracy_summary.txt`` when ``out`` is given."""
    rows = read_rows(csv)
    runs = rows[_is_done(rows)].drop(columns=["status", "device", "date"])
    if runs.empty:
        print(f"{csv}: no finished runs yet")
        return []
    _, lines = bench_slam_accuracy.report(runs.reset_index(drop=True), list(UNBLURRED), [],
                                          "preset paper, GPU")
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        write_text_atomic(out / "accuracy_summary.txt", "".join(f"{x}\n" for x in lines))
    return lines


class ProcessRunner:
    """Runs each step as an ``egs-bench`` process, so that a time limit can stop it cleanly."""

    def __init__(self, device: str) -> None:
        self.device = device

    def _call(self, cmd: list[str], timeout_s: float) -> tuple[int | None, float]:
        """Return code (None: stopped at the limit) and seconds."""
        t0 = time.monotonic()
        proc = subprocess.Popen(cmd, cwd=ROOT)
        try:
            return proc.wait(timeout=max(timeout_s, 1.0)), time.monotonic() - t0
        except subprocess.TimeoutExpired:
            proc.send_signal(signal.SIGTERM)  # egs-bench marks the run interrupted
            try:
                proc.wait(timeout=STOP_GRACE_S)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
            return None, time.monotonic() - t0

    def prepare(self, sequence: str, timeout_s: float) -> bool:
        code = ("from egs_bench.datasets.registry import resolve_sequence; "
                f"resolve_sequence({sequence!r})")
        rc, _ = self._call([sys.executable, "-c", code], timeout_s)
        return rc == 0

    def run(self, req: RunRequest, timeout_s: float) -> RunOutcome:
        cmd = [sys.executable, "-m", "egs_bench", "run", "--method", req.method, "--seq",
               req.sequence, "--preset", "paper", "--device", self.device, "--seed",
               str(req.seed), "--out", str(req.out), "--eval", "--quiet", "--overwrite"]
        req.out.parent.mkdir(parents=True, exist_ok=True)
        rc, wall = self._call(cmd, timeout_s)
        if rc is None:
            return RunOutcome("aborted", wall)
        if rc != 0:
            return RunOutcome("failed", wall)
        return RunOutcome("done", wall, read_values(req.out))


def read_values(run: Path) -> dict[str, Any]:
    """The CSV's metric columns of a finished, evaluated run folder (rounded as the cpu-budget
    CSV)."""
    import json

    from egs_bench.eval.results import read_run_result

    r = read_run_result(run, run.parent, evaluate_missing=False)
    v = r.values
    stats = json.loads(read_text(run / "slam_stats.json"))
    timing = json.loads(read_text(run / "timing.json"))

    def rounded(key: str, scale: float, digits: int) -> float | None:
        return round(scale * v[key], digits) if key in v else None

    return {"ate_cm": rounded("ate", 100, 2), "psnr_db": rounded("psnr", 1, 2),
            "ssim": rounded("ssim", 1, 3), "lpips": rounded("lpips", 1, 3),
            "keyframes": stats.get("keyframes"), "gaussians": stats.get("gaussians"),
            "slam_wall_s": round(float(timing["total_wall_s"]), 1)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--until-s", type=float, default=540.0,
                    help="stop before this many seconds from now (default 540)")
    ap.add_argument("--csv", type=Path, default=DEFAULT_CSV, help="the run table to extend")
    ap.add_argument("--out", type=Path, default=ROOT / "bench_out" / "gpu_accuracy",
                    help="folder of the run folders and the summary")
    ap.add_argument("--device", default="cuda")
    ap.add_argument("--summary-only", action="store_true", help="run nothing, summarise")
    args = ap.parse_args(argv)
    if not args.until_s > 0:
        ap.error("--until-s must be > 0")
    def act() -> int:
        if not args.summary_only:
            from egs_bench.provenance import code_revision

            code = bench_slam_accuracy._code_label(code_revision())
            os.environ.setdefault("EGS_BENCH_DATA", str(ROOT / "data"))
            campaign(plan(args.out.resolve()), args.csv, args.until_s,
                     ProcessRunner(args.device), device=args.device, code=code)
        summary(args.csv, args.out)
        return 0

    return gpu_cost_model.exit_code_of(act)


if __name__ == "__main__":
    sys.exit(main())
