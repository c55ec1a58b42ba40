"""``docs/guide/extending.md`` is a test: its code blocks run in order, and what they print
and build is checked here (a keyframe rule, a loss term with an analytic value, a tracker, a
method made of them, a run, a dataset written with ``SequenceWriter`` and a method of its own
scored on it)."""

from __future__ import annotations

import re
import sys
import types
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import torch
import yaml

from egs_bench.errors import ConfigError

GUIDE = Path(__file__).resolve().parents[2] / "docs" / "guide" / "extending.md"


def guide_code() -> list[str]:
    """The guide's ```python blocks, in order."""
    return re.findall(r"```python\n(.*?)```", GUIDE.read_text(encoding="utf-8"), flags=re.S)


@pytest.fixture(scope="module")
def guide_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Where the guide's code runs (its working directory)."""
    return tmp_path_factory.mktemp("guide")


@pytest.fixture(scope="module")
def guide_namespace(guide_folder: Path) -> Iterator[dict]:
    """The guide's code blocks run once, in order, in ``guide_folder``, as the module
    ``guide`` (what a reader's own module would be: its classes have import paths); the
    methods they register are removed afterwards."""
    from egs_bench.interop import registry as interop_registry
    from egs_bench.runs import registry

    module = types.ModuleType("guide")
    namespace: dict = module.__dict__
    with pytest.MonkeyPatch.context() as patch:
        patch.chdir(guide_folder)
        patch.setitem(sys.modules, "guide", module)
        try:
            for block in guide_code():
                # dont_inherit: the guide's code runs without this file's __future__ imports
                exec(compile(block, str(GUIDE), "exec", dont_inherit=True), namespace)
            yield namespace
        finally:
            registry._USER.pop("egs-depth-tv", None)
            registry._USER.pop("short-steps", None)
            interop_registry._REGISTERED.pop("toyslam", None)


def test_the_guide_has_its_examples() -> None:
    assert len(guide_code()) == 10


def test_the_guides_keyframe_setting_is_an_option_with_its_range(
        guide_namespace: dict, guide_folder: Path) -> None:
    """``keyframes.n`` reaches the policy (a keyframe every second frame by default, every
    third when set), is checked against its range, and is recorded in ``config.yaml``."""
    assert guide_namespace["options"] == {"keyframes.n": 3}
    assert guide_namespace["refused"] == "SLAM option keyframes.n must be in [1, 1000]"
    cfg = yaml.safe_load((guide_folder / "runs" / "egs-depth-tv" / "config.yaml").read_text())
    assert cfg["slam"]["keyframes"]["n"] == 2
    assert cfg["components"]["keyframes"]["target"] == "guide:EveryNthFrame"
    method = guide_namespace["METHOD"].with_options(guide_namespace["options"])
    policy = guide_namespace["EveryNthFrame"](
        type("Context", (), {"cfg": method.config("cpu")})())
    from egs_bench.slam.keyframes import KeyframeCandidate

    def candidate(frame: int) -> KeyframeCandidate:
        vis = np.ones(4, dtype=bool)
        return KeyframeCandidate(frame, 0, np.eye(4), np.eye(4), vis, vis, 1.0, 1)

    assert [policy.is_keyframe(candidate(i)) for i in (1, 2, 3, 4)] == [False, False, True, True]


def test_the_guides_run_uses_its_keyframe_rule_tracker_and_loss_weight(guide_namespace: dict,
                                                                       guide_folder: Path) -> None:
    run = guide_namespace["run"]
    assert run.read_status().state == "done"
    assert list(run.read_keyframes()) == [0, 2, 4]
    assert sorted(guide_namespace["iterations_by_frame"]) == [1, 2, 3, 4, 5]
    cfg = yaml.safe_load((guide_folder / "runs" / "egs-depth-tv" / "config.yaml").read_text())
    assert cfg["slam"]["loss"]["lambda_depth_tv"] == 0.1 and cfg["slam"]["extra"] == {}
    assert cfg["components"]["loss_config_class"] == "guide:DepthTvConfig"
    from egs_bench.runs.registry import get_method

    assert get_method("egs-depth-tv") is guide_namespace["METHOD"]


