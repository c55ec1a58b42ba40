"""Components carry their own configuration: a plug-in's fields are set with ``--set`` and
checked like a built-in's, listed on the configuration page, and recorded with the component's
import path in ``config.yaml``; ``run --config`` re-runs a stored configuration to the same
trajectory, and configuration files in the layouts of earlier versions still load."""

from __future__ import annotations

import dataclasses
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np
import pytest
import yaml

from egs_bench.cli import main
from egs_bench.errors import ConfigError
from egs_bench.slam import methods
from egs_bench.slam.components import SlamComponents
from egs_bench.slam.config import ALIASES, Bounds, KeyframeConfig, SlamConfig, cpu_preset
from egs_bench.slam.context import SlamContext
from egs_bench.slam.keyframes import KeyframeCandidate, MonoGSKeyframes
from tests.helpers.cli import assert_cli_error

QUICK = ["--preset", "cpu", "--quiet", "--set", "init_iters=2", "--set", "tracking_iters=2",
         "--set", "mapping_iters=1"]


@dataclass(frozen=True)
class EveryNthConfig(KeyframeConfig):
    """MonoGS's window rules, and a keyframe every ``n`` frames."""

    n: int = 2  # frames from one keyframe to the next
    RANGES: ClassVar[dict[str, Bounds]] = {"n": Bounds(low=1, high=1000)}


class EveryNthFrame:
    """A keyframe policy with its own setting (``keyframes.n``)."""

    Config: ClassVar[type] = EveryNthConfig

    def __init__(self, ctx: SlamContext) -> None:
        rules = ctx.cfg.keyframes
        assert isinstance(rules, EveryNthConfig)  # what Config puts in the group
        self.rules = rules
        self.window = MonoGSKeyframes(self.rules, ctx.cfg.budget.window_size)

    def is_keyframe(self, candidate: KeyframeCandidate) -> bool:
        return candidate.frame_idx - candidate.last_kf_idx >= self.rules.n

    def update_window(self, window: list[int], new_kf: int, visibility: dict[int, np.ndarray],
                      poses_cw: dict[int, np.ndarray]) -> tuple[list[int], list[int]]:
        return self.window.update_window(window, new_kf, visibility, poses_cw)


METHOD = dataclasses.replace(methods.BUILTIN["egs"], name="egs-every-nth",
                             components=SlamComponents(keyframes=EveryNthFrame))
METHOD_PATH = f"{__name__}:METHOD"


