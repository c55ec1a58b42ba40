"""Never lose a user's data: what an output path may replace, command by command.

Each test is a way an output path could delete or replace something the tool did not create.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from egs_bench.datasets.sequence import Sequence
from egs_bench.errors import OutputError, UnwritableOutputError
from egs_bench.fileio import atomic_path
from egs_bench.images import read_ldr_image, write_ldr_image
from egs_bench.outputs import prepare_output
from egs_bench.runs.folder import RunFolder
from tests.helpers.cli import assert_cli_error, run_cli
from tests.helpers.safety_helpers import QUICK_RUN


def _user_folder(path: Path) -> Path:
    """A folder holding the user's own data: a note and a sub-folder."""
    (path / "sub").mkdir(parents=True)
    (path / "notes.txt").write_text("my notes\n")
    return path


def _snapshot(path: Path) -> dict[str, bytes]:
    return {str(p.relative_to(path)): p.read_bytes() for p in sorted(path.rglob("*"))
            if p.is_file()}


def _ply(tmp_path: Path) -> Path:
    import torch

    from egs_bench.geometry import Intrinsics
    from egs_bench.render import GaussianMap
    from egs_bench.render.ply import save_ply

    gmap = GaussianMap.empty()
    gmap.add_from_depth(np.full((12, 16, 3), 0.5, np.float32), np.full((12, 16), 2.0, np.float32),
                        Intrinsics(15.0, 15.0, 8, 6, 16, 12), np.eye(4), downsample=2,
                        point_size=1.0, generator=torch.Generator().manual_seed(0))
    path = tmp_path / "map.ply"
    save_ply(gmap, path)
    return path


