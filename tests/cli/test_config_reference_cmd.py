"""``egs-bench config-reference`` prints the configuration page; the page lists the fields
that the components of a method registered through the ``egs_bench.methods`` entry point
add."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from egs_bench.runs import registry
from egs_bench.slam.config_reference import render
from tests.helpers.cli import assert_cli_error, run_cli
from tests.slam.test_component_configs import METHOD, METHOD_PATH


class _EntryPoint:
    """What ``importlib.metadata`` gives for an installed plug-in's entry point."""

    value = METHOD_PATH

    def load(self) -> Any:
        return METHOD


def test_the_page_lists_an_entry_point_methods_fields(monkeypatch: pytest.MonkeyPatch,
                                                      capsys: pytest.CaptureFixture[str]
                                                      ) -> None:
    assert "### `egs-every-nth`" not in render()
    monkeypatch.setattr(registry, "_entry_point_methods",
                        lambda: {"egs-every-nth": _EntryPoint()})
    page = render()
    own = page.split("### `egs-every-nth`")[1]
    row = next(line for line in own.splitlines() if line.startswith("| `keyframes.n`"))
    assert "in [1, 1000]" in row and "frames from one keyframe to the next" in row
    code, out, err = run_cli(capsys, "config-reference")
    assert code == 0, err
    assert out.rstrip("\n") == page.rstrip("\n")


def test_config_reference_writes_out_and_refuses_a_user_method(tmp_path: Path,
                                                               capsys: pytest.CaptureFixture[str]
                                                               ) -> None:
    target = tmp_path / "config.md"
    code, _, err = run_cli(capsys, "config-reference", "-m", METHOD_PATH, "-o", target)
    assert code == 0, err
    assert target.read_text().rstrip("\n") == render(METHOD.config_classes(),
                                                      METHOD.name).rstrip("\n")
    code, _, err = run_cli(capsys, "config-reference", "-m", "tests.helpers.sweep_fixtures:GOOD")
    assert_cli_error(code, err, 2, "is not configured by a SlamConfig")
