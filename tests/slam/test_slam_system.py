"""End-to-end SLAM runs on the tiny generated sequence, method registry and CLI."""

from __future__ import annotations

import json
import signal
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch
import yaml
from typer.testing import CliRunner

import egs_bench.cli.slam_cmds  # noqa: F401  (registers the commands)
from egs_bench.cli.app import app
from egs_bench.datasets.sequence import Sequence
from egs_bench.errors import ConfigError, InputError, Interrupted
from egs_bench.render import GaussianMap
from egs_bench.render.ply import load_ply
from egs_bench.runs import registry
from egs_bench.runs.folder import RunFolder
from egs_bench.slam import methods
from egs_bench.slam.components import SlamComponents
from egs_bench.slam.config import cpu_preset
from egs_bench.slam.context import SlamContext
from egs_bench.slam.crf import CameraResponse
from egs_bench.slam.runner import RunSettings, run_slam
from egs_bench.slam.tracker import GradientTracker, TrackRequest, TrackResult
from tests.helpers.cli import assert_cli_error, run_cli

# Small but complete: every stage runs (init mapping, tracking with events, keyframe mapping).
FAST = dict(resolution_scale=1.0, init_iters=20, tracking_iters=20, mapping_iters=3,
            views_per_iter=2, kf_interval=2, pcd_downsample_init=2, pcd_downsample=4)


QUIET = RunSettings(preset="cpu", progress=False)


Around = Callable[[GradientTracker, GaussianMap, CameraResponse, TrackRequest], TrackResult]


def tracker_wrapped(around: Around) -> SlamComponents:
    """Components whose tracker is ``around(inner, gmap, crf, request)`` around the built-in
    one (the seam a researcher's tracker plugs into)."""
    class Wrapped:
        def __init__(self, ctx: SlamContext) -> None:
            self.inner = GradientTracker(ctx)

        def track(self, gmap: GaussianMap, crf: CameraResponse, request: TrackRequest
                  ) -> TrackResult:
            return around(self.inner, gmap, crf, request)

    return SlamComponents(tracker=Wrapped)


@pytest.fixture(scope="module")
def egs_run(tiny_room: Path, tmp_path_factory: pytest.TempPathFactory
            ) -> tuple[RunFolder, Sequence]:
    seq = Sequence.open(tiny_room)
    cfg = methods.BUILTIN["egs"].config("cpu").replace(**FAST)
    run = run_slam(seq, tmp_path_factory.mktemp("runs") / "egs", method_name="egs", config=cfg,
                   settings=RunSettings(preset="cpu", seed=3, progress=False))
    return run, seq


@pytest.mark.parametrize("no_prior, expected", [(5, [(1, 5), (2, 2), (3, 2)]),
                                                (None, [(1, 2), (2, 2), (3, 2)])])
def test_frame_without_velocity_gets_the_no_prior_iteration_budget(
        tiny_sequence: Path, tmp_path: Path, no_prior: int | None,
        expected: list[tuple[int, int]]) -> None:
    """Frame 1 has no velocity to extrapolate: it is tracked with
    ``tracking_iters_no_prior`` iterations (None: ``tracking_iters``); later frames with
    ``tracking_iters``."""
    seq = Sequence.open(tiny_sequence)
    cfg = methods.BUILTIN["monogs"].config("cpu").replace(
        **{**FAST, "tracking_iters": 2, "init_iters": 2, "tracking_iters_no_prior": no_prior})
    used: list[tuple[int, int]] = []

    def counting(inner: GradientTracker, gmap: GaussianMap, crf: CameraResponse,
                 request: TrackRequest) -> TrackResult:
        res = inner.track(gmap, crf, request)
        used.append((request.obs.index, res.iterations))
        return res

    cfg = cfg.replace(converged_threshold=1e-12)  # run every iteration of the budget
    run_slam(seq, tmp_path / "run", method_name="monogs", config=cfg,
             settings=RunSettings(max_frames=4, progress=False),
             components=tracker_wrapped(counting))
    assert used == expected


