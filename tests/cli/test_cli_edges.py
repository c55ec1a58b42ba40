"""Sharp edges of the command line: paths and values are printed
as they are (never read as rich markup), every option is checked where it is parsed with one
line naming it, and the commands agree with each other and with the command table of README.md."""

from __future__ import annotations

import inspect
import shutil
from pathlib import Path
from typing import Any

import pytest
import yaml

from egs_bench.cli import main
from tests.helpers.cli import assert_cli_error, run_cli

# `[`, `]`, a closing tag, a style tag and an emoji code: rich would raise on `[/x]`, eat
# `[red]` and turn `:smile:` into an emoji
NASTY = "a[b]c[/x][red]d:smile:"


def _commands() -> set[str]:
    from egs_bench.cli import _register_commands
    from egs_bench.cli.app import app

    _register_commands()
    return {str(c.name or getattr(c.callback, "__name__", "")) for c in app.registered_commands}


def _bad_path_cases(tmp: Path, make: bool = True) -> dict[str, tuple[list[str | Path],
                                                                      Path | str]]:
    """Per command: arguments naming a missing input (or a refused output) whose path holds
    markup, and the text the one error line must contain literally."""
    missing = tmp / NASTY / "in[/y]"
    out = tmp / f"out{NASTY}"
    folder = tmp / f"dir{NASTY}"
    if make:
        folder.mkdir(parents=True, exist_ok=True)
    return {
        "info": (["info", missing], missing),
        "show": (["show", missing, "-o", out.with_suffix(".png")], missing),
        "demo": (["demo", "--seq", missing, "-o", out], missing),
        "make-synthetic": (["make-synthetic", "-s", "office", "-o", out, "--frames", "2",
                            "--trajectory", missing], missing),
        "make-eventreplica": (["make-eventreplica", "-o", out, "-i", missing], missing),
        "eval": (["eval", missing], missing),
        "ate": (["ate", missing, missing], missing),
        "rpe": (["rpe", missing, missing], missing),
        "compare-images": (["compare-images", missing, missing], missing),
        "leaderboard": (["leaderboard", missing], missing),
        "plot": (["plot", missing], missing),
        "import-run": (["import-run", missing, "-o", out, "--from", "tum", "-m", "m", "-s", "s"],
                       out),
        "render-map": (["render-map", missing, "-o", out.with_suffix(".png")], missing),
        "export-map": (["export-map", missing, "-o", out.with_suffix(".ply")], missing),
        "render-demo": (["render-demo", "-o", folder], folder),
        "config-reference": (["config-reference", "-o", folder], folder),
        "run": (["run", "-m", "monogs", "-s", missing], missing),
        "list": (["list", NASTY], NASTY),
        "export": (["export", missing, "-o", out, "-f", "tum-rgbd"], missing),
        "import-recording": (["import-recording", "-o", out, "--events", missing, "--depth",
                              missing, "--gt", missing], missing),
        "import-enslam": (["import-enslam", "--input", missing, "-o", out, "--calib", missing,
                           "--exposure-us", "10000", "--frame-stamp", "end"], missing),
        "make-calib": (["make-calib", "-o", out, "--kalibr", missing], missing),
        "sweep": (["sweep", missing], missing),
        "report": (["report", missing, "-o", out], missing),
        "regress": (["regress", missing, missing], missing),
        "paper-tables": (["paper-tables", missing], missing),
        "figure": (["figure", "trajectories", missing, "-o", out.with_suffix(".pdf")], missing),
    }


LISTINGS = {"list-scenes", "list-methods", "recording-presets"}
WITHOUT_PATHS = {"warm-up"}  # tests/test_warmup.py runs it
# the cases that are usage errors (exit 2): a choice not offered, a refused output; the others
# name a missing input (a data error, exit 3)
USAGE_ERROR_CASES = {"list", "render-demo", "config-reference"}


def test_every_command_has_a_bracket_case(tmp_path: Path) -> None:
    """A new command must be added to the markup cases below."""
    assert set(_bad_path_cases(tmp_path)) | LISTINGS | WITHOUT_PATHS == _commands()


