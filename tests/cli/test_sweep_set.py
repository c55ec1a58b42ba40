"""``egs-bench sweep --set`` reaches a plug-in component's fields as the sweep file's ``set:``
does, with the same checks, and reports a bad item in one error line."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from egs_bench.experiments.spec import command_line_options, expand, load_sweep
from tests.helpers.cli import assert_cli_error, run_cli
from tests.helpers.sweep_fixtures import make_sequence, worker_env
from tests.slam.test_component_configs import METHOD_PATH


def _sweep(tmp_path: Path, method: str) -> Path:
    path = tmp_path / f"{method.replace(':', '_')}.yaml"
    path.write_text(yaml.safe_dump({"methods": [method], "sequences": ["data/sa"],
                                    "preset": "cpu", "out": "out"}))
    return path


@pytest.fixture
def data(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    worker_env(monkeypatch)
    make_sequence(tmp_path / "data", "sa", 4, 0)
    monkeypatch.chdir(tmp_path)
    return tmp_path / "data"


def test_sweep_set_reaches_a_plugins_field(data: Path, tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    sweep = _sweep(tmp_path, METHOD_PATH)
    code, out, err = run_cli(capsys, "sweep", sweep, "--dry-run", "--set", "keyframes.n=3")
    assert code == 0, err
    spec = load_sweep(sweep)
    options = command_line_options(spec, ["keyframes.n=3", "lambda_d=1e-3"])
    assert options == {"keyframes.n": 3, "loss.lambda_d": 0.001}
    (run,) = expand(spec, {"data/sa": data / "sa"}, extra_options=options)
    assert run.identity["resolved"]["keyframes"]["n"] == 3
    assert run.identity["resolved"]["loss"]["lambda_d"] == 0.001


def test_sweep_set_checks_a_plugins_field_like_a_built_in(data: Path, tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]
                                                          ) -> None:
    code, _, err = run_cli(capsys, "sweep", _sweep(tmp_path, METHOD_PATH), "--dry-run",
                           "--set", "keyframes.n=three")
    assert_cli_error(code, err, 2, "SLAM option keyframes.n needs an integer, got 'three'")
    code, _, err = run_cli(capsys, "sweep", _sweep(tmp_path, "egs"), "--dry-run",
                           "--set", "keyframes.n=3")
    assert_cli_error(code, err, 2, "unknown SLAM option 'keyframes.n'")
    # a range is checked with the run's whole configuration, as for the file's ``set:``
    code, _, err = run_cli(capsys, "sweep", _sweep(tmp_path, METHOD_PATH), "--dry-run",
                           "--set", "keyframes.n=0")
    assert_cli_error(code, err, 3, "SLAM option keyframes.n must be in [1, 1000]")