def test_the_guides_loss_term_on_a_depth_ramp(guide_namespace: dict) -> None:
    """A depth ramp of 0.1 m per column and constant rows: mean |dx| = 0.1, |dy| = 0, so the
    term is 0.1 x its weight, per view."""
    from egs_bench.slam.config import cpu_preset
    from egs_bench.slam.frames import FrameObs
    from egs_bench.slam.loss_terms import RenderedViews, TermSetup

    term = guide_namespace["DEPTH_TV"]
    with_term = cpu_preset().with_groups({"loss": term.config})
    cfg = with_term.replace(**{"loss.lambda_depth_tv": 0.5})
    assert term.weight(cfg) == 0.5 and term.weight(with_term) == 0.0
    with pytest.raises(ConfigError, match=r"SLAM option loss.lambda_depth_tv must be >= 0"):
        with_term.replace(**{"loss.lambda_depth_tv": -1.0}).validate()
    h, w = 4, 6
    ones = torch.ones(h, w, dtype=torch.bool)
    obs = FrameObs(0, torch.zeros(h, w, 3, dtype=torch.float64),
                   torch.ones(h, w, dtype=torch.float64), ones, ones, None, np.array([1.0]),
                   None, 0)
    prepared = term.prepare(obs, TermSetup(cfg, (0.25, 0.25), False, False), term.weight(cfg))
    ramp = 1.0 + 0.1 * torch.arange(w, dtype=torch.float64).expand(h, w)
    depth = ramp.expand(2, 3, h, w)  # V = 2 frames, M = 3 sub-poses
    views = RenderedViews(torch.zeros(2, 3, h, w, 3, dtype=torch.float64),
                          torch.zeros(2, h, w, 3, dtype=torch.float64),
                          torch.ones(2, 3, h, w, dtype=torch.float64), depth, False, 1e-3,
                          torch.ones(3, dtype=torch.float64))
    stacked = {k: torch.cat([v, v]) for k, v in prepared.items()}
    np.testing.assert_allclose(term.value(views, stacked).numpy(), [0.05, 0.05], rtol=1e-12)


def test_the_guides_dataset_is_a_valid_sequence_with_what_it_wrote(guide_namespace: dict,
                                                                  guide_folder: Path) -> None:
    from egs_bench.datasets.sequence import Sequence

    seq = Sequence.open(guide_folder / "my_wall")
    assert len(seq) == 4 and seq.has_events and not seq.has_sharp
    assert (seq.width, seq.height) == (64, 48)
    np.testing.assert_array_equal(seq.rgb(2), guide_namespace["wall"][:, 2:66])
    np.testing.assert_allclose(seq.depth(1), 2.0)
    np.testing.assert_allclose(seq.poses[:, :2, 3], [[0.0, 0.0], [0.01, 0.002], [0.02, 0.008],
                                                     [0.03, 0.018]], atol=1e-9)
    start, end = seq.exposure(3)
    events = seq.events.window(start, end)
    assert len(events) == 8 and set(events.x.tolist()) == {13}
    assert sorted(set(events.p.tolist())) == [-1, 1]
    assert not list(guide_folder.glob(".my_wall*"))  # the staging folder is gone


def test_the_guides_short_steps_leave_a_tenth_of_the_spread_after_alignment(
        guide_namespace: dict, guide_folder: Path) -> None:
    """Positions scaled by 0.9 about frame 0: the SE(3) alignment that best maps them onto the
    ground truth is a pure translation, and 10 % of each position's offset from the mean
    remains."""
    from egs_bench.datasets.sequence import Sequence
    from egs_bench.runs.registry import get_method

    run = guide_namespace["short_run"]
    assert run.read_status().state == "done"
    metrics = guide_namespace["metrics"]
    assert metrics["rendering"] is None
    positions = Sequence.open(guide_folder / "my_wall").poses[:, :3, 3]
    spread = positions - positions.mean(0)
    expected = 0.1 * np.sqrt((spread ** 2).sum(1).mean())
    np.testing.assert_allclose(metrics["ate"]["rmse_m"], expected, rtol=1e-6)
    assert isinstance(get_method("short-steps"), guide_namespace["ShortSteps"])


def test_the_guides_settings_are_on_the_configuration_reference(
        guide_namespace: dict, capsys: pytest.CaptureFixture[str]) -> None:
    """The page lists the fields the registered example's components add, with their
    ranges; ``config-reference --method`` prints the method's whole reference."""
    from egs_bench.cli import main
    from egs_bench.slam.config_reference import render

    own = render().split("## Components' own settings")[1].split("### `egs-depth-tv`")[1]
    own = own.split("### ")[0]
    rows = {line.split("|")[1].strip(): line for line in own.splitlines()
            if line.startswith("| `")}
    assert set(rows) == {"`keyframes.n`", "`loss.lambda_depth_tv`"}
    assert "in [1, 1000]" in rows["`keyframes.n`"]
    assert ">= 0" in rows["`loss.lambda_depth_tv`"]

    assert main(["config-reference", "--method", "egs-depth-tv"]) == 0
    page = capsys.readouterr().out
    assert page.startswith("# Configuration reference of method `egs-depth-tv`")
    keyframes = page.split("## `keyframes`")[1].split("## ")[0]
    assert any(line.startswith("| `n`") and "in [1, 1000]" in line
               for line in keyframes.splitlines())
    assert "## Components' own settings" not in page
