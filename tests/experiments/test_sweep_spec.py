"""Sweep files: validation with one-line errors, expansion, stable names, hashes, shards, slots."""

from pathlib import Path
from typing import Any

import pytest

from egs_bench.errors import ConfigError, InputError
from egs_bench.experiments.backends import plan_slots
from egs_bench.experiments.spec import (
    LocalOptions,
    expand,
    in_shard,
    load_sweep,
    parse_shard,
    parse_sweep,
)
from tests.helpers.sweep_fixtures import GOOD_PATH, make_sequence


@pytest.fixture(scope="module")
def seqs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("seqs")
    return {"a": make_sequence(root, "sa", 6, 0), "b": make_sequence(root, "sb", 6, 1)}


@pytest.mark.parametrize(("data", "message"), [
    ({"sequences": ["a"]}, "missing 'methods'"),
    ({"methods": ["egs"], "sequences": ["a"], "seed": [1]}, "unknown key(s): seed"),
    ({"methods": ["egs"], "sequences": ["a"], "seeds": ["x"]}, "'seeds' must hold integers"),
    ({"methods": ["egs"], "sequences": []}, "'sequences' is empty"),
    ({"methods": ["egs", "egs"], "sequences": ["a"]}, "'methods' lists a value twice"),
    ({"methods": ["egs"], "sequences": ["a"], "device": "tpu"}, "must be cpu or cuda"),
    ({"methods": ["egs"], "sequences": ["a"], "max_frames": 0}, "'max_frames' must be a"),
    ({"methods": ["egs"], "sequences": ["a"], "local": {"jobz": 2}}, "unknown key(s) in 'local'"),
    ({"methods": ["egs"], "sequences": ["a"], "slurm": {"timeout_min": -1}},
     "'slurm.timeout_min' must be a positive number"),
    ({"methods": ["egs"], "sequences": ["a"], "protocol": "tum"}, "unknown protocol 'tum'"),
    ({"methods": ["egs"], "sequences": ["a"], "protocol": ["egs"]}, "unknown protocol ['egs']"),
    (["egs"], "must be a YAML mapping"),
])
def test_sweep_file_errors_name_the_file(tmp_path: Path, data: Any, message: str) -> None:
    with pytest.raises(InputError) as err:
        parse_sweep(data, tmp_path / "s.yaml")
    assert message in str(err.value) and str(tmp_path / "s.yaml") in str(err.value)