def _run(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    code = main(["run", *args])
    return code, capsys.readouterr().err


def test_a_plugins_field_is_set_checked_and_recorded(tiny_sequence: Path, tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "n1"
    code, err = _run(["--method", METHOD_PATH, "--seq", str(tiny_sequence), "--out", str(out),
                      *QUICK, "--set", "keyframes.n=1"], capsys)
    assert code == 0, err
    stored = yaml.safe_load((out / "config.yaml").read_text())
    assert stored["slam"]["keyframes"]["n"] == 1
    assert stored["slam"]["keyframes"]["interval"] == KeyframeConfig().interval
    assert stored["components"]["keyframes"] == {
        "target": f"{__name__}:EveryNthFrame", "config": "keyframes",
        "config_class": f"{__name__}:EveryNthConfig"}
    assert (out / "keyframes.txt").read_text().split() == ["0", "1", "2", "3"]
    for value, words in [("0", "SLAM option keyframes.n must be in [1, 1000]"),
                         ("two", "SLAM option keyframes.n needs an integer")]:
        code, err = _run(["--method", METHOD_PATH, "--seq", str(tiny_sequence), "--out",
                          str(tmp_path / f"bad-{value}"), *QUICK, "--set", f"keyframes.n={value}"],
                         capsys)
        assert_cli_error(code, err, 2, words)
        assert not (tmp_path / f"bad-{value}").exists()
    # a built-in method has no such field
    code, err = _run(["--method", "egs", "--seq", str(tiny_sequence), *QUICK,
                      "--set", "keyframes.n=3"], capsys)
    assert_cli_error(code, err, 2, "unknown SLAM option 'keyframes.n'")


def test_a_plugins_config_is_the_group_the_component_reads() -> None:
    cfg = METHOD.config("cpu")
    assert isinstance(cfg.keyframes, EveryNthConfig) and cfg.keyframes.n == 2
    assert cfg.budget == cpu_preset().budget  # the preset still decides the budget
    three = METHOD.with_options(methods.parse_method_options(METHOD, ["keyframes.n=3"]))
    keyframes = three.config("cpu").keyframes
    assert isinstance(keyframes, EveryNthConfig) and keyframes.n == 3
    assert SlamConfig.from_dict(three.config("cpu").to_dict(),
                                METHOD.config_classes()) == three.config("cpu")
    with pytest.raises(TypeError, match="extending KeyframeConfig"):
        cpu_preset().with_groups({"keyframes": dict})
    assert not isinstance(methods.BUILTIN["egs"].config("cpu").keyframes, EveryNthConfig)


def test_every_built_in_part_declares_the_ranged_frozen_config_of_its_group() -> None:
    import typing

    from egs_bench.slam.components import ROLE_GROUPS
    from egs_bench.slam.config import GROUPS, RANGES, LossConfig
    from egs_bench.slam.loss_terms import LOSS_TERMS

    parts = SlamComponents()
    declared = {group: getattr(parts, role).Config for role, group in ROLE_GROUPS.items()}
    assert declared == {group: GROUPS[group] for group in ROLE_GROUPS.values()}
    assert all(term.config is None for term in LOSS_TERMS)
    assert parts.config_classes() == GROUPS and GROUPS["loss"] is LossConfig
    for group, cls in parts.config_classes().items():
        first = dataclasses.fields(cls)[0].name
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(cls(), first, getattr(cls(), first))
        for f in dataclasses.fields(cls):
            kinds = set(typing.get_args(typing.get_type_hints(cls)[f.name])) or {
                typing.get_type_hints(cls)[f.name]}
            if kinds & {int, float}:
                assert f"{group}.{f.name}" in RANGES, f"{group}.{f.name} has no range"


def test_the_convergence_rule_and_the_schedule_read_their_own_recorded_configs() -> None:
    """Each is built from its own frozen config class, a base of its group's class (the
    spellings ``tracking.convergence*`` and ``mapping.mapping_mode`` stay), whose numbers have
    ranges, and ``config.yaml`` records it with the replaceable parts."""
    import torch

    from egs_bench.slam.components import FIXED_PARTS
    from egs_bench.slam.config import (
        GROUPS,
        RANGES,
        ConvergenceConfig,
        ScheduleConfig,
        parse_overrides,
    )
    from egs_bench.slam.convergence import ConvergenceTest
    from egs_bench.slam.scheduling import ConcurrentMapping

    assert {role: (part.Config, group) for role, (part, group) in FIXED_PARTS.items()} == {
        "convergence": (ConvergenceConfig, "tracking"), "schedule": (ScheduleConfig, "mapping")}
    for part, group in FIXED_PARTS.values():
        assert issubclass(GROUPS[group], part.Config)
        with pytest.raises(dataclasses.FrozenInstanceError):
            part.Config().__setattr__(dataclasses.fields(part.Config)[0].name, None)
    assert {"tracking.convergence_tolerance", "tracking.convergence_patience"} <= set(RANGES)

    cfg = cpu_preset().replace(**parse_overrides(
        ["convergence=plateau", "tracking.convergence_patience=7", "mapping_mode=concurrent"]))
    test = ConvergenceTest.from_config(cfg.validate().tracking)
    assert (test.rule, test.tolerance, test.patience) == ("plateau", 0.1, 7)
    scheduled = ConcurrentMapping.scheduled(cfg.mapping, 3, torch.device("cpu"), print)
    assert scheduled is not None and scheduled.per_frame == 3
    assert ConcurrentMapping.scheduled(cpu_preset().mapping, 3, torch.device("cpu"),
                                       print) is None
    with pytest.raises(ConfigError, match="tracking.convergence_patience must be in"):
        cfg.replace(convergence_patience=0).validate()

    record = METHOD.components.record() if METHOD.components else {}
    assert record["convergence"] == {
        "target": "egs_bench.slam.convergence:ConvergenceTest", "config": "tracking",
        "config_class": "egs_bench.slam.config:ConvergenceConfig"}
    assert record["schedule"] == {
        "target": "egs_bench.slam.scheduling:ConcurrentMapping", "config": "mapping",
        "config_class": "egs_bench.slam.config:ScheduleConfig"}


def test_a_sweeps_settings_reach_a_plugins_fields() -> None:
    from egs_bench.experiments.spec import typed_options

    assert typed_options({"keyframes.n": 3, "lambda_d": "1e-3"}, METHOD) == {
        "keyframes.n": 3, "loss.lambda_d": 0.001}
    with pytest.raises(ConfigError, match="SLAM option keyframes.n needs an integer"):
        typed_options({"keyframes.n": "three"}, METHOD)
    with pytest.raises(ConfigError, match="unknown SLAM option 'keyframes.n'"):
        typed_options({"keyframes.n": 3}, methods.BUILTIN["egs"])


def test_the_configuration_page_lists_a_plugins_fields() -> None:
    from tests.docs.conftest import _load

    reference = _load("config_reference")
    page = reference.render(METHOD.config_classes())
    keyframes = page.split("## `keyframes`")[1].split("## ")[0]
    row = next(line for line in keyframes.splitlines() if line.startswith("| `n`"))
    assert "in [1, 1000]" in row and "frames from one keyframe to the next" in row
    assert "| `interval`" in keyframes  # the built-in fields it extends, with their docs
    assert "| `n`" not in reference.render().split("## `keyframes`")[1]


def test_config_yaml_names_each_component_so_an_oracle_run_differs_from_egs() -> None:
    from tests.slam.test_oracle_tracking import _fake_sequence, _script

    plain = SlamComponents().record()
    assert plain["tracker"]["target"] == "egs_bench.slam.tracker:GradientTracker"
    assert plain["mapper"]["target"] == "egs_bench.slam.mapper:Mapper"
    assert [t["name"] for t in plain["loss_terms"]] == ["photometric", "depth", "events"]
    seq, _ = _fake_sequence(lambda i: (50_000, 100_000))
    oracle = _script().oracle_components(seq, None, None, exposure0=True).record()
    assert oracle["tracker"] != plain["tracker"] and oracle["mapper"] != plain["mapper"]
    assert oracle["keyframes"] == plain["keyframes"]


def test_the_loss_group_takes_the_most_derived_config_of_its_terms() -> None:
    from egs_bench.slam.config import LossConfig
    from egs_bench.slam.loss_terms import LOSS_TERMS, LossTerm

    @dataclass(frozen=True)
    class First(LossConfig):
        a: float = 0.0

    @dataclass(frozen=True)
    class Second(First):
        b: float = 0.0

    @dataclass(frozen=True)
    class Other(LossConfig):
        c: float = 0.0

    def term(name: str, config: type) -> LossTerm:
        return dataclasses.replace(LOSS_TERMS[0], name=name, config=config)

    both = SlamComponents(loss_terms=(*LOSS_TERMS, term("a", First), term("b", Second)))
    assert both.config_classes()["loss"] is Second
    assert SlamComponents().config_classes()["loss"] is LossConfig
    with pytest.raises(TypeError, match="'c' declares Other, unrelated to First"):
        SlamComponents(loss_terms=(term("a", First), term("c", Other))).config_classes()


@pytest.mark.parametrize("method", ["egs", METHOD_PATH])
def test_run_config_reproduces_the_trajectory_byte_for_byte(method: str, tiny_sequence: Path,
                                                            tmp_path: Path,
                                                            capsys: pytest.CaptureFixture[str]
                                                            ) -> None:
    first, again = tmp_path / "first", tmp_path / "again"
    code, err = _run(["--method", method, "--seq", str(tiny_sequence), "--out", str(first),
                      *QUICK, "--set", "lambda_d=0.2", "--max-frames", "3"], capsys)
    assert code == 0, err
    where = [] if method == "egs" else ["--method", method]  # not registered by its name
    code, err = _run(["--config", str(first / "config.yaml"), "--out", str(again), "--quiet",
                      *where], capsys)
    assert code == 0, err
    assert (again / "trajectory.txt").read_bytes() == (first / "trajectory.txt").read_bytes()
    assert yaml.safe_load((again / "config.yaml").read_text()) == \
        yaml.safe_load((first / "config.yaml").read_text())
    code, err = _run(["--config", str(first / "config.yaml"), "--out", str(tmp_path / "x"),
                      "--seed", "3"], capsys)
    assert_cli_error(code, err, 2, "--config re-runs the stored --seed")


def test_run_config_without_out_writes_where_run_does(tiny_sequence: Path, tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str],
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    from egs_bench.runs.locations import run_location

    first = tmp_path / "first"
    code, err = _run(["--method", "monogs", "--seq", str(tiny_sequence), "--out", str(first),
                      *QUICK, "--max-frames", "2"], capsys)
    assert code == 0, err
    monkeypatch.chdir(tmp_path)
    code, err = _run(["--config", str(first / "config.yaml"), "--quiet"], capsys)
    assert code == 0, err
    default = tmp_path / run_location(Path(), "plane", "monogs")
    assert (default / "trajectory.txt").read_bytes() == (first / "trajectory.txt").read_bytes()


def test_run_config_refuses_a_run_made_with_other_components(tiny_sequence: Path, tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]
                                                             ) -> None:
    first = tmp_path / "first"
    code, err = _run(["--method", "egs", "--seq", str(tiny_sequence), "--out", str(first),
                      *QUICK, "--max-frames", "2"], capsys)
    assert code == 0, err
    stored = yaml.safe_load((first / "config.yaml").read_text())
    stored["components"]["tracker"]["target"] = "oracle_tracking:oracle_components.<locals>.tracker"
    (first / "config.yaml").write_text(yaml.safe_dump(stored))
    code, err = _run(["--config", str(first / "config.yaml"), "--out", str(tmp_path / "x")],
                     capsys)
    assert_cli_error(code, err, 2, "the run was made with other parts than method 'egs' has: "
                     "tracker oracle_tracking:oracle_components.<locals>.tracker (the method's: "
                     "egs_bench.slam.tracker:GradientTracker)")


def test_a_config_yaml_in_the_earlier_layouts_still_loads_and_reruns(
        tiny_sequence: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The layout written before components were recorded (groups, no ``components``) re-runs
    to the same trajectory; the flat layout of earlier versions (``kf_interval``,
    ``n_segments``, unique field names) loads to the same configuration."""
    first = tmp_path / "first"
    code, err = _run(["--method", "monogs", "--seq", str(tiny_sequence), "--out", str(first),
                      *QUICK, "--max-frames", "2"], capsys)
    assert code == 0, err
    stored = yaml.safe_load((first / "config.yaml").read_text())
    old = tmp_path / "old"
    shutil.copytree(first, old)
    parts = stored.pop("components")
    (old / "config.yaml").write_text(yaml.safe_dump(stored))
    code, err = _run(["--config", str(old / "config.yaml"), "--out", str(tmp_path / "again"),
                      "--quiet"], capsys)
    assert code == 0, err
    assert (tmp_path / "again" / "trajectory.txt").read_bytes() == \
        (first / "trajectory.txt").read_bytes()
    # recorded before the convergence rule and the schedule were: the built-in ones
    del parts["convergence"], parts["schedule"]
    (old / "config.yaml").write_text(yaml.safe_dump({**stored, "components": parts}))
    code, err = _run(["--config", str(old / "config.yaml"), "--out", str(tmp_path / "again"),
                      "--quiet", "--overwrite"], capsys)
    assert code == 0, err

    cfg = SlamConfig.from_dict(stored["slam"])
    flat = {name: cfg.get(path) for name, path in ALIASES.items()}
    assert {"kf_interval", "n_segments", "lambda_d"} <= set(flat)
    # a name two groups share has no flat spelling: such a field keeps its default
    named = {path: cfg.get(path) for path in set(ALIASES.values())}
    assert SlamConfig.from_dict(flat) == SlamConfig().replace(**named)
    assert SlamConfig.from_dict(flat).budget.segments == cfg.budget.segments
    with pytest.raises(ConfigError, match="unknown SLAM option 'no_such_option'"):
        SlamConfig.from_dict({"no_such_option": 1})
