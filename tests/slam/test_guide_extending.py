"""``docs/guide/extending.md`` is a test: its code blocks run in order, and what they print
and build is checked here (a keyframe rule, a loss term with an analytic value, a tracker, a
method made of them, and a run)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import torch
import yaml

GUIDE = Path(__file__).resolve().parents[2] / "docs" / "guide" / "extending.md"


def guide_code() -> list[str]:
    """The guide's ```python blocks, in order."""
    return re.findall(r"```python\n(.*?)```", GUIDE.read_text(encoding="utf-8"), flags=re.S)


@pytest.fixture
def guide_namespace(tmp_path: Path, monkeypatch) -> dict:
    from egs_bench.runs import registry

    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": "guide"}
    try:
        for block in guide_code():
            exec(compile(block, str(GUIDE), "exec"), namespace)  # the guide's code
        yield namespace
    finally:
        registry._USER.pop("egs-depth-tv", None)


def test_the_guide_has_its_examples() -> None:
    assert len(guide_code()) == 5


def test_the_guides_run_uses_its_keyframe_rule_tracker_and_loss_weight(guide_namespace,
                                                                       tmp_path: Path) -> None:
    run = guide_namespace["run"]
    assert run.read_status().state == "done"
    assert list(run.read_keyframes()) == [0, 2, 4]
    assert sorted(guide_namespace["iterations_by_frame"]) == [1, 2, 3, 4, 5]
    cfg = yaml.safe_load((tmp_path / "runs" / "egs-depth-tv" / "config.yaml").read_text())
    assert cfg["slam"]["extra"] == {"lambda_depth_tv": 0.1}
    from egs_bench.runs.registry import get_method

    assert get_method("egs-depth-tv") is guide_namespace["METHOD"]


def test_the_guides_loss_term_on_a_depth_ramp(guide_namespace) -> None:
    """A depth ramp of 0.1 m per column and constant rows: mean |dx| = 0.1, |dy| = 0, so the
    term is 0.1 x its weight, per view."""
    from egs_bench.slam.config import cpu_preset
    from egs_bench.slam.frames import FrameObs
    from egs_bench.slam.loss_terms import RenderedViews, TermSetup

    term = guide_namespace["DEPTH_TV"]
    cfg = cpu_preset().replace(**{"extra.lambda_depth_tv": 0.5})
    assert term.weight(cfg) == 0.5 and term.weight(cpu_preset()) == 0.0
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