@pytest.mark.slow
def test_egs_end_to_end_writes_complete_run(egs_run: tuple[RunFolder, Sequence]) -> None:
    run, seq = egs_run
    assert run.read_status().state == "done"
    traj = run.read_trajectory()
    assert len(traj.poses) == len(seq)
    np.testing.assert_allclose(traj.timestamps, seq.timestamps_s)
    np.testing.assert_allclose(traj.poses[0], seq.poses[0], atol=1e-9)  # frame 0 at GT
    kfs = run.read_keyframes()
    assert kfs is not None and kfs[0] == 0
    assert run.render_indices() == list(range(len(seq)))
    assert run.read_render(1).shape == (seq.height, seq.width, 3)
    assert (run.path / "map.ply").is_file()
    # radiance is non-negative: mapping projects colours onto >= 0 after every step
    assert float(load_ply(run.path / "map.ply").colors.min()) >= -1e-6
    stats = json.loads((run.path / "slam_stats.json").read_text())
    assert stats["gaussians"] > 0
    # the map's size after every frame, ending at the saved map's
    sizes = stats["gaussians_per_frame"]
    assert len(sizes) == len(seq) and sizes[-1] == stats["gaussians"]
    assert sizes[0] > 0 and min(sizes) > 0


@pytest.fixture(scope="module")
def small_room(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """8 frames of the `demo` motion at half its resolution (112x64): ~2.6 cm and ~1 deg per
    frame through the furnished office, 25 ms exposure, events."""
    from egs_bench.datasets.synthetic import make_synthetic

    return make_synthetic("office", tmp_path_factory.mktemp("small") / "office", frames=8,
                          width=112, height=64, speed=0.4, seed=7, exposure_ms=25.0,
                          progress=False)


@pytest.mark.slow
@pytest.mark.parametrize("method", ["egs", "monogs"])
def test_end_to_end_tracking_error_is_a_fraction_of_the_motion(small_room: Path, tmp_path: Path,
                                                               method: str) -> None:
    """The `cpu` preset as it is (the sequence's resolution, coarse-to-fine levels): the RMS
    error of the estimated T_tau must stay below 0.15 x that of a tracker that never moves
    (absolute error, no alignment: frame 0 is placed at GT). Measured: egs 0.98 cm, monogs
    0.72 cm, vs 9.13 cm for the stuck tracker."""
    seq = Sequence.open(small_room)
    cfg = methods.BUILTIN[method].config("cpu")
    run = run_slam(seq, tmp_path / method, method_name=method, config=cfg, settings=QUIET)
    traj = run.read_trajectory()
    err = np.sqrt(((traj.poses[:, :3, 3] - seq.poses[:, :3, 3]) ** 2).sum(1).mean())
    stuck = np.sqrt(((seq.poses[:1, :3, 3] - seq.poses[:, :3, 3]) ** 2).sum(1).mean())
    assert err < 0.15 * stuck, f"{method}: {err * 100:.2f} cm vs {stuck * 100:.2f} cm stuck"


def test_divergence_falls_back_to_retracking_then_previous_pose(tiny_sequence: Path,
                                                                tmp_path: Path) -> None:
    """A pose jump beyond the physical bound is detected, logged, re-tracked from the previous
    pose with half the learning rate, and if that diverges too the previous pose is kept."""
    seq = Sequence.open(tiny_sequence)
    cfg = methods.BUILTIN["monogs"].config("cpu").replace(
        **{**FAST, "tracking_iters": 2, "init_iters": 2})
    calls: list[tuple[int, float]] = []

    def jumpy(inner: GradientTracker, gmap: GaussianMap, crf: CameraResponse,
              request: TrackRequest) -> TrackResult:
        index, lr_scale = request.obs.index, request.lr_scale
        calls.append((index, lr_scale))
        res = inner.track(gmap, crf, request)
        # frame 1: the first attempt jumps 2 m; frame 2: both attempts jump
        if (index == 1 and lr_scale == 1.0) or index == 2:
            res.state.pose1_cw = res.state.pose1_cw.copy()
            res.state.pose1_cw[0, 3] += 2.0
        return res

    run = run_slam(seq, tmp_path / "run", method_name="monogs", config=cfg,
                   settings=RunSettings(max_frames=3, progress=False),
                   components=tracker_wrapped(jumpy))
    assert calls == [(1, 1.0), (1, 0.5), (2, 1.0), (2, 0.5)]
    assert run.read_status().state == "done"
    stats = json.loads((run.path / "slam_stats.json").read_text())
    assert len(stats["divergences"]) == 2
    assert all("pose jump" in d for d in stats["divergences"])
    poses = run.read_trajectory().poses
    step1 = np.linalg.norm(poses[1][:3, 3] - poses[0][:3, 3])
    assert step1 < 0.5  # the re-tracked estimate, not the 2 m jump
    np.testing.assert_allclose(poses[2], poses[1], atol=1e-12)  # previous pose kept
    log = (run.path / "log.txt").read_text()
    assert "tracking diverged" in log and "keeping the previous pose" in log


def test_cpu_run_is_deterministic(tiny_sequence: Path, tmp_path: Path) -> None:
    seq = Sequence.open(tiny_sequence)
    cfg = methods.BUILTIN["monogs"].config("cpu").replace(
        **{**FAST, "tracking_iters": 5, "init_iters": 5})
    settings = RunSettings(seed=1, max_frames=2, progress=False)
    a = run_slam(seq, tmp_path / "a", method_name="monogs", config=cfg, settings=settings)
    b = run_slam(seq, tmp_path / "b", method_name="monogs", config=cfg, settings=settings)
    np.testing.assert_array_equal(a.read_trajectory().poses, b.read_trajectory().poses)
    assert (a.path / "map.ply").read_bytes() == (b.path / "map.ply").read_bytes()


def test_single_frame_sequence(tiny_sequence: Path, tmp_path: Path) -> None:
    seq = Sequence.open(tiny_sequence)
    cfg = methods.BUILTIN["egs"].config("cpu").replace(
        **{**FAST, "init_iters": 3, "tracking_iters": 3})
    one = run_slam(seq, tmp_path / "one", method_name="egs", config=cfg,
                   settings=RunSettings(max_frames=1, progress=False))
    assert len(one.read_trajectory().poses) == 1


@pytest.mark.parametrize("exc,state,words", [
    (RuntimeError("CUDA out of memory"), "failed", "RuntimeError: CUDA out of memory"),
    (KeyboardInterrupt(), "interrupted", "SIGINT"),
    (Interrupted(signal.SIGTERM), "interrupted", "interrupted by SIGTERM"),
])
def test_failure_marks_run_failed_or_interrupted(tiny_sequence: Path, tmp_path: Path,
                                                 exc: BaseException, state: str,
                                                 words: str) -> None:
    seq = Sequence.open(tiny_sequence)
    cfg = methods.BUILTIN["monogs"].config("cpu").replace(**FAST)

    def boom(*_a: Any) -> TrackResult:
        raise exc

    with pytest.raises(type(exc)):
        run_slam(seq, tmp_path / "run", method_name="monogs", config=cfg, settings=QUIET,
                 components=tracker_wrapped(boom))
    status = RunFolder.open(tmp_path / "run").read_status()
    assert status.state == state and words in (status.reason or "")


def test_interrupted_run_keeps_the_trajectory_of_the_processed_frames(
        tiny_sequence: Path, tmp_path: Path) -> None:
    """Ctrl-C (or a cluster's SIGTERM) at frame 2: the run is marked interrupted and holds the
    poses of frames 0 and 1, so it can be scored over them."""
    seq = Sequence.open(tiny_sequence)
    cfg = methods.BUILTIN["monogs"].config("cpu").replace(**FAST)

    def stop_at_2(inner: GradientTracker, gmap: GaussianMap, crf: CameraResponse,
                  request: TrackRequest) -> TrackResult:
        if request.obs.index == 2:
            raise KeyboardInterrupt
        return inner.track(gmap, crf, request)

    with pytest.raises(KeyboardInterrupt):
        run_slam(seq, tmp_path / "run", method_name="monogs", config=cfg, settings=QUIET,
                 components=tracker_wrapped(stop_at_2))
    run = RunFolder.open(tmp_path / "run")
    assert run.read_status().state == "interrupted"
    traj = run.read_trajectory()
    assert len(traj.poses) == 2
    np.testing.assert_allclose(traj.timestamps, seq.timestamps_s[:2])


def test_registry_builtins_import_path_and_errors(tmp_path: Path, monkeypatch: pytest.MonkeyPatch
                                                  ) -> None:
    names = registry.available_methods()
    for n in ("egs", "egs-no-event-tracking", "egs-no-event-mapping", "egs-no-events",
              "egs-no-crf", "egs-no-ne-loss", "monogs"):
        assert n in names
    mono = methods.BUILTIN["monogs"].config("paper")
    assert mono.n_segments == 1 and not mono.method.event_tracking
    assert mono.method.crf == "identity"
    (tmp_path / "my_slam_plugin.py").write_text(
        "class M:\n    name = 'user-x'\n    description = 'test method'\n"
        "    def run(self, sequence, out, **kw):\n        raise NotImplementedError\n"
        "def make():\n    return M()\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    m = registry.get_method("my_slam_plugin:make")
    assert m.name == "user-x"
    registry.register_method(m)
    assert registry.available_methods()["user-x"] == "test method"
    with pytest.raises(ConfigError, match="cannot import"):
        registry.get_method("my_slam_plugin:missing")
    with pytest.raises(ConfigError, match="unknown method"):
        registry.get_method("nope")
    with pytest.raises(ConfigError, match="unknown SLAM option"):
        cpu_preset().replace(not_a_field=1)
    with pytest.raises(ConfigError, match="blur_model"):
        cpu_preset().replace(blur_model=False).validate()  # events need sub-poses


def test_cli_list_methods_and_bad_method(capsys: pytest.CaptureFixture[str]) -> None:
    runner = CliRunner()
    for argv in (["list-methods"], ["list", "methods"]):
        res = runner.invoke(app, argv)
        assert res.exit_code == 0 and "monogs" in res.output and "egs-no-crf" in res.output
    code, _, err = run_cli(capsys, "list", "nonsense")
    assert_cli_error(code, err, 2, "'nonsense' is not one of 'methods', 'scenes'")
    code, _, err = run_cli(capsys, "run", "--method", "nope", "--seq", "x")
    assert_cli_error(code, err, 2, "unknown method 'nope'; available: egs")


@pytest.mark.parametrize("options,anchored", [
    ({"continuous_exposure": True, "short_exposure_ratio": 0.0}, True),
    ({"short_exposure_ratio": 1.0}, True),  # every exposure is "short" against ratio 1
    ({"short_exposure_ratio": 0.0}, False),  # the paper: T_0 and T_tau both free
])
def test_anchored_exposure_places_t0_on_the_path_from_the_previous_frame(
        tiny_sequence: Path, options: dict, anchored: bool) -> None:
    """With ``continuous_exposure``, or for exposures shorter than ``short_exposure_ratio`` of
    the time since the previous exposure ended, tracking estimates T_tau only; T_0 of every
    tracked frame is the pose at f0 = (t_start - previous t_end) / (t_end - previous t_end) on
    the straight path from the previous frame's T_tau to this frame's T_tau. Otherwise T_0 is
    free and off that path."""
    from egs_bench.slam.exposure import exposure_path
    from egs_bench.slam.system import SlamSystem

    seq = Sequence.open(tiny_sequence)
    cfg = methods.BUILTIN["egs"].config("cpu").replace(
        **{**FAST, "tracking_iters": 3, "init_iters": 3, **options})
    states = SlamSystem(seq, cfg, seed=0).run(len(seq)).states
    for i in range(1, len(seq)):
        t0, t1 = seq.exposure(i)
        prev_end = seq.exposure(i - 1)[1]
        f0 = np.array([(t0 - prev_end) / (t1 - prev_end)])
        expect = exposure_path(states[i - 1].pose1_cw, states[i].pose1_cw, f0)[0][0]
        assert not np.array_equal(states[i].pose0_cw, states[i].pose1_cw)
        off_path = float(np.abs(states[i].pose0_cw - expect).max())
        if anchored:
            assert off_path < 1e-9
        else:
            assert off_path > 1e-6



@pytest.mark.parametrize("events", [True, False])
def test_black_frame_missing_depth_and_no_events_run_through(tiny_sequence: Path,
                                                             tmp_path: Path,
                                                             events: bool) -> None:
    """Frame 2 all black, half of frame 1's depth missing, and (second case) a sequence without
    events, run by the method without events (``egs`` itself is refused on it): the run
    completes with finite poses for every frame."""
    import shutil

    import cv2
    import yaml

    root = tmp_path / "seq"
    shutil.copytree(tiny_sequence, root)
    black = cv2.imread(str(root / "rgb" / "000002.png"))
    cv2.imwrite(str(root / "rgb" / "000002.png"), np.zeros_like(black))
    depth_path = str(root / "depth" / "000001.png")
    depth = cv2.imread(depth_path, cv2.IMREAD_UNCHANGED)
    assert depth is not None
    depth[:, : depth.shape[1] // 2] = 0
    cv2.imwrite(depth_path, depth)
    if not events:
        meta = yaml.safe_load((root / "meta.yaml").read_text())
        meta["has_events"] = False
        (root / "meta.yaml").write_text(yaml.safe_dump(meta))
        (root / "events.h5").unlink()
    seq = Sequence.open(root)
    assert seq.has_events is events
    name = "egs" if events else "egs-no-events"
    cfg = methods.BUILTIN[name].config("cpu").replace(
        **{**FAST, "init_iters": 3, "tracking_iters": 3})
    if not events:  # an event method on a sequence without events is refused up front
        with pytest.raises(InputError, match=r"meta.yaml: has_events is false, but the method "
                                             r"uses events \(event_tracking, event_mapping\)"):
            run_slam(seq, tmp_path / "egs", method_name="egs",
                     config=methods.BUILTIN["egs"].config("cpu"), settings=QUIET)
        assert not (tmp_path / "egs").exists()
    run = run_slam(seq, tmp_path / "run", method_name=name, config=cfg, settings=QUIET)
    assert run.read_status().state == "done"
    poses = run.read_trajectory().poses
    assert len(poses) == len(seq) and np.isfinite(poses).all()


def test_parse_overrides_types_and_errors() -> None:
    from egs_bench.slam.config import parse_overrides

    got = parse_overrides(["lambda_d=0.05", "method.crf=srgb", "theta=null",
                           "tracking_iters=40", "event_mapping=false", "views_per_iter=3",
                           "lambda_e=1", "kf_interval=2"])
    assert got == {"loss.lambda_d": 0.05, "method.crf": "srgb", "method.theta": None,
                   "budget.tracking_iters": 40, "method.event_mapping": False,
                   "budget.views_per_iter": 3, "loss.lambda_e": 1.0, "keyframes.interval": 2}
    assert isinstance(got["loss.lambda_e"], float)
    for bad, words in [("lambda_d", "KEY=VALUE"), ("foo=1", "unknown"),
                       ("tracking_iters=1.5", "integer"), ("event_mapping=2", "true or false"),
                       ("lambda_d=abc", "finite number"), ("lambda_d=nan", "finite number"),
                       ("crf=bogus", "one of"), ("backend=bogus", "runtime.backend"),
                       ("extra=1", "unknown"), ("loss.nope=1", "unknown")]:
        with pytest.raises(ConfigError, match=words):
            parse_overrides([bad])


def test_extra_options_for_user_components() -> None:
    """``extra.NAME`` sets a free value a user's component reads (e.g. a loss weight); it is
    kept in the resolved configuration and survives its round trip."""
    from egs_bench.slam.config import SlamConfig, parse_overrides

    got = parse_overrides(["extra.lambda_tv=0.5", "extra.mode=fast"])
    assert got == {"extra.lambda_tv": 0.5, "extra.mode": "fast"}
    cfg = cpu_preset().replace(**got)
    assert cfg.extra == {"lambda_tv": 0.5, "mode": "fast"}
    assert SlamConfig.from_dict(cfg.to_dict()) == cfg
    for bad in ("extra.=1", "extra.a.b=1", "extra.x=nan"):
        with pytest.raises(ConfigError, match="extra"):
            parse_overrides([bad])


def test_every_option_is_validated_and_presets_differ_only_in_budget() -> None:
    from egs_bench.slam.config import GROUPS, SlamConfig, paper_preset

    cpu, paper = cpu_preset(), paper_preset()
    for group in GROUPS:
        if group != "budget":
            assert getattr(cpu, group) == getattr(paper, group), group
    assert cpu.budget != paper.budget
    for key, value in [("lambda_d", -0.1), ("resolution_scale", 0.0), ("tracking_iters", -1),
                       ("overlap", 1.5), ("window_size", 2), ("prune_opacity", 1.0),
                       ("short_exposure_ratio", 2.0), ("crf_nodes", 1), ("theta", 0.0),
                       ("views_per_iter", 0), ("lr_rot", 0.0), ("near_plane", 0.0)]:
        with pytest.raises(ConfigError, match=key):
            cpu.replace(**{key: value}).validate()
    round_trip = SlamConfig.from_dict(cpu.to_dict())
    assert round_trip == cpu


def test_cli_run_set_overrides_reach_the_run_config(tiny_sequence: Path, tmp_path: Path) -> None:
    out = tmp_path / "run"
    res = CliRunner().invoke(app, [
        "run", "--method", "monogs", "--seq", str(tiny_sequence), "--preset", "cpu",
        "--out", str(out), "--max-frames", "1", "--quiet",
        "--set", "init_iters=2", "--set", "lambda_d=0.2"])
    assert res.exit_code == 0, res.output
    cfg = yaml.safe_load((out / "config.yaml").read_text())
    assert cfg["slam"]["loss"]["lambda_d"] == 0.2 and cfg["slam"]["budget"]["init_iters"] == 2
    res = CliRunner().invoke(app, ["run", "--method", "monogs", "--seq", str(tiny_sequence),
                                   "--set", "lambda_d=abc"])
    assert isinstance(res.exception, ConfigError) and "lambda_d" in str(res.exception)


def test_auto_preset_and_device(tiny_sequence: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
                                ) -> None:
    """Without --preset/--device a CPU machine runs the cpu budget on the CPU (the paper budget
    took over 6 minutes for frame 0 on 2 cores); CUDA, when present, gets the paper budget."""
    from egs_bench.slam.config import resolve_device, resolve_preset

    assert resolve_preset("auto", "cpu") == "cpu"
    assert resolve_preset("auto", "cuda") == resolve_preset("auto", "cuda:1") == "paper"
    assert resolve_preset("paper", "cpu") == "paper"
    with pytest.raises(ConfigError, match="unknown preset"):
        resolve_preset("fast", "cpu")
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    assert resolve_device("auto") == "cpu"
    with pytest.raises(ConfigError, match="no CUDA GPU"):
        resolve_device("cuda")
    with pytest.raises(ConfigError, match="unknown device"):
        resolve_device("tpu")
    out = tmp_path / "run"
    res = CliRunner().invoke(app, [
        "run", "--method", "monogs", "--seq", str(tiny_sequence), "--out", str(out),
        "--max-frames", "1", "--quiet", "--set", "init_iters=2"])
    assert res.exit_code == 0, res.output
    cfg = yaml.safe_load((out / "config.yaml").read_text())
    assert cfg["preset"] == "cpu" and cfg["device"] == "cpu"
    assert cfg["slam"]["budget"]["resolution_scale"] == methods.BUILTIN["monogs"].config(
        "cpu").budget.resolution_scale


def test_final_refinement_lowers_keyframe_loss_and_keeps_poses(tiny_sequence: Path) -> None:
    from egs_bench.slam.exposure import exposure_path
    from egs_bench.slam.render_model import blur_loss, prepare_targets
    from egs_bench.slam.system import SlamSystem

    seq = Sequence.open(tiny_sequence)
    cfg = methods.BUILTIN["egs"].config("cpu").replace(**FAST)
    system = SlamSystem(seq, cfg, seed=0)
    result = system.run(len(seq))
    states = {k: result.states[k] for k in result.keyframes}
    obs = {k: system.obs(k) for k in result.keyframes}
    poses = {k: (s.pose0_cw.copy(), s.pose1_cw.copy()) for k, s in states.items()}

    def keyframe_loss() -> float:
        total = 0.0
        for k, s in states.items():
            views = exposure_path(s.pose0_cw, s.pose1_cw, obs[k].fractions)[0]
            res = system.ctx.render(system.gmap, views, phase="mapping")
            targets = prepare_targets(obs[k], cfg, system.ctx.theta, tracking=False,
                                      use_events=True)
            exp_ab = torch.tensor([[s.exp_a, s.exp_b]])
            total += blur_loss(res, targets, system.crf, exp_ab, cfg, tracking=False,
                               eps=system.ctx.eps).item()
        return total / len(states)

    before = keyframe_loss()
    system.mapper.refine(states, obs, result.keyframes, 60)
    after = keyframe_loss()
    assert after < 0.9 * before, (before, after)
    for k, s in states.items():
        assert np.array_equal(s.pose0_cw, poses[k][0]) and np.array_equal(s.pose1_cw,
                                                                            poses[k][1])
    assert not system.gmap.means.requires_grad