@pytest.mark.parametrize("command", sorted(_bad_path_cases(Path("/nonexistent"), make=False)))
def test_bracketed_paths_are_named_literally_in_one_line(command: Any, tmp_path: Path,
                                                         capsys: pytest.CaptureFixture[str],
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    argv, named = _bad_path_cases(tmp_path)[command]
    code, _, err = run_cli(capsys, *argv)
    assert_cli_error(code, err, 2 if command in USAGE_ERROR_CASES else 3, named)


@pytest.mark.parametrize("command", sorted(LISTINGS))
def test_listings_print(command: Any, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run_cli(capsys, command)
    assert code == 0 and out and not err


def test_bracketed_paths_in_successful_commands(tiny_sequence: Path, tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    seq = Path(shutil.copytree(tiny_sequence, tmp_path / f"seq{NASTY}"))
    code, out, err = run_cli(capsys, "info", seq, "--no-check")
    assert code == 0 and "sequence plane" in out, err
    calib = tmp_path / f"c{NASTY}.yaml"
    code, out, err = run_cli(capsys, "make-calib", "-o", calib)
    assert code == 0 and calib.is_file(), err
    assert f"wrote {calib}" in out
    gt = tmp_path / f"gt{NASTY}.txt"
    gt.parent.mkdir(parents=True, exist_ok=True)
    shutil.copy(seq / "groundtruth.txt", gt)
    est = shutil.copy(seq / "groundtruth.txt", tmp_path / "estimate.txt")
    code, out, err = run_cli(capsys, "ate", gt, est, "--align", "none")  # a straight path
    assert code == 0, err
    assert f"reference {gt}" in out.replace("\n", "")


def test_library_messages_keep_their_brackets(monkeypatch: pytest.MonkeyPatch,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    """Text the library wrote with brackets (an install hint) reaches the user whole."""
    from egs_bench.errors import ConfigError

    def refuse(*_args: Any, **_kwargs: Any) -> None:
        raise ConfigError("backend 'gsplat' needs gsplat 1.5.3: pip install 'egs-bench[cuda]'")

    monkeypatch.setattr("egs_bench.datasets.registry.load_sequence", refuse)
    code, _, err = run_cli(capsys, "info", "x")
    assert_cli_error(code, err, 2,
                     "backend 'gsplat' needs gsplat 1.5.3: pip install 'egs-bench[cuda]'")


# ------------------------------------------------------------------ option values
@pytest.mark.parametrize("argv,option", [
    (["make-synthetic", "-s", "office", "-o", "o", "--seed", "-1"], "--seed"),
    (["run", "-m", "monogs", "-s", "x", "--seed", "-1"], "--seed"),
    (["make-eventreplica", "-o", "o", "-i", "x", "--seed", "-1"], "--seed"),
    (["run", "-m", "monogs", "-s", "x", "--seed", "99999999999999999999"], "--seed"),
    (["import-recording", "-o", "o", "--events", "e", "--depth", "d", "--gt", "g",
      "--max-depth-dt-ms", "nan"], "--max-depth-dt-ms"),
    (["make-synthetic", "-s", "office", "-o", "o", "--fps", "inf"], "--fps"),
    (["ate", "a", "b", "--max-diff", "nan"], "--max-diff"),
    (["rpe", "a", "b", "--max-diff", "-1"], "--max-diff"),
    (["import-recording", "-o", "o", "--events", "e", "--depth", "d", "--gt", "g",
      "--exposure-us", "-5"], "--exposure-us"),
    (["import-recording", "-o", "o", "--events", "e", "--depth", "d", "--gt", "g",
      "--max-gt-gap-ms", "-1"], "--max-gt-gap-ms"),
    (["leaderboard", ".", "--metrics", ","], "--metrics"),
    (["paper-tables", ".", "--tables", " , "], "--tables"),
    (["compare-images", "a.png", "b.png", "--lpips-net", "foo"], "--lpips-net"),
    (["ate", "a", "b", "--align", "affine"], "--align"),
    (["list", "foo"], "'foo' is not one of 'methods', 'scenes'"),
    (["list"], "Missing argument 'WHAT'. Choose from: methods, scenes"),
    (["run", "-m", "os:system", "-s", "x"], "os:system does not provide a method"),
    (["run", "-m", "monogs", "-s", "x", "--nosuch"], "--nosuch"),
    (["make-calib", "-o", "c.yaml", "--preset", "foo"], "--preset 'foo'"),
])
def test_bad_option_values_are_one_line_naming_the_option(argv: list[Any], option: str,
                                                          tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str],
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    code, _, err = run_cli(capsys, *argv)
    assert_cli_error(code, err, 2, option)
    assert not (tmp_path / "c.yaml").exists()


@pytest.mark.parametrize("flag", ["--kalibr", "--ros-yaml"])
def test_binary_calibration_files_are_named(flag: str, tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    binary = tmp_path / "cam.yaml"
    binary.write_bytes(bytes(range(256)) * 4)
    code, _, err = run_cli(capsys, "make-calib", "-o", tmp_path / "c.yaml", flag, binary)
    assert_cli_error(code, err, 3, f"{binary}: not a UTF-8 text file")


def test_a_file_that_is_not_pytorch_weights_is_named_without_unsafe_advice(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from egs_bench.images import write_ldr_image

    img = tmp_path / "a.png"
    write_ldr_image(img, __import__("numpy").zeros((16, 16, 3), "uint8"))
    weights = tmp_path / "hostname"
    weights.write_text("myhost\n")
    monkeypatch.setenv("EGS_BENCH_LPIPS_WEIGHTS", str(weights))
    code, _, err = run_cli(capsys, "compare-images", img, img)
    assert "weights_only" not in assert_cli_error(code, err, 3, weights)


# ------------------------------------------------------------------ make-calib
def test_make_calib_overwrite_replaces_only_with_the_flag(tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]
                                                          ) -> None:
    out = tmp_path / "calib.yaml"
    out.write_text("mine: 1\n")
    code, _, err = run_cli(capsys, "make-calib", "-o", out)
    assert_cli_error(code, err, 2, f"{out}: already exists; pass --overwrite")
    assert out.read_text() == "mine: 1\n"
    code, _, err = run_cli(capsys, "make-calib", "-o", out, "--overwrite", "--preset",
                           "mvsec-indoor")
    assert code == 0, err
    assert yaml.safe_load(out.read_text())["depth_camera"] == "event"


# ------------------------------------------------------------------ consistency
def test_help_lists_choices_and_shows_no_bool_type(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run_cli(capsys, "ate", "--help")
    assert code == 0 and "[se3|sim3|none]" in out and "<bool>" not in out, out
    code, out, _ = run_cli(capsys, "render-map", "--help")
    assert "[default: the run's camera, else 640]" in " ".join(out.split()), out


def test_topic_options_have_help(capsys: pytest.CaptureFixture[str]) -> None:
    from egs_bench.cli import _register_commands
    from egs_bench.cli.app import app

    _register_commands()
    command = next(c for c in app.registered_commands if c.name == "import-recording")
    assert command.callback is not None
    for name, param in inspect.signature(command.callback).parameters.items():
        assert param.default.help, f"--{name.replace('_', '-')} has no help"


def test_cli_choices_match_the_library() -> None:
    from typing import get_args

    from egs_bench.cli import choices
    from egs_bench.datasets.eventreplica.interpolate import INTERPOLATORS
    from egs_bench.datasets.rgbd_layouts import LAYOUTS as RGBD_LAYOUTS
    from egs_bench.eval.ate import ALIGNMENTS
    from egs_bench.eval.leaderboard import FORMATS, LAYOUTS
    from egs_bench.eval.lpips import NETS
    from egs_bench.eval.protocols import PROTOCOLS
    from egs_bench.eval.rpe import DELTA_UNITS, RELATIONS
    from egs_bench.eval.tables import WIDTHS
    from egs_bench.experiments.sweep import BACKENDS
    from egs_bench.interop.export import FORMATS as EXPORT_FORMATS
    from egs_bench.interop.rampvo import QUATERNION_ORDERS
    from egs_bench.recordings.enslam import FRAME_SOURCES
    from egs_bench.recordings.folders import UNIT_TO_US
    from egs_bench.slam.config import PRESETS
    from egs_bench.slam.map_export import COLOR_MODES

    pairs = [(choices.Protocol, PROTOCOLS), (choices.SlamPreset, ["auto", *PRESETS]),
             (choices.Alignment, ALIGNMENTS), (choices.PoseRelation, RELATIONS),
             (choices.DeltaUnit, DELTA_UNITS), (choices.LpipsNet, NETS),
             (choices.BoardFormat, FORMATS), (choices.BoardLayout, LAYOUTS),
             (choices.TableWidth, WIDTHS),
             (choices.QuaternionOrder, QUATERNION_ORDERS), (choices.ExportFormat, EXPORT_FORMATS),
             (choices.MapColors, COLOR_MODES), (choices.SweepBackend, BACKENDS),
             (choices.Interpolator, INTERPOLATORS), (choices.TimesUnit, UNIT_TO_US),
             (choices.RgbdLayout, RGBD_LAYOUTS), (choices.EnslamFrames, FRAME_SOURCES)]
    for literal, library in pairs:
        assert set(get_args(literal)) == set(library), literal


def test_an_existing_export_is_a_usage_error_like_every_output(tiny_sequence: Path, tmp_path: Path,
                                                               capsys: pytest.CaptureFixture[str]
                                                               ) -> None:
    out = tmp_path / "exp"
    assert main(["export", str(tiny_sequence), "-o", str(out), "-f", "tum-rgbd", "--quiet"]) == 0
    capsys.readouterr()
    code, _, err = run_cli(capsys, "export", tiny_sequence, "-o", out, "-f", "tum-rgbd", "--quiet")
    assert_cli_error(code, err, 2, f"{out}: already exists", "--overwrite")


def test_info_does_not_invent_event_thresholds(tiny_sequence: Path, tmp_path: Path) -> None:
    from egs_bench.datasets.inspect import sequence_summary
    from egs_bench.datasets.sequence import Sequence

    seq = Path(shutil.copytree(tiny_sequence, tmp_path / "seq"))
    meta = yaml.safe_load((seq / "meta.yaml").read_text())
    assert "event_thresholds" in meta
    assert sequence_summary(Sequence.open(seq))["event_thresholds"]["pos"] > 0
    del meta["event_thresholds"]
    (seq / "meta.yaml").write_text(yaml.safe_dump(meta))
    assert sequence_summary(Sequence.open(seq))["event_thresholds"] == "not recorded"


def test_orbslam_frame_rate_is_rounded() -> None:
    from egs_bench.geometry import Intrinsics
    from egs_bench.interop.orbslam2 import orbslam2_settings

    text = orbslam2_settings(Intrinsics(100.0, 100.0, 32.0, 24.0, 64, 48),
                             fps=1e6 / 33333, depth_scale=5000.0, name="s")
    assert "Camera.fps: 30.0\n" in text, text


def test_rendering_table_latex_uses_math_arrows() -> None:
    from egs_bench.experiments.paper_tables import _latex_stub

    assert _latex_stub("PSNR ↑") == r"PSNR $\uparrow$"
    assert _latex_stub("LPIPS ↓") == r"LPIPS $\downarrow$"


def test_paper_tables_into_an_existing_file_is_a_usage_error(tmp_path: Path) -> None:
    from egs_bench.errors import OutputError
    from egs_bench.experiments.paper_tables import write_tables

    taken = tmp_path / "tables"
    taken.write_text("a user's file\n")
    with pytest.raises(OutputError, match="not a folder") as exc:
        write_tables({}, taken)
    assert exc.value.exit_code == 2 and taken.read_text() == "a user's file\n"
