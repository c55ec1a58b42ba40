"""metrics.json read back into RunMetrics: today's files, older files, corrupt files."""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from egs_bench.errors import InputError
from egs_bench.eval.evaluate import evaluate_run
from egs_bench.eval.metrics_file import METRICS_SCHEMA_VERSION, parse_metrics, read_metrics
from tests.helpers.eval_fixtures import make_run

DATA = Path(__file__).parent / "metrics_files"


@pytest.fixture(scope="module")
def evaluated(tmp_path_factory: pytest.TempPathFactory, eval_sequence: Path
              ) -> tuple[Path, dict[str, Any]]:
    """A run folder evaluated by today's code, and what evaluation returned."""
    run = make_run(tmp_path_factory.mktemp("runs"), eval_sequence)
    return run.path, evaluate_run(run.path, "egs")


def _rewrite(src: Path, dst_root: Path, change: Callable[[dict[str, Any]], object]) -> Path:
    """A copy of ``src``'s metrics.json in a fresh folder, its content passed through
    ``change``; returns the folder."""
    data = json.loads((src / "metrics.json").read_text())
    change(data)
    dst_root.mkdir(exist_ok=True)
    (dst_root / "metrics.json").write_text(json.dumps(data))
    return dst_root


def test_a_file_written_by_evaluation_reads_back_whole(evaluated: tuple[Path, dict[str, Any]]
                                                       ) -> None:
    run_dir, written = evaluated
    m = read_metrics(run_dir)
    assert m.protocol == "egs" and m.protocol_settings == written["protocol"]
    assert (m.method, m.sequence, m.status) == ("egs", "tiny", "done")
    assert m.schema_version == METRICS_SCHEMA_VERSION
    assert m.ate_rmse_m is not None and m.fps is not None
    assert m.ate_rmse_m == written["ate"]["rmse_m"] and 0.0 < m.ate_rmse_m < 0.05
    assert m.ate == written["ate"] and m.rpe == written["rpe"]
    rendering = written["rendering"]
    assert (m.psnr_db, m.ssim, m.lpips) == (rendering["psnr_db"], rendering["ssim"],
                                            rendering["lpips"])
    assert m.rendering is not None and m.rendering["per_frame"]["frame"] == [0, 5, 10]
    assert m.render_fps == 250.0 and m.fps == written["speed"]["fps"] and m.fps > 0
    assert (m.frames_processed, m.frames_in_sequence) == (12, 12)  # the whole sequence
    assert m.notes == tuple(written["notes"]) and m.tools == written["tools"]
    assert m.ate_poses == written["ate"]["n_matched"] == 12 and m.renders_scored == 3
    for rpe, spacing in ((m.rpe_per_frame, "per_frame"), (m.rpe_per_metre, "per_metre")):
        entry = written["rpe"][spacing]
        if entry["translation"] is None:  # a path shorter than 1 m has no per-metre pair
            assert rpe is None
            continue
        assert rpe is not None
        assert (rpe.translation_m, rpe.rotation_deg, rpe.n_pairs) == (
            entry["translation"]["rmse"], entry["rotation"]["rmse"],
            entry["translation"]["n_pairs"])
    assert m.rpe_per_frame is not None and m.rpe_per_frame.n_pairs == 11
    assert parse_metrics(written, run_dir / "metrics.json") == m  # JSON changes nothing


def test_a_file_without_the_sections_added_later_still_reads(evaluated: tuple[Path, dict[str, Any]],
                                                             tmp_path: Path) -> None:
    """Files written before RPE and coverage were recorded have neither key; a run without
    timing.json or renders has ``speed`` / ``rendering`` null."""
    run_dir, written = evaluated

    def older(data: dict[str, Any]) -> None:
        del data["rpe"], data["coverage"]
        data["speed"] = None

    m = read_metrics(_rewrite(run_dir, tmp_path / "old", older))
    assert m.rpe is None and (m.frames_processed, m.frames_in_sequence) == (None, None)
    assert m.rpe_per_frame is None and m.rpe_per_metre is None
    assert m.speed is None and m.fps is None and m.render_fps is None
    assert m.ate_rmse_m == written["ate"]["rmse_m"]
    assert m.psnr_db == written["rendering"]["psnr_db"]

    def required_only(data: dict[str, Any]) -> None:
        for key in set(data) - {"protocol", "ate"}:
            del data[key]

    minimal = read_metrics(_rewrite(run_dir, tmp_path / "minimal", required_only))
    assert minimal.protocol == "egs" and minimal.ate_rmse_m == written["ate"]["rmse_m"]
    assert minimal.notes == () and minimal.method is None and minimal.rendering is None
    assert minimal.renders_scored is None and minimal.ate_poses == written["ate"]["n_matched"]


