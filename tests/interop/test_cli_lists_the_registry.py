"""The command line's view of the registry of external systems: ``import-run --from`` takes
exactly the registry's import formats, a system registered from outside is listed in the help
and offered by shell completion while it is registered (and not after), and ``--render-ply``
names the system whose output is read."""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import pytest

from egs_bench.cli import main
from egs_bench.errors import ConfigError
from egs_bench.interop import registry
from egs_bench.interop.importing import import_external_run
from egs_bench.interop.systems import ExternalEstimate, ExternalSystem, ImportOptions
from tests.helpers.cli import assert_cli_error


def _read_nothing(source: Path, options: ImportOptions) -> ExternalEstimate:
    raise AssertionError("the import is refused before the output is read")


PLUGIN = ExternalSystem(key="plugslam", title="PlugSLAM", read=_read_nothing,
                        output="plug.txt")


@pytest.fixture
def plugin() -> Iterator[ExternalSystem]:
    registry.register_system(PLUGIN)
    try:
        yield PLUGIN
    finally:
        registry._REGISTERED.pop(PLUGIN.key, None)


def _from_choices(capsys: pytest.CaptureFixture[str]) -> list[str]:
    """The choices ``import-run --help`` shows for ``--from``."""
    assert main(["import-run", "--help"]) == 0
    found = re.search(r"--from \[([^\]]+)\]", capsys.readouterr().out)
    assert found, "import-run --help shows no --from choices"
    return found.group(1).split("|")


def test_the_from_choices_are_the_registry_s_import_formats(
        capsys: pytest.CaptureFixture[str]) -> None:
    readers = [s.key for s in registry.all_systems() if s.read is not None]
    assert _from_choices(capsys) == ["tum", *readers] == list(registry.import_formats())
    # every built-in system with a reader, and no exporting-only one
    assert "nice_slam" not in readers and {"monogs", "orbslam2", "rampvo"} <= set(readers)


def test_a_registered_system_is_a_choice_while_it_is_registered(
        plugin: ExternalSystem, capsys: pytest.CaptureFixture[str]) -> None:
    assert _from_choices(capsys)[-1] == "plugslam"
    assert main(["import-run", "--help"]) == 0
    assert "plugslam (plug.txt)" in " ".join(capsys.readouterr().out.split())
    registry._REGISTERED.pop(plugin.key)
    assert "plugslam" not in _from_choices(capsys)
    code = main(["import-run", "plug.txt", "-o", "run", "--from", "plugslam"])
    assert_cli_error(code, capsys.readouterr().err, 2, "Invalid value for '--from': "
                     "'plugslam' is not one of 'tum', 'monogs'")


def test_render_ply_names_the_system_that_writes_no_gaussian_map(
        plugin: ExternalSystem, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(ConfigError, match=r"--render-ply: PlugSLAM writes no Gaussian map "
                                          r"\(systems that do: monogs\)"):
        import_external_run(tmp_path / "plug.txt", tmp_path / "run", fmt="plugslam",
                            render_ply=True)
    assert main(["import-run", "--help"]) == 0
    assert "--render-ply --from monogs: render its Gaussian map " \
           "(point_cloud/final/point_cloud.ply)" in " ".join(capsys.readouterr().out.split())


def test_shell_completion_offers_a_registered_system(
        plugin: ExternalSystem, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setenv("_EGS_BENCH_COMPLETE", "complete_bash")
    monkeypatch.setenv("COMP_WORDS", "egs-bench import-run x --from p")
    monkeypatch.setenv("COMP_CWORD", "4")
    assert main([]) == 0
    assert capsys.readouterr().out.split() == ["photoslam", "plugslam"]
