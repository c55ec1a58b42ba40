"""The extending guide's external-system section runs as written: a system described by one
``ExternalSystem`` and registered once gets its camera file in an export of the layout it
reads, and its output imports as a run folder that evaluation scores, from Python and through
the command line, which lists it."""

from __future__ import annotations

import re
import sys
import types
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from egs_bench.interop import registry

GUIDE = Path(__file__).resolve().parents[2] / "docs" / "guide" / "extending.md"


def section_code(heading: str) -> str:
    """The ```python blocks of the guide's section ``## heading``, joined."""
    text = GUIDE.read_text(encoding="utf-8")
    section = re.search(rf"^## {re.escape(heading)}\n(.*?)(?=^## |\Z)", text, re.S | re.M)
    assert section, f"no section {heading!r} in {GUIDE}"
    return "\n".join(re.findall(r"```python\n(.*?)```", section.group(1), flags=re.S))


@pytest.fixture(scope="module")
def guide_run(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[dict[str, Any], Path,
                                                                          str]]:
    """The guide's dataset section (the ``my_wall`` sequence) and its external-system
    section, run in order in a fresh folder as the module ``guide``; what they printed."""
    import contextlib
    import io

    folder = tmp_path_factory.mktemp("guide_external")
    module = types.ModuleType("guide")
    printed = io.StringIO()
    with pytest.MonkeyPatch.context() as patch:
        patch.chdir(folder)
        patch.setitem(sys.modules, "guide", module)
        try:
            with contextlib.redirect_stdout(printed):
                for heading in ("A dataset of your own", "An external system"):
                    exec(compile(section_code(heading), str(GUIDE), "exec", dont_inherit=True),
                         module.__dict__)
            yield module.__dict__, folder, printed.getvalue()
        finally:
            registry._REGISTERED.pop("toyslam", None)


def test_the_registered_system_gets_its_camera_file_in_the_export(
        guide_run: tuple[dict[str, Any], Path, str]) -> None:
    namespace, folder, printed = guide_run
    export = namespace["export"]
    assert list(export.files) == ["monogs", "orbslam2", "photoslam", "toyslam", "associations"]
    assert printed.splitlines()[0] == "toyslam.txt"
    cam = namespace["export"].path / "toyslam.txt"
    fx, fy, cx, cy, w, h = cam.read_text().split()
    # the guide's my_wall camera, in the OpenCV pixel convention
    assert (float(fx), float(fy), float(cx), float(cy), int(w), int(h)) == (
        50.0, 50.0, 31.5, 23.5, 64, 48)


def test_its_output_imports_as_a_run_that_evaluation_scores(
        guide_run: tuple[dict[str, Any], Path, str]) -> None:
    namespace, folder, printed = guide_run
    run = namespace["toy_run"]
    assert printed.splitlines()[1:3] == ["ToySLAM all", "0.0"]
    assert run.read_status().state == "done" and run.method == "ToySLAM"
    assert run.read_config()["format"] == "toyslam"
    truth = np.loadtxt(folder / "exports" / "my_wall" / "groundtruth.txt", ndmin=2)
    estimate = run.read_trajectory()
    np.testing.assert_allclose(estimate.poses[:, 0, 3], truth[:, 1] + 0.02, atol=1e-6)
    # mapped back onto the sequence's own stamps (the export kept them: frames 33 ms apart)
    np.testing.assert_allclose(estimate.timestamps, truth[:, 0], atol=1e-6)
    assert namespace["toy_metrics"]["ate"]["rmse_m"] < 1e-6


def test_the_command_line_imports_it_with_from_its_key(
        guide_run: tuple[dict[str, Any], Path, str]) -> None:
    namespace, folder, printed = guide_run
    assert namespace["code"] == 0
    assert printed.splitlines()[3:] == [
        f"imported ToySLAM on my-wall into {Path('runs/toyslam-cli')} (poses: all, renders: "
        "none)", "0"]
    from egs_bench.runs.folder import RunFolder

    run = RunFolder.open(folder / "runs" / "toyslam-cli")
    assert run.method == "ToySLAM" and run.read_config()["format"] == "toyslam"
    np.testing.assert_allclose(run.read_trajectory().poses,
                               namespace["toy_run"].read_trajectory().poses)


def test_the_command_line_lists_it_in_the_help_and_the_errors(
        guide_run: tuple[dict[str, Any], Path, str], capsys: pytest.CaptureFixture[str]) -> None:
    from egs_bench.cli import main

    assert main(["import-run", "--help"]) == 0
    help_text = " ".join(capsys.readouterr().out.split())
    assert "--from [tum|monogs|orbslam2|photoslam|rampvo|toyslam]" in help_text
    assert main(["export", "--help"]) == 0
    assert "tum-rgbd (MonoGS, ORB-SLAM2, Photo-SLAM, ToySLAM)" in " ".join(
        capsys.readouterr().out.split())
    assert main(["import-run", "x", "-o", "y", "--from", "nosuchslam"]) == 2
    assert "'rampvo', 'toyslam'." in capsys.readouterr().err


def test_registering_is_refused_for_a_built_in_key() -> None:
    from egs_bench.errors import ConfigError
    from egs_bench.interop.systems import ExternalSystem

    for key in ("monogs", "tum"):
        with pytest.raises(ConfigError, match="built-in import format"):
            registry.register_system(ExternalSystem(key=key, title="x"))
    from egs_bench.interop import monogs

    assert registry.importable_system("monogs") is monogs.SYSTEM