def test_a_file_of_the_first_layout_reads(tmp_path: Path) -> None:
    """``metrics_files/metrics_4061f7e.json`` was written by ``evaluate_run`` at commit 4061f7e (the
    first metrics.json: no ``rpe``, no ``coverage``) on the fixtures of that commit."""
    shutil.copy(DATA / "metrics_4061f7e.json", tmp_path / "metrics.json")
    written = json.loads((tmp_path / "metrics.json").read_text())
    m = read_metrics(tmp_path)
    assert "rpe" not in written and "coverage" not in written
    assert m.rpe is None and (m.frames_processed, m.frames_in_sequence) == (None, None)
    assert (m.protocol, m.method, m.sequence, m.status) == ("egs", "egs", "tiny", "done")
    assert m.ate_rmse_m == written["ate"]["rmse_m"] and m.lpips == written["rendering"]["lpips"]
    assert (m.psnr_db, m.ssim) == (written["rendering"]["psnr_db"], written["rendering"]["ssim"])
    assert (m.fps, m.render_fps) == (written["speed"]["fps"], written["speed"]["render_fps"])


def _set(path: tuple[str, ...], value: Any) -> Callable[[dict[str, Any]], None]:
    def change(data: dict[str, Any]) -> None:
        for key in path[:-1]:
            data = data[key]
        data[path[-1]] = value
    return change


@pytest.mark.parametrize(("change", "problem"), [
    (lambda d: d.pop("ate"), "not an egs-bench metrics file (no 'protocol'/'ate')"),
    (lambda d: d.pop("protocol"), "not an egs-bench metrics file (no 'protocol'/'ate')"),
    (_set(("protocol",), "egs"), "'protocol' must be a mapping with a 'name'"),
    (_set(("protocol", "name"), None), "'protocol' must be a mapping with a 'name'"),
    (_set(("ate",), None), "'ate' must be a mapping with 'rmse_m', found None"),
    (_set(("ate",), 5), "expected a mapping with 'rmse_m', found int"),
    (_set(("ate", "rmse_m"), "0.01"), "'rmse_m' must be a number, found '0.01'"),
    (_set(("rendering", "ssim"), True), "'ssim' must be a number, found True"),
    (_set(("rendering",), [1.0]), "expected a mapping with 'psnr_db', found list"),
    (_set(("speed", "render_fps"), "fast"), "'render_fps' must be a number, found 'fast'"),
    (_set(("coverage", "frames_processed"), 11.5),
     "'coverage' needs integer frames_processed / frames_in_sequence"),
    (_set(("coverage",), [12, 12]), "'coverage' must be a mapping"),
    (_set(("run",), "egs"), "'run' must be a mapping"),
    (_set(("run", "method"), 3), "'method' must be a string, found 3"),
    (_set(("rpe",), []), "'rpe' must be a mapping"),
    (_set(("rpe", "per_frame"), 0.1), "'rpe.per_frame' must be a mapping"),
    (_set(("rpe", "per_frame", "translation", "n_pairs"), 2.5),
     "'n_pairs' must be a non-negative integer, found 2.5"),
    (_set(("ate", "n_matched"), -1), "'n_matched' must be a non-negative integer, found -1"),
    (_set(("tools", "torch"), 2.13), "'tools' must map tool names to version strings"),
    (_set(("notes",), "one note"), "'notes' must be a list of strings"),
    (_set(("schema_version",), "1"), "'schema_version' must be an integer, found '1'"),
])
def test_a_wrong_field_is_one_line_naming_the_file(evaluated: tuple[Path, dict[str, Any]],
                                                   tmp_path: Path, change: Any, problem: str
                                                   ) -> None:
    folder = _rewrite(evaluated[0], tmp_path / "bad", change)
    with pytest.raises(InputError) as info:
        read_metrics(folder)
    assert str(info.value) == f"{folder / 'metrics.json'}: {problem}"


@pytest.mark.parametrize(("content", "problem"), [
    (None, "not found (run `egs-bench eval` first)"),
    (b"{not json", "not valid JSON (Expecting property name enclosed in double quotes: "
                   "line 1 column 2 (char 1))"),
    (b"\x89PNG\r\n\x1a\n\x00\xff", "not a UTF-8 text file (binary or corrupt)"),
    (b"[1, 2]", "not an egs-bench metrics file (no 'protocol'/'ate')"),
])
def test_a_missing_or_unreadable_file_is_one_line_naming_it(tmp_path: Path, content: bytes | None,
                                                            problem: str) -> None:
    if content is not None:
        (tmp_path / "metrics.json").write_bytes(content)
    with pytest.raises(InputError) as info:
        read_metrics(tmp_path)
    assert str(info.value) == f"{tmp_path / 'metrics.json'}: {problem}"
    assert "\n" not in str(info.value)
