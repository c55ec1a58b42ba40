"""Sizes and numbers the user types: every count has a declared range, checked before a run
folder exists; a render that cannot fit in memory is refused before it is allocated; ``1e-3``
is a number wherever a number is expected, although YAML 1.1 reads it as a string."""

from __future__ import annotations

import dataclasses
import json
import typing
from pathlib import Path
from typing import Any

import pytest
import yaml

from egs_bench.errors import ConfigError
from egs_bench.slam import config
from tests.helpers.cli import assert_cli_error, run_cli
from tests.helpers.safety_helpers import QUICK_RUN

HUGE = 10**20  # beyond int64: numpy and torch refuse it deep inside a run


def _integer_fields() -> list[str]:
    keys = []
    for group, cls in config.GROUPS.items():
        hints = typing.get_type_hints(cls)
        for f in dataclasses.fields(cls):
            if int in (typing.get_args(hints[f.name]) or (hints[f.name],)):
                keys.append(f"{group}.{f.name}")
    return keys


@pytest.mark.parametrize("key", _integer_fields())
def test_every_count_has_an_upper_bound(key: Any) -> None:
    base = config.cpu_preset()
    with pytest.raises(ConfigError, match=key):
        base.replace(**{key: HUGE}).validate()


def test_a_huge_count_is_refused_before_the_run_folder_exists(tiny_sequence: Path, tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str]
                                                              ) -> None:
    out = tmp_path / "run"
    code, _, err = run_cli(capsys, "run", "--method", "egs", "--seq", tiny_sequence, "--out",
                           out, *QUICK_RUN, "--set", f"method.crf_nodes={HUGE}")
    assert_cli_error(code, err, 2, "method.crf_nodes must be in [2, 1024]")
    assert not out.exists()


@pytest.mark.parametrize("text,key,value", [
    ("lambda_d=1e-3", "loss.lambda_d", 1e-3),
    ("resolution_scale=5e-1", "budget.resolution_scale", 0.5),
    ("lr_means=+2E-4", "budget.lr_means", 2e-4),
    ("theta=.25", "method.theta", 0.25),  # an optional number
])
def test_exponent_notation_is_a_number(text: str, key: str, value: float) -> None:
    assert config.parse_overrides([text]) == {key: value}


@pytest.mark.parametrize("text,message", [
    ("lambda_d=1e-3x", "needs a finite number, got '1e-3x'"),
    ("crf_nodes=1e3", "needs an integer, got '1e3'"),  # a float's notation for a count
    ("lambda_d=inf", "needs a finite number, got inf"),
])
def test_strings_that_are_not_numbers_stay_refused(text: str, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        config.parse_overrides([text])


def test_run_set_takes_exponent_notation(tiny_sequence: Path, tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "run"
    code, _, err = run_cli(capsys, "run", "--method", "monogs", "--seq", tiny_sequence,
                           "--out", out, *QUICK_RUN, "--max-frames", "2",
                           "--set", "lambda_d=1e-3")
    assert code == 0, err
    assert yaml.safe_load((out / "config.yaml").read_text())["slam"]["loss"]["lambda_d"] == 1e-3


@pytest.mark.slow
def test_sweep_set_takes_exponent_notation(room_sequence: Path, tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    sweep = tmp_path / "sweep.yaml"
    # written as a user types it: PyYAML reads this `1e-3` as the string "1e-3"
    sweep.write_text(f"sequences: [{room_sequence}]\nmethods: [monogs]\npreset: cpu\n"
                     "set: {lambda_d: 1e-3, init_iters: 2, tracking_iters: 2, "
                     "mapping_iters: 1, resolution_scale: 1.0}\nprotocol: egs\n")
    assert yaml.safe_load(sweep.read_text())["set"]["lambda_d"] == "1e-3"
    code, _, err = run_cli(capsys, "sweep", sweep, "--out", tmp_path / "sw", "--jobs", "1")
    assert code == 0, err
    (run_dir,) = [p.parent for p in (tmp_path / "sw").rglob("config.yaml")]
    assert yaml.safe_load((run_dir / "config.yaml").read_text())["slam"]["loss"]["lambda_d"] == 1e-3
    assert json.loads((run_dir / "status.json").read_text())["state"] == "done"


def test_render_map_refuses_a_size_that_cannot_fit(tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    from tests.safety.test_outputs import _ply

    ply = _ply(tmp_path)
    out = tmp_path / "v.png"
    code, _, err = run_cli(capsys, "render-map", ply, "-o", out, "--width", "100000",
                           "--height", "100000")
    assert_cli_error(code, err, 2, "--width 100000 x --height 100000", "GiB")
    assert not out.exists()
    assert not list(Path(tmp_path).glob(".v.png*"))