# ---------------------------------------------------------------- a folder became a file
@pytest.mark.parametrize("command", ["show", "render-map", "render-demo", "leaderboard"])
@pytest.mark.parametrize("overwrite", [False, True])
def test_file_outputs_never_replace_a_folder(command: str, overwrite: bool, tmp_path: Path,
                                             tiny_sequence: Path, done_run: RunFolder,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    target = _user_folder(tmp_path / "d")
    before = _snapshot(target)
    argvs: dict[str, list[str | Path]] = {
        "show": ["show", tiny_sequence, "--frame", "1", "--out", target],
        "render-map": ["render-map", _ply(tmp_path), "-o", target, "--width", "16",
                       "--height", "12"],
        "render-demo": ["render-demo", "-o", target],
        "leaderboard": ["leaderboard", done_run.path.parent, "-o", target,
                        "--metrics", "ate", "--no-eval"],
    }
    argv = argvs[command] + (["--overwrite"] if overwrite else [])
    code, _, err = run_cli(capsys, *argv)
    expected = ("is a folder: --overwrite only replaces" if overwrite
                else "already exists and is a folder; choose another")
    assert_cli_error(code, err, 2, f"{target}: {expected}")
    assert target.is_dir() and _snapshot(target) == before


def test_overwrite_replaces_only_an_output_of_the_same_kind(tmp_path: Path, tiny_sequence: Path,
                                                            capsys: pytest.CaptureFixture[str]
                                                            ) -> None:
    notes = tmp_path / "panel.png"
    notes.write_text("not an image, my notes\n")
    code, _, err = run_cli(capsys, "show", tiny_sequence, "--frame", "1", "--out", notes,
                           "--overwrite")
    assert_cli_error(code, err, 2, f"{notes}: is not a PNG image: --overwrite only replaces a PNG")
    assert notes.read_text() == "not an image, my notes\n"
    png = tmp_path / "old.png"
    write_ldr_image(png, np.zeros((4, 4, 3), np.uint8))
    code, _, err = run_cli(capsys, "show", tiny_sequence, "--frame", "1", "--out", png)
    assert_cli_error(code, err, 2, f"{png}: already exists; pass --overwrite")
    assert read_ldr_image(png).shape == (4, 4, 3)  # kept without --overwrite
    assert run_cli(capsys, "show", tiny_sequence, "--frame", "1", "--out", png,
                   "--overwrite")[0] == 0
    assert read_ldr_image(png).shape[1] > 300  # the panel replaced it


def test_atomic_writes_refuse_folders_and_leave_no_temporary_files(tmp_path: Path) -> None:
    folder = _user_folder(tmp_path / "out.txt")
    with pytest.raises(OutputError, match="is a folder that is not empty; refusing to replace"):
        with atomic_path(folder) as tmp:
            tmp.write_text("x")
    empty = tmp_path / "empty.txt"
    empty.mkdir()
    with pytest.raises(OutputError, match="is a folder; refusing to replace it with a file"):
        with atomic_path(empty) as tmp:
            tmp.write_text("x")
    empty.rmdir()
    with pytest.raises(RuntimeError), atomic_path(tmp_path / "f.txt") as tmp:
        tmp.write_text("half")
        raise RuntimeError("writer failed")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.txt"]


# ---------------------------------------------------------------- run --out <finished run>
def test_run_into_a_finished_run_needs_overwrite_and_keeps_user_files(
        tmp_path: Path, room_sequence: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    argv: list[str | Path] = ["run", "--method", "monogs", "--seq", room_sequence, "--out", out,
                              *QUICK_RUN]
    assert run_cli(capsys, *argv)[0] == 0
    assert run_cli(capsys, "eval", out)[0] == 0
    (out / "my_notes.txt").write_text("keep me\n")
    before = _snapshot(out)
    code, _, err = run_cli(capsys, *argv)
    assert_cli_error(code, err, 2, f"{out}: already exists; pass --overwrite to replace it")
    assert _snapshot(out) == before  # metrics, renders, map: all still there
    code, _, err = run_cli(capsys, *argv, "--overwrite")
    assert code == 0, err
    assert not (out / "metrics.json").exists()  # the old run's evaluation went with it
    assert (out / "my_notes.txt").read_text() == "keep me\n"  # not written by a run: kept
    assert "kept 1 file(s) of the replaced run folder" in (out / "log.txt").read_text()


def test_run_out_must_be_a_run_folder(tmp_path: Path, tiny_sequence: Path,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    user = _user_folder(tmp_path / "docs")
    before = _snapshot(user)
    for extra in ([], ["--overwrite"]):
        code, _, err = run_cli(capsys, "run", "--method", "monogs", "--seq", tiny_sequence,
                               "--out", user, *QUICK_RUN, *extra)
        assert_cli_error(code, err, 2, user, "has no readable run.yaml")
    assert _snapshot(user) == before


# ---------------------------------------------------------------- the current directory,
# the input, a parent of the input
def test_make_synthetic_never_replaces_the_current_directory(tmp_path: Path,
                                                             monkeypatch: pytest.MonkeyPatch,
                                                             capsys: pytest.CaptureFixture[str]
                                                             ) -> None:
    work = _user_folder(tmp_path / "work")
    monkeypatch.chdir(work)
    before = _snapshot(work)
    code, _, err = run_cli(capsys, "make-synthetic", "--scene", "office", "--out", ".",
                           "--frames", "2", "--width", "32", "--height", "24", "--overwrite",
                           "--no-progress")
    assert_cli_error(code, err, 2, "is the current directory or one of its parents")
    assert _snapshot(work) == before and sorted(os.listdir(work)) == ["notes.txt", "sub"]


def test_make_eventreplica_never_replaces_its_input(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    from egs_bench.datasets.replica import export_replica_layout
    from egs_bench.geometry import Intrinsics

    scene = export_replica_layout([np.full((24, 32, 3), 128, np.uint8)] * 3,
                                  [np.ones((24, 32))] * 3, [np.eye(4)] * 3, tmp_path / "scene",
                                  intrinsics=Intrinsics(30.0, 30.0, 16.0, 12.0, 32, 24),
                                  image_format="png")
    before = _snapshot(scene)
    for out in (scene, tmp_path):  # the input itself, a folder containing it
        code, _, err = run_cli(capsys, "make-eventreplica", "--input", scene, "--out", out,
                               "--overwrite", "--width", "32", "--height", "24", "--no-progress")
        assert_cli_error(code, err, 2, out, "is an input of this command" if out == scene
                         else f"contains the input {scene}")
    assert _snapshot(scene) == before


def test_generated_sequences_are_replaced_only_when_clean_and_asked(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "seq"
    argv: list[str | Path] = ["make-synthetic", "--scene", "office", "--out", out, "--frames",
                              "2", "--width",
            "32", "--height", "24", "--no-progress"]
    assert run_cli(capsys, *argv)[0] == 0
    first = _snapshot(out)
    code, _, err = run_cli(capsys, *argv, "--seed", "3")
    assert_cli_error(code, err, 2, f"{out}: already exists; pass --overwrite")
    assert _snapshot(out) == first
    (out / "notes.txt").write_text("mine\n")
    code, _, err = run_cli(capsys, *argv, "--seed", "3", "--overwrite")
    assert_cli_error(code, err, 2, out, "also holds files egs-bench did not write (notes.txt)")
    (out / "notes.txt").unlink()
    assert run_cli(capsys, *argv, "--seed", "3", "--overwrite")[0] == 0
    assert _snapshot(out) != first and len(Sequence.open(out)) == 2
    assert [p.name for p in tmp_path.iterdir()] == ["seq"]  # no staging folder left


def test_protected_paths_even_with_overwrite(tmp_path: Path, monkeypatch: pytest.MonkeyPatch
                                             ) -> None:
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    home = _user_folder(tmp_path / "home")
    for path in (home, Path(home.anchor)):
        with pytest.raises(OutputError, match="home directory or one of its parents|root"):
            prepare_output(path, "sequence", overwrite=True)


# ---------------------------------------------------------------- unwritable output locations
def test_output_under_a_file_is_a_clear_data_error(tmp_path: Path, tiny_sequence: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    blocker = tmp_path / "file.txt"
    blocker.write_text("x")
    code, _, err = run_cli(capsys, "show", tiny_sequence, "--frame", "1", "--out",
                           blocker / "panel.png")
    assert_cli_error(code, err, 3, f"{blocker}/panel.png: {blocker} is a file, not a folder")


@pytest.mark.skipif(os.geteuid() == 0, reason="root ignores folder permissions")
def test_read_only_output_folder_is_a_clear_data_error(tmp_path: Path, tiny_sequence: Path,
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        code, _, err = run_cli(capsys, "show", tiny_sequence, "--frame", "1", "--out",
                               ro / "p.png")
        assert_cli_error(code, err, 3, ro, "permission denied")
        with pytest.raises(UnwritableOutputError):
            prepare_output(ro / "seq", "sequence")
    finally:
        ro.chmod(0o700)


def test_demo_rewrites_only_its_own_outputs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch
                                            ) -> None:
    """The demo resumes into its folder: a foreign file where its panel goes is not replaced."""
    from egs_bench.demo import run_demo

    out = tmp_path / "demo"
    out.mkdir()
    shutil.copytree(Path(__file__).parent, out / "unrelated")  # any user content
    panel = out / "seq_frame.png"
    panel.write_text("not a png")
    monkeypatch.setenv("EGS_BENCH_DATA", str(tmp_path / "data"))
    with pytest.raises(OutputError, match="seq_frame.png: is not a PNG image"):
        run_demo(out, sequence=str(_plane(tmp_path)), methods=(), say=lambda _t: None,
                 progress=False)
    assert panel.read_text() == "not a png"


def _plane(tmp_path: Path) -> Path:
    from tests.helpers.plane_scene import make_plane_sequence

    return make_plane_sequence(tmp_path / "seq", frames=2)


def test_overwrite_never_replaces_a_file_inside_an_input_folder(seq_copy: Path,
                                                                capsys: pytest.CaptureFixture[str]
                                                                ) -> None:
    frame = seq_copy / "rgb" / "000001.png"
    before = frame.read_bytes()
    code, _, err = run_cli(capsys, "show", seq_copy, "--frame", "1", "--out", frame,
                           "--overwrite")
    assert_cli_error(code, err, 2, frame, f"is inside the input {seq_copy}; refusing to replace it")
    assert frame.read_bytes() == before
    new = seq_copy / "panel.png"  # a new file next to the inputs replaces nothing: allowed
    assert run_cli(capsys, "show", seq_copy, "--frame", "1", "--out", new)[0] == 0


@pytest.mark.parametrize("name", ["status.json", "000012.png", "map", "trajectory.txt"])
def test_atomic_temp_names_are_recognised(tmp_path: Path, name: str) -> None:
    """The names ``atomic_path`` writes under are what ``is_atomic_temp`` recognises (a killed
    writer's leftover is deleted with the run that wrote it), and a user's dot-file is not."""
    from egs_bench.fileio import is_atomic_temp

    with atomic_path(tmp_path / name) as tmp:
        assert is_atomic_temp(tmp.name), tmp.name
        tmp.write_text("x")
    assert not is_atomic_temp(name)
    for other in (".notes.txt.swp", ".status.json.part.json", ".x.0123456789ab.partial"):
        assert not is_atomic_temp(other), other