def test_load_sweep_file_errors(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="sweep file not found"):
        load_sweep(tmp_path / "nope.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("methods: [egs\n")
    with pytest.raises(InputError, match="not valid YAML"):
        load_sweep(bad)
    (tmp_path / "ok.yaml").write_text("methods: [egs]\nsequences: [x]\n")
    spec = load_sweep(tmp_path / "ok.yaml")
    assert spec.seeds == (0,) and spec.presets == ("paper",) and str(spec.out) == "sweeps/ok"


def test_expand_names_hashes_and_settings(tmp_path: Path, seqs: dict[str, Path]) -> None:
    spec = parse_sweep({"methods": ["egs", "monogs"], "sequences": ["a", "b"], "seeds": [0, 1],
                        "preset": "cpu", "max_frames": 4,
                        "settings": {"base": {}, "low-d": {"lambda_d": 0.05}}}, "s.yaml")
    runs = expand(spec, seqs, tmp_path / "out")
    assert len(runs) == 2 * 2 * 2 * 2
    ids = [r.run_id for r in runs]
    assert ids[:4] == ["sa/egs__base/seed0", "sa/egs__base/seed1", "sa/egs__low-d/seed0",
                       "sa/egs__low-d/seed1"]
    assert runs[0].run_dir == str((tmp_path / "out" / "runs" / ids[0]).resolve())
    low = next(r for r in runs if r.run_id == "sa/egs__low-d/seed0")
    assert low.options == {"lambda_d": 0.05}
    assert low.identity["resolved"]["loss"]["lambda_d"] == 0.05
    # stable: the same file expands to the same names and hashes
    assert [(r.run_id, r.config_hash) for r in expand(spec, seqs, tmp_path / "out")] == \
        [(r.run_id, r.config_hash) for r in runs]
    # every ingredient of the result changes the hash, never the folder name
    changed = parse_sweep({"methods": ["egs", "monogs"], "sequences": ["a", "b"],
                           "seeds": [0, 1], "preset": "cpu", "max_frames": 5,
                           "settings": {"base": {}, "low-d": {"lambda_d": 0.05}}}, "s.yaml")
    again = expand(changed, seqs, tmp_path / "out")
    assert [r.run_id for r in again] == ids
    assert all(a.config_hash != b.config_hash for a, b in zip(runs, again, strict=True))
    forced = expand(spec, seqs, tmp_path / "out", extra_options={"tracking_iters": 3})
    assert forced[0].config_hash != runs[0].config_hash
    assert forced[0].identity["resolved"]["budget"]["tracking_iters"] == 3
    # several presets / devices enter the folder name
    multi = parse_sweep({"methods": ["egs"], "sequences": ["a"], "preset": ["cpu", "paper"]},
                        "s.yaml")
    assert [r.run_id for r in expand(multi, seqs, tmp_path)] == ["sa/egs__cpu/seed0",
                                                                 "sa/egs__paper/seed0"]


def test_expand_rejects_bad_overrides_and_methods(tmp_path: Path, seqs: dict[str, Path]) -> None:
    bad = parse_sweep({"methods": ["egs"], "sequences": ["a"], "set": {"lambda_q": 1}},
                      tmp_path / "s.yaml")
    with pytest.raises(InputError, match="unknown SLAM option 'lambda_q'"):
        expand(bad, seqs, tmp_path)
    typed = parse_sweep({"methods": ["egs"], "sequences": ["a"], "set": {"lambda_d": "x"}},
                        tmp_path / "s.yaml")
    with pytest.raises(InputError, match="lambda_d needs a finite number"):
        expand(typed, seqs, tmp_path)
    unknown = parse_sweep({"methods": ["nosuch"], "sequences": ["a"]}, tmp_path / "s.yaml")
    with pytest.raises(InputError, match="unknown method 'nosuch'"):
        expand(unknown, seqs, tmp_path)
    plugin = parse_sweep({"methods": [GOOD_PATH], "sequences": ["a"],
                          "set": {"lambda_d": 0.1}}, tmp_path / "s.yaml")
    with pytest.raises(InputError, match="is a user method"):
        expand(plugin, seqs, tmp_path)


def test_shards_partition_the_runs(tmp_path: Path, seqs: dict[str, Path]) -> None:
    spec = parse_sweep({"methods": ["egs", "monogs", "egs-no-crf"], "sequences": ["a", "b"],
                        "seeds": [0, 1, 2]}, "s.yaml")
    runs = expand(spec, seqs, tmp_path)
    parts = [[r.run_id for r in runs if in_shard(r, (i, 3))] for i in range(3)]
    assert sorted(sum(parts, [])) == sorted(r.run_id for r in runs)  # disjoint and complete
    assert all(parts)
    assert parse_shard("1/3") == (1, 3) and parse_shard(None) is None
    for text in ("3/3", "1", "a/b", "0/0"):
        with pytest.raises(ConfigError, match="--shard must be i/N"):
            parse_shard(text)


def test_plan_slots_cpu_budget_and_gpus(tmp_path: Path, seqs: dict[str, Path]) -> None:
    spec = parse_sweep({"methods": ["egs"], "sequences": ["a", "b"], "seeds": [0, 1, 2]},
                       "s.yaml")
    runs = expand(spec, seqs, tmp_path)
    slots = plan_slots(runs, LocalOptions(cpu_budget=8))
    assert len(slots) == 6 and slots[0].env["OMP_NUM_THREADS"] == "1"  # capped by the runs
    slots = plan_slots(runs, LocalOptions(cpu_budget=8), jobs=2)
    assert len(slots) == 2 and {s.env["NUMBA_NUM_THREADS"] for s in slots} == {"4"}
    slots = plan_slots(runs, LocalOptions(cpu_budget=8, threads_per_job=4))
    assert len(slots) == 2 and slots[1].env["EGS_BENCH_THREADS"] == "4"
    cuda = expand(parse_sweep({"methods": ["egs"], "sequences": ["a"], "seeds": [0, 1, 2],
                               "device": "cuda"}, "s.yaml"), seqs, tmp_path)
    slots = plan_slots(cuda, LocalOptions(cpu_budget=16), gpus=["2", "5"])
    assert [s.env["CUDA_VISIBLE_DEVICES"] for s in slots] == ["2", "5"]
    assert slots[0].env["OMP_NUM_THREADS"] == "8"
    with pytest.raises(ConfigError, match="no CUDA GPU is visible"):
        plan_slots(cuda, LocalOptions(), gpus=[])


def test_decide_from_the_run_folder(tmp_path: Path, seqs: dict[str, Path]) -> None:
    import json

    from egs_bench.experiments.worker import (
        CONFLICT,
        EVALUATE,
        KEEP_FAILED,
        RUN,
        SKIP,
        STALE,
        decide,
    )

    spec = parse_sweep({"methods": [GOOD_PATH], "sequences": ["a"]}, "s.yaml")
    run = expand(spec, seqs, tmp_path)[0]
    run_dir = tmp_path / "runs" / run.run_id

    def state(record: dict | None, status: dict | None, evaluated_under: str | None = "egs"
              ) -> str:
        run_dir.mkdir(parents=True, exist_ok=True)
        metrics = None if evaluated_under is None else {"protocol": {"name": evaluated_under},
                                                        "ate": {"rmse_m": 0.01}}
        for name, data in (("sweep.json", record), ("status.json", status),
                           ("metrics.json", metrics)):
            (run_dir / name).unlink(missing_ok=True)
            if data is not None:
                (run_dir / name).write_text(json.dumps(data))
        return decide(run).action

    ours = {"run_id": run.run_id, "config_hash": run.config_hash}
    finished = {**ours, "state": "done", "evaluated": "egs"}
    assert decide(run).action == RUN  # no folder yet
    assert state(None, {"state": "done"}) == CONFLICT  # a folder the sweep did not make
    assert state(finished, {"state": "done"}) == SKIP
    assert state({**finished, "config_hash": "x"}, {"state": "done"}) == STALE
    # metrics.json under another protocol than the sweep's (or none): only evaluated again
    assert state(finished, {"state": "done"}, evaluated_under="monogs") == EVALUATE
    assert "'monogs'" in decide(run).why and "'egs'" in decide(run).why
    assert state(finished, {"state": "done"}, evaluated_under=None) == EVALUATE
    (run_dir / "metrics.json").write_text('{"protocol": {"name": "egs"}, "ate": 5}')
    assert decide(run).action == EVALUATE  # unreadable: evaluated again, as if missing
    # the method finished, its evaluation failed (or hit the time limit): kept like a failed
    # run; --retry-failed evaluates again without rerunning the method, --force reruns it
    for record in ({**ours, "state": "failed", "evaluation_error": "ValueError: x"},
                   {**ours, "state": "timeout", "reason": "time limit of 1 min reached"},
                   {**ours, "state": "done"}):  # older records: done without "evaluated"
        assert state(record, {"state": "done"}) == KEEP_FAILED
        assert "--retry-failed" in decide(run).why
        assert decide(run, retry_failed=True).action == EVALUATE
        assert decide(run, force=True).action == RUN
    # the method itself hit the time limit: rerun only when asked
    assert state({**ours, "state": "timeout"}, {"state": "interrupted"}) == KEEP_FAILED
    assert decide(run, retry_failed=True).action == RUN
    # killed after the method finished, before its evaluation: the record still says running
    # (or interrupted, for SIGTERM); the outputs are kept and only evaluated, unless forced
    assert state({**ours, "state": "running"}, {"state": "done"}) == EVALUATE
    assert decide(run, force=True).action == RUN
    assert state({**ours, "state": "interrupted"}, {"state": "done"}) == EVALUATE
    assert state({**ours, "state": "running"}, None) == RUN
    assert state({**ours, "state": "interrupted"}, {"state": "failed"}) == RUN
    assert state({**ours, "state": "failed"}, {"state": "failed"}) == KEEP_FAILED
    assert decide(run, retry_failed=True).action == RUN
    assert state(finished, {"state": "done"}) == SKIP
    assert decide(run, force=True).action == RUN


def test_a_repeated_sigterm_during_the_interruption_record_is_ignored(
        tmp_path: Path, seqs: dict[str, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The first SIGTERM arrives during the evaluation, a second one just as the worker writes
    its ``interrupted`` record (a process-group kill followed by the pool's own SIGTERM): the
    record must still be written, saying ``interrupted``."""
    import json
    import os
    import signal

    from egs_bench.experiments import worker
    from egs_bench.interrupts import signals_interrupt

    def sigterm_self(*_args: Any, **_kwargs: Any) -> None:
        os.kill(os.getpid(), signal.SIGTERM)

    write_record = worker.write_record

    def repeat_then_write(run_dir: Path, record: dict[str, Any]) -> None:
        if record["state"] == "interrupted":
            sigterm_self()
        write_record(run_dir, record)

    monkeypatch.setattr(worker, "_evaluate", sigterm_self)
    monkeypatch.setattr(worker, "write_record", repeat_then_write)
    spec = parse_sweep({"methods": [GOOD_PATH], "sequences": ["a"]}, "s.yaml")
    run = expand(spec, seqs, tmp_path)[0]
    with signals_interrupt():
        record = worker.execute(run, redirect=False)
    assert record["state"] == "interrupted"
    saved = json.loads((tmp_path / "runs" / run.run_id / "sweep.json").read_text())
    assert saved["state"] == "interrupted" and saved["reason"] == "interrupted by SIGTERM"


def test_a_running_row_says_how_far_the_method_got(tmp_path: Path, seqs: dict[str, Path]) -> None:
    """A long run's summary row names its worker and the frame its method has reached (from
    the run's status heartbeat), so a sweep status shows progress, not only 'running'."""
    import json

    from egs_bench.experiments.sweep import run_row
    from egs_bench.experiments.worker import run_lock
    from egs_bench.runs.folder import RunFolder

    spec = parse_sweep({"methods": [GOOD_PATH], "sequences": ["a"]}, "s.yaml")
    run = expand(spec, seqs, tmp_path)[0]
    folder = RunFolder.create(run.run_dir, method="GOOD", sequence_name="sa",
                              sequence_path=seqs["a"])
    (folder.path / "sweep.json").write_text(json.dumps({
        "run_id": run.run_id, "config_hash": run.config_hash, "state": "running",
        "pid": 4242, "host": "node7"}))
    folder.set_progress(3, 6)
    folder.mark_running()  # what the next heartbeat writes
    with run_lock(run) as mine:  # the worker's lock
        assert mine
        row = run_row(run)
    assert row["state"] == "running" and row["reason"] == "pid 4242 on node7, at frame 3/6"
    folder.mark_done()
