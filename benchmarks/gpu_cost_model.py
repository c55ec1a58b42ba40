"""GPU cost model: the FPS of a SLAM schedule on one H100/H200, from work counted on a CPU.

A run's GPU time is modelled as a sum over optimisation iterations. One iteration of phase
``p`` (tracking or mapping) that renders ``C`` cameras (sub-pose renders: K+1 per view with the
blur model, 1 without) and launches ``L`` device operations costs

    t_iter = L * launch_ms + C * camera_ms[p, family]      (one or more host-device syncs)
    t_iter = max(L * launch_ms, C * camera_ms[p, family])   (no sync: host and device overlap)

``family`` is ``blur`` (the blur model with events: ``egs`` and its ablations) or ``plain`` (one
pose per frame: ``monogs``). Every iteration measured so far has exactly one sync (BENCHMARKS
"SLAM overhead"), so the sync cost is not separable from the launch cost: it is folded into
``launch_ms``, and the no-sync rule is a prediction only. A run then costs

    init      = init_iters x t_iter(mapping, cameras of one keyframe)
    tracking  = sum over frames 1.. of tracking_iterations[frame] x t_iter(tracking)
    mapping   = sum over keyframe rounds of mapping_iters x t_iter(mapping, cameras of the round)
    total     = init + tracking + mapping                    (mapping_mode sequential)
    total     = init + max(tracking, mapping)                (concurrent: a prediction, assuming
                                                              the two share the GPU without slowing
                                                              each other)

where a round's cameras are (window keyframes + random older ones, capped at views_per_iter)
x cameras per view. Per-frame work outside the iterations (keyframe decisions, target
preparation) is folded into the tracking iteration cost because the data cannot separate it,
so a prediction with fewer tracking iterations per frame is optimistic.

Work counts (:func:`schedule_from_run`) come from a run folder written on any device, e.g. a
short CPU run: ``config.yaml`` (segments, blur model, init / mapping iterations, window size,
random keyframes, views per iteration, final refinement), ``slam_stats.json`` (tracking
iterations of every frame), ``keyframes.txt`` and ``log.txt`` (the keyframes each window
update removed). Launches per iteration are not in a run folder: they are the counts of
``bench_slam_overhead.py`` on the H200 (:data:`LAUNCHES`, JSON ``overhead`` section,
SLAM-side launching operations + gsplat operations, at 2 keyframes for mapping; assumed
independent of the window size).

Constants and the data they come from (all from one H200, 2026-11-27, commit 799729c,
``docs/notes/gpu_check_h200_2026-11-27_first.json``, paper budget, 25 frames of ``office1``):

* 4 free parameters (:class:`CostConstants`: ``launch_ms``, ``track_camera_ms``,
  ``map_camera_blur_ms``, ``map_camera_plain_ms``), fitted by least squares
  (:func:`fit_constants`) to 12 per-phase data points: for each method the tracking cost per
  iteration (median tracking-only frame / 100 iterations: egs 4.78 ms, monogs 3.31 ms) and the
  cost per mapping iteration of each of its 5 keyframe rounds (keyframe frame minus the median
  tracking frame, / 150 iterations: egs 28.6-72.8 ms at 10-30 cameras, monogs 3.7-5.6 ms at
  2-6 cameras).
* Held out (not used in the fit, reported by ``--table``): map initialisation of each method
  (frame 0 / 1050 iterations: egs 16.3 ms, monogs 2.9 ms) and the overhead script's own
  per-iteration times (egs tracking 5.5 ms, mapping 31.3 ms at 2 keyframes; monogs 3.1 ms,
  4.6 ms): 6 points.
* The two FPS figures ``--check`` tests (egs 0.37, monogs 1.78) are sums of the same frames
  the fit used, except frame 0, so they test the composition (frame counts, keyframe
  schedule, window growth) more than the constants; the held-out points are the independent
  test. Not fitted and not validated: anything at other resolutions, map sizes (the fit
  spans 6k-16k Gaussians) or GPUs; an H100 is assumed to cost the same as the H200.

    python benchmarks/gpu_cost_model.py --check          # exit 1 if a measured FPS is off > 25 %
    python benchmarks/gpu_cost_model.py --table          # measured vs model, and predictions
    python benchmarks/gpu_cost_model.py --run RUN [--tracking-iters-mean N] [--concurrent]
    python benchmarks/gpu_cost_model.py --fit            # refit the constants from the JSON
"""

from __future__ import annotations

import argparse
import dataclasses
import re
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from egs_bench.errors import ConfigError, EgsBenchError, InputError  # noqa: E402
from egs_bench.fileio import read_text  # noqa: E402
from egs_bench.runs.folder import read_json_object  # noqa: E402

MEASURED_JSON = ROOT / "docs" / "notes" / "gpu_check_h200_2026-11-27_first.json"
#: tolerance of ``--check`` on the measured FPS (relative)
CHECK_TOLERANCE = 0.25
#: device operations launched per iteration, by (phase, family): the H200 overhead counts
#: (SLAM-side launching operations + rasteriser operations) of MEASURED_JSON, not fitted
LAUNCHES: dict[tuple[str, str], float] = {
    ("tracking", "blur"): 146.25, ("mapping", "blur"): 251.15,
    ("tracking", "plain"): 95.85, ("mapping", "plain"): 140.65,
}
#: which measured method stands for which family
FAMILY_METHOD = {"blur": "egs", "plain": "monogs"}


@dataclass(frozen=True)
class CostConstants:
    """Fitted per-unit costs, milliseconds (see the module docstring for the data)."""

    launch_ms: float = 0.02591          # per launched operation, the one sync folded in
    track_camera_ms: float = 0.2217     # per camera of a tracking iteration
    map_camera_blur_ms: float = 2.222   # per camera of a mapping iteration, blur model + events
    map_camera_plain_ms: float = 0.2806  # per camera of a mapping iteration, one pose per view

    def camera_ms(self, phase: str, family: str) -> float:
        if phase == "tracking":
            return self.track_camera_ms
        return self.map_camera_blur_ms if family == "blur" else self.map_camera_plain_ms


@dataclass(frozen=True)
class Schedule:
    """The work of one run, as counted on any device.

    Attributes:
        label: what the schedule is (a run folder, a measured run, a hypothetical one).
        family: ``blur`` or ``plain`` (see the module docstring).
        cameras_per_view: cameras rendered per view and iteration (K+1, or 1).
        init_iters: map-initialisation iterations on frame 0 (one keyframe).
        tracking_iters: tracking iterations of each frame after frame 0, [frames - 1].
        mapping_iters: iterations of each keyframe round.
        mapping_cameras: cameras rendered per mapping iteration of each round, [rounds].
        refine_iters: final refinement iterations (one keyframe each).
        syncs_per_iter: host-device synchronisations per iteration (1 in today's code).
        concurrent: mapping overlapped with tracking (``mapping_mode: concurrent``).
        tracking_view_cameras, mapping_view_cameras: mean cameras rendered per view and
            iteration in that phase (None: ``cameras_per_view``; fewer where a coarse level
            renders fewer sub-poses, ``budget.*_coarse_segments``).
        tracking_pixel_share, mapping_pixel_share: mean pixels of a camera of that phase, as
            a fraction of a camera at the sequence's full resolution (1.0: the fitted runs;
            lower with ``resolution_scale`` < 1 or coarse-to-fine levels). How a camera's cost
            follows it is not measured on a GPU yet: see :data:`PIXEL_SCALINGS`.
    """

    label: str
    family: str
    cameras_per_view: int
    init_iters: int
    tracking_iters: tuple[int, ...]
    mapping_iters: int
    mapping_cameras: tuple[int, ...]
    refine_iters: int = 0
    syncs_per_iter: int = 1
    concurrent: bool = False
    tracking_pixel_share: float = 1.0
    mapping_pixel_share: float = 1.0
    tracking_view_cameras: float | None = None
    mapping_view_cameras: float | None = None

    @property
    def frames(self) -> int:
        return len(self.tracking_iters) + 1

    def view_cameras(self, phase: str) -> float:
        """Mean cameras per view and iteration of ``phase`` (``tracking`` or ``mapping``)."""
        mean = self.tracking_view_cameras if phase == "tracking" else self.mapping_view_cameras
        return float(self.cameras_per_view) if mean is None else mean

    def replace(self, **changes: Any) -> Schedule:
        return dataclasses.replace(self, **changes)


@dataclass(frozen=True)
class Prediction:
    """Predicted seconds per phase and the FPS over all frames of the schedule."""

    init_s: float
    tracking_s: float
    mapping_s: float
    total_s: float
    fps: float


#: How a camera's cost follows its pixel count, bracketing what no GPU run has measured yet:
#: ``cameras`` (a camera costs the same at any resolution: fixed per-camera work dominates,
#: the pessimistic end) and ``pixels`` (cost in proportion to pixels: the optimistic end).
PIXEL_SCALINGS = ("cameras", "pixels")


def iteration_ms(phase: str, family: str, cameras: float, syncs: int, c: CostConstants,
                 pixel_factor: float = 1.0) -> float:
    """Milliseconds of one iteration (module docstring): host launches and device rendering are
    serialised by a sync and overlap without one; ``pixel_factor`` scales the cameras' cost."""
    host = LAUNCHES[phase, family] * c.launch_ms
    device = cameras * c.camera_ms(phase, family) * pixel_factor
    return host + device if syncs >= 1 else max(host, device)


def predict(s: Schedule, c: CostConstants | None = None, scaling: str = "cameras"
            ) -> Prediction:
    """The predicted time of ``s`` on one H200 with constants ``c`` (default: the fitted ones),
    a camera's cost following its pixels as ``scaling`` says (:data:`PIXEL_SCALINGS`)."""
    c = c or CostConstants()
    if scaling not in PIXEL_SCALINGS:
        raise ConfigError(f"unknown pixel scaling {scaling!r} ({', '.join(PIXEL_SCALINGS)})")
    pixels = scaling == "pixels"
    track_f = s.tracking_pixel_share if pixels else 1.0
    map_f = s.mapping_pixel_share if pixels else 1.0

    def mapping_s(iters: int, cameras: float) -> float:
        return iters * iteration_ms("mapping", s.family, cameras, s.syncs_per_iter, c,
                                    map_f) / 1e3

    per_view = s.view_cameras("mapping") / s.cameras_per_view  # coarse levels' fewer sub-poses
    init = mapping_s(s.init_iters, s.view_cameras("mapping"))
    track = (sum(s.tracking_iters) / 1e3
             * iteration_ms("tracking", s.family, s.view_cameras("tracking"), s.syncs_per_iter,
                            c, track_f))
    mapping = (sum(mapping_s(s.mapping_iters, cams * per_view) for cams in s.mapping_cameras)
               + mapping_s(s.refine_iters, s.cameras_per_view))
    total = init + (max(track, mapping) if s.concurrent else track + mapping)
    return Prediction(init, track, mapping, total, s.frames / total if total > 0 else float("nan"))


# ------------------------------------------------------------------ counting the work

def _value(slam: dict[str, Any], group: str, name: str, path: Path) -> Any:
    try:
        return slam[group][name]
    except (KeyError, TypeError):
        raise InputError(path, f"no slam.{group}.{name} (not a SLAM run's configuration)"
                         ) from None


def build_schedule(label: str, slam: dict[str, Any], tracking_iters: list[int],
                   keyframes: list[int], removed: dict[int, int], source: Path) -> Schedule:
    """A :class:`Schedule` from a SLAM configuration (nested groups, as ``config.yaml``'s
    ``slam``), the tracking iterations of frames 1.., the keyframe indices (frame 0 first) and
    how many keyframes each keyframe's window update removed. ``source`` names the file a
    missing value is reported against."""
    blur = bool(_value(slam, "method", "blur_model", source))
    per_view = int(_value(slam, "budget", "segments", source)) + 1 if blur else 1
    window_size = int(_value(slam, "budget", "window_size", source))
    n_random = int(_value(slam, "mapping", "n_random_kfs", source))
    views_cap = _value(slam, "budget", "views_per_iter", source)
    cameras = []
    window = 1
    for count, kf in enumerate(keyframes[1:], start=2):
        # the window gains the new keyframe and loses what update_window removed (at most
        # window_size); random views come from the keyframes outside it
        window = min(window + 1 - removed.get(kf, 0), window_size)
        views = window + min(n_random, count - window)
        if views_cap is not None:
            views = min(views, int(views_cap))
        cameras.append(views * per_view)
    # mapping_mode arrives with the concurrent engine; absent means sequential
    modes = [g.get("mapping_mode") for g in slam.values() if isinstance(g, dict)]
    budget = slam.get("budget") or {}
    return Schedule(
        label=label, family="blur" if blur else "plain", cameras_per_view=per_view,
        init_iters=int(_value(slam, "budget", "init_iters", source)),
        tracking_iters=tuple(int(i) for i in tracking_iters),
        mapping_iters=int(_value(slam, "budget", "mapping_iters", source)),
        mapping_cameras=tuple(cameras),
        refine_iters=int(_value(slam, "mapping", "refine_iters", source)),
        concurrent="concurrent" in modes,
        tracking_pixel_share=level_share(budget, "tracking", per_view - 1 if blur else None),
        mapping_pixel_share=level_share(budget, "mapping", per_view - 1 if blur else None),
        tracking_view_cameras=level_cameras(budget, "tracking", per_view - 1) if blur else None,
        mapping_view_cameras=level_cameras(budget, "mapping", per_view - 1) if blur else None)


def _levels(budget: dict[str, Any], phase: str, segments: int | None
            ) -> tuple[float, float, float, float]:
    """``(coarse fraction of the iterations, coarse scale, cameras per view at the coarse
    level, at the fine level)`` of ``phase``; ``segments``: K of the blur model (None without
    it). The coarse level's sub-poses follow the SLAM's own rule
    (:func:`egs_bench.slam.levels.kept_subposes`); fields a budget lacks count as off."""
    from egs_bench.slam.levels import kept_subposes

    coarse = float(budget.get(f"{phase}_coarse_scale", 1.0))
    fraction = float(budget.get(f"{phase}_coarse_fraction", 0.0)) if coarse < 1.0 else 0.0
    if segments is None:
        return fraction, coarse, 1.0, 1.0
    kept = kept_subposes(segments, budget.get(f"{phase}_coarse_segments"))
    return fraction, coarse, float(len(kept)), segments + 1.0


def level_share(budget: dict[str, Any], phase: str, segments: int | None = None) -> float:
    """A camera's mean pixels in ``phase`` as a fraction of the sequence's, from the budget:
    ``resolution_scale^2`` x the coarse and fine levels' pixel shares weighted by the cameras
    each renders (iterations x sub-poses, :func:`level_cameras`; ``segments``: K of the blur
    model, None without it) (egs_bench/slam/levels.py)."""
    scale = float(budget.get("resolution_scale", 1.0))
    fraction, coarse, coarse_cams, fine_cams = _levels(budget, phase, segments)
    pixels = fraction * coarse_cams * coarse ** 2 + (1.0 - fraction) * fine_cams
    return scale ** 2 * pixels / level_cameras(budget, phase, segments)


def level_cameras(budget: dict[str, Any], phase: str, segments: int | None) -> float:
    """Mean cameras per view in ``phase`` with K = ``segments``: the coarse fraction of the
    iterations renders the sub-poses its level keeps (``budget.{phase}_coarse_segments``), the
    rest ``K + 1`` (1 without the blur model, ``segments`` None)."""
    fraction, _, coarse_cams, fine_cams = _levels(budget, phase, segments)
    return fraction * coarse_cams + (1.0 - fraction) * fine_cams


_REMOVED = re.compile(r"frame (\d+): keyframe; window -\[([^\]]*)\]")


def schedule_from_run(run: Path) -> Schedule:
    """Count the work of a finished SLAM run folder (see the module docstring).

    Raises:
        InputError: naming the file that is missing or malformed.
    """
    cfg_path = run / "config.yaml"
    try:
        config = yaml.safe_load(read_text(cfg_path, "SLAM configuration"))
    except yaml.YAMLError as exc:
        raise InputError(cfg_path, f"not YAML ({str(exc).splitlines()[0]})") from None
    if not isinstance(config, dict) or not isinstance(config.get("slam"), dict):
        raise InputError(cfg_path, "no 'slam' configuration (not a SLAM run)")
    stats_path = run / "slam_stats.json"
    iters = read_json_object(stats_path).get("tracking_iterations")
    if (not isinstance(iters, list) or not iters
            or not all(isinstance(i, int) and i >= 0 for i in iters)):
        raise InputError(stats_path, "'tracking_iterations' must be a non-empty list of "
                         "non-negative integers")
    kf_path = run / "keyframes.txt"
    try:
        keyframes = sorted(int(x) for x in read_text(kf_path, "keyframe list").split())
    except ValueError:
        raise InputError(kf_path, "not a list of frame indices") from None
    if not keyframes or keyframes[0] != 0:
        raise InputError(kf_path, "frame 0 must be the first keyframe")
    removed: dict[int, int] = {}
    log = run / "log.txt"
    if log.is_file():  # without a log no removals are known: the window is at its largest
        for m in _REMOVED.finditer(read_text(log)):
            removed[int(m.group(1))] = len([x for x in m.group(2).split(",") if x.strip()])
    # slam_stats' first entry is frame 0, whose "iterations" are the map initialisation's
    s = build_schedule(str(run), config["slam"], iters[1:], keyframes, removed, cfg_path)
    work = read_json_object(stats_path).get("work")
    full = _full_pixels(run)
    if isinstance(work, dict) and full:
        # the counted shares replace the budget's nominal ones (they include rounding)
        phases = work.get("by_phase") or {}
        shares = {p: phases[p]["pixels"] / (phases[p]["cameras"] * full)
                  for p in ("tracking", "mapping") if (phases.get(p) or {}).get("cameras")}
        s = s.replace(tracking_pixel_share=shares.get("tracking", s.tracking_pixel_share),
                      mapping_pixel_share=shares.get("mapping", s.mapping_pixel_share))
        track = phases.get("tracking") or {}
        if track.get("calls"):  # one view per tracking call: counted cameras per view
            s = s.replace(tracking_view_cameras=track["cameras"] / track["calls"])
    return s


def _full_pixels(run: Path) -> int | None:
    """Pixels of one camera at the run's sequence resolution (appearance.json's camera)."""
    path = run / "appearance.json"
    if not path.is_file():
        return None
    cam = read_json_object(path).get("camera") or {}
    try:
        return int(cam["width"]) * int(cam["height"])
    except (KeyError, TypeError, ValueError):
        return None


# ------------------------------------------------------------------ the measured H200 runs

def _measured(path: Path = MEASURED_JSON) -> dict[str, Any]:
    data = read_json_object(path)
    try:
        return {m: data["methods"][m] for m in FAMILY_METHOD.values()} | {
            "overhead": {o["method"]: o for o in data["overhead"]}}
    except (KeyError, TypeError):
        raise InputError(path, "no 'methods' / 'overhead' records of egs and monogs") from None


def measured_keyframes(record: dict[str, Any], path: Path = MEASURED_JSON) -> list[int]:
    """Keyframe indices of a measured run. The GPU check records only their count; a keyframe
    frame carries a 150-iteration mapping round, so it takes several times a tracking frame:
    the frames over 1.5 x the median after frame 0 (checked against the recorded count)."""
    times = np.asarray(record["per_frame_s"], dtype=np.float64)
    kfs = [0] + [int(i) + 1 for i in np.flatnonzero(times[1:] > 1.5 * np.median(times[1:]))]
    if len(kfs) != int(record["keyframes"]):
        raise InputError(path, f"{len(kfs)} long frames but {record['keyframes']} keyframes")
    return kfs


def measured_schedule(method: str, path: Path = MEASURED_JSON) -> Schedule:
    """The schedule of a measured H200 run: the paper preset's configuration of ``method``,
    its keyframes, no window removals (the window never fills in 25 frames) and 100 tracking
    iterations per frame (the paper budget's convergence test never stopped tracking early;
    BENCHMARKS "GPU")."""
    from egs_bench.slam.methods import BUILTIN

    record = _measured(path)[method]
    slam = BUILTIN[method].config("paper").to_dict()
    iters = [slam["budget"]["tracking_iters"]] * (int(record["frames"]) - 1)
    return build_schedule(f"{method}, measured run", slam, iters,
                          measured_keyframes(record, path), {}, path)


def fit_points(path: Path = MEASURED_JSON) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """The per-phase data points of the fit: the design matrix ``[n, 4]`` (coefficients of the
    four :class:`CostConstants` fields, in field order), the measured ms per iteration ``[n]``
    and a label per point."""
    rows, ms, labels = [], [], []
    for family, method in FAMILY_METHOD.items():
        record = _measured(path)[method]
        s = measured_schedule(method, path)
        times = np.asarray(record["per_frame_s"], dtype=np.float64)
        kfs = measured_keyframes(record, path)
        tracking = float(np.median(np.delete(times, kfs)))
        blur = family == "blur"
        rows.append([LAUNCHES["tracking", family], s.cameras_per_view, 0, 0])
        ms.append(1e3 * tracking / s.tracking_iters[0])
        labels.append(f"{method} tracking iteration")
        for kf, cams in zip(kfs[1:], s.mapping_cameras, strict=True):
            rows.append([LAUNCHES["mapping", family], 0, cams if blur else 0, 0 if blur else cams])
            ms.append(1e3 * (times[kf] - tracking) / s.mapping_iters)
            labels.append(f"{method} mapping iteration, {cams} cameras (frame {kf})")
    return np.asarray(rows, dtype=np.float64), np.asarray(ms), labels


def fit_constants(path: Path = MEASURED_JSON) -> CostConstants:
    """Least-squares fit of the four constants to :func:`fit_points`."""
    a, y, _ = fit_points(path)
    sol = np.linalg.lstsq(a, y, rcond=None)[0]
    return CostConstants(*(float(v) for v in sol))


def held_out(c: CostConstants, path: Path = MEASURED_JSON) -> list[tuple[str, float, float]]:
    """(label, measured ms per iteration, model ms) of the points the fit did not use."""
    data = _measured(path)
    out = []
    for family, method in FAMILY_METHOD.items():
        s = measured_schedule(method, path)
        init = iteration_ms("mapping", family, s.cameras_per_view, 1, c)
        out.append((f"{method} map initialisation iteration",
                     1e3 * data[method]["per_frame_s"][0] / s.init_iters, init))
        ov = data["overhead"][method]
        out.append((f"{method} tracking iteration (overhead script)",
                     ov["tracking"]["ms_per_iter"],
                     iteration_ms("tracking", family, s.cameras_per_view, 1, c)))
        views = ov["mapping"]["views"] * s.cameras_per_view
        out.append((f"{method} mapping iteration, {views} cameras (overhead script)",
                     ov["mapping"]["ms_per_iter"], iteration_ms("mapping", family, views, 1, c)))
    return out


def check(c: CostConstants, path: Path = MEASURED_JSON) -> list[tuple[str, float, float, bool]]:
    """(method, measured FPS, model FPS, within tolerance) for the two measured runs."""
    data = _measured(path)
    out = []
    for method in FAMILY_METHOD.values():
        fps = predict(measured_schedule(method, path), c).fps
        measured = float(data[method]["fps"])
        out.append((method, measured, fps, abs(fps / measured - 1) <= CHECK_TOLERANCE))
    return out


# ------------------------------------------------------------------ hypothetical schedules

def converged(s: Schedule, mean_iters: float) -> Schedule:
    """``s`` with tracking stopping after ``mean_iters`` iterations per frame on average."""
    total = round(mean_iters * len(s.tracking_iters))
    base, extra = divmod(total, max(len(s.tracking_iters), 1))
    iters = tuple(base + (i < extra) for i in range(len(s.tracking_iters)))
    return s.replace(label=f"{s.label}, tracking {mean_iters:g} iterations / frame",
                     tracking_iters=iters)


def paper_scale(method: str, frames: int = 300, preset: str = "paper") -> Schedule:
    """A ``frames``-frame run of ``method`` at ``preset``'s budget with a keyframe at every
    allowed interval (keyframes.interval), the window full and random keyframes added: the
    most mapping a run can do, for time estimates (the cpu-budget 300-frame runs had 69-75
    keyframes, this gives 75)."""
    from egs_bench.slam.methods import BUILTIN

    slam = BUILTIN[method].config(preset).to_dict()
    kfs = list(range(0, frames, int(slam["keyframes"]["interval"])))
    budget = slam["budget"]
    iters = [budget["tracking_iters"]] * (frames - 1)
    if frames > 1 and budget["tracking_iters_no_prior"] is not None and \
            slam["tracking"]["motion_model"] == "constant-velocity":
        iters[0] = budget["tracking_iters_no_prior"]  # frame 1 has no velocity yet
    return build_schedule(f"{method}, {preset} preset, {frames} frames, keyframe every "
                          f"{slam['keyframes']['interval']}", slam, iters, kfs, {}, Path("config"))


def preset_predictions(c: CostConstants, frames: tuple[int, ...] = (25, 300)) -> list[str]:
    """Markdown lines: every preset's predicted H200 FPS for egs and monogs over ``frames``
    of ``office1``, as the range between the two :data:`PIXEL_SCALINGS`. Predictions, not
    measurements: only the paper preset at full resolution was measured."""
    from egs_bench.slam.config import PRESETS

    lines = ["| prediction (H200, office1, keyframe every interval) | frames | pixels per "
             "tracking / mapping camera | FPS if a camera's cost follows its pixels | FPS if "
             "it does not |", "|---|---:|---:|---:|---:|"]
    for preset in PRESETS:
        for method in FAMILY_METHOD.values():
            for n in frames:
                s = paper_scale(method, n, preset)
                fast, slow = (predict(s, c, scaling).fps for scaling in ("pixels", "cameras"))
                lines.append(f"| {method}, {preset} | {n} | {s.tracking_pixel_share:.2f} / "
                             f"{s.mapping_pixel_share:.2f} | {fast:.2f} | {slow:.2f} |")
    return lines


def _fmt(p: Prediction) -> str:
    return (f"{p.fps:.2f} | {p.init_s:.1f} | {p.tracking_s:.1f} | {p.mapping_s:.1f} | "
            f"{p.total_s:.1f}")


def table(c: CostConstants, mean_iters: float, path: Path = MEASURED_JSON) -> list[str]:
    """Markdown lines: measured vs model for the two H200 runs, held-out points, and the
    model's predictions for hypothetical schedules (labelled)."""
    lines = ["| schedule (25 frames of office1, paper budget, H200) | FPS | init s | "
             "tracking s | mapping s | total s |", "|---|---:|---:|---:|---:|---:|"]
    data = _measured(path)
    for method in FAMILY_METHOD.values():
        s = measured_schedule(method, path)
        rec = data[method]
        lines.append(f"| {method} measured | {rec['fps']:.2f} | {rec['frame0_s']:.1f} | | | "
                     f"{rec['slam_wall_s']:.1f} |")
        lines.append(f"| {method} model | {_fmt(predict(s, c))} |")
        for variant in (converged(s, mean_iters), s.replace(concurrent=True),
                        converged(s, mean_iters).replace(concurrent=True)):
            what = variant.label.removeprefix(s.label).lstrip(", ") or "sequential"
            if variant.concurrent:
                what = (what + ", " if what != "sequential" else "") + "mapping concurrent"
            lines.append(f"| {method} prediction: {what} | {_fmt(predict(variant, c))} |")
    lines += ["", "| held-out point | measured ms / iteration | model ms |", "|---|---:|---:|"]
    lines += [f"| {label} | {m:.2f} | {p:.2f} |" for label, m, p in held_out(c, path)]
    lines += ["", "| prediction: 300 frames, keyframe every 4, full window | FPS | init s | "
              "tracking s | mapping s | total s |", "|---|---:|---:|---:|---:|---:|"]
    for method in FAMILY_METHOD.values():
        s = paper_scale(method)
        lines.append(f"| {method} sequential | {_fmt(predict(s, c))} |")
        both = converged(s, mean_iters).replace(concurrent=True)
        lines.append(f"| {method} tracking {mean_iters:g} / frame, mapping concurrent | "
                     f"{_fmt(predict(both, c))} |")
    return lines


def parse_constants(items: list[str]) -> CostConstants:
    """``NAME=VALUE`` overrides of :class:`CostConstants` (what-if studies, the test)."""
    names = {f.name for f in dataclasses.fields(CostConstants)}
    changes = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or name not in names:
            raise ConfigError(f"--constant {item!r}: expected NAME=VALUE with NAME one of "
                              f"{', '.join(sorted(names))}")
        try:
            changes[name] = float(value)
        except ValueError:
            raise ConfigError(f"--constant {item!r}: {value!r} is not a number") from None
        if not changes[name] >= 0:
            raise ConfigError(f"--constant {item!r}: must be >= 0")
    return dataclasses.replace(CostConstants(), **changes)


def exit_code_of(action: Callable[[], int]) -> int:
    """``action()``'s exit code; an :class:`EgsBenchError` becomes one line on stderr (naming
    the file or option) and its exit code, never a traceback."""
    try:
        return action()
    except EgsBenchError as exc:
        print(f"{Path(sys.argv[0]).name}: error: {exc}", file=sys.stderr)
        return exc.exit_code


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true",
                    help=f"exit 1 if the model misses a measured FPS by more than "
                         f"{CHECK_TOLERANCE * 100:.0f} %%")
    ap.add_argument("--table", action="store_true", help="measured vs model and predictions")
    ap.add_argument("--presets", action="store_true",
                    help="predicted FPS of every preset over 25 and 300 frames of office1")
    ap.add_argument("--fit", action="store_true", help="refit the constants, print them")
    ap.add_argument("--run", type=Path, action="append", default=[],
                    help="a SLAM run folder whose work to count and predict")
    ap.add_argument("--tracking-iters-mean", type=float, default=None, metavar="N",
                    help="prediction: tracking stops after N iterations per frame on average "
                         "(--table: default 50)")
    ap.add_argument("--concurrent", action="store_true",
                    help="prediction: mapping concurrent with tracking (--run)")
    ap.add_argument("--constant", action="append", default=[], metavar="NAME=VALUE",
                    help="replace a fitted constant (what-if)")
    ap.add_argument("--measured", type=Path, default=MEASURED_JSON,
                    help="the H200 gpu_check JSON the constants and the check refer to")
    args = ap.parse_args(argv)
    if not (args.check or args.table or args.fit or args.run or args.presets):
        ap.error("give --check, --table, --fit, --presets or --run RUN")
    if args.tracking_iters_mean is not None and not args.tracking_iters_mean >= 0:
        ap.error("--tracking-iters-mean must be >= 0")

    def act() -> int:
        c = parse_constants(args.constant)
        if args.fit:
            fitted = fit_constants(args.measured)
            a, y, labels = fit_points(args.measured)
            fit = a @ np.array(dataclasses.astuple(fitted))
            print(f"fitted ({len(y)} points, 4 parameters): {fitted}")
            for label, m, p in zip(labels, y, fit, strict=True):
                print(f"  {label}: measured {m:.2f} ms, fit {p:.2f} ms ({p / m - 1:+.0%})")
        for run in args.run:
            s = schedule_from_run(run)
            if args.tracking_iters_mean is not None:
                s = converged(s, args.tracking_iters_mean)
            if args.concurrent:
                s = s.replace(concurrent=True)
            p = predict(s, c)
            fast = predict(s, c, "pixels")
            print(f"{s.label}: {s.frames} frames, {len(s.mapping_cameras)} mapping rounds, "
                  f"mean tracking iterations {np.mean(s.tracking_iters or (0,)):.1f}"
                  f"{', mapping concurrent' if s.concurrent else ''}, pixels per camera "
                  f"{s.tracking_pixel_share:.2f} (tracking) / {s.mapping_pixel_share:.2f} "
                  f"(mapping) of the sequence's: prediction on one H200 "
                  f"{p.fps:.2f} FPS (init {p.init_s:.1f} s, tracking {p.tracking_s:.1f} s, "
                  f"mapping {p.mapping_s:.1f} s), {fast.fps:.2f} FPS if a camera's cost "
                  "follows its pixels")
        if args.table:
            print("\n".join(table(c, args.tracking_iters_mean or 50.0, args.measured)))
        if args.presets:
            print("\n".join(preset_predictions(c)))
        if args.check:
            results = check(c, args.measured)
            for method, measured, fps, ok in results:
                print(f"{method}: measured {measured:.2f} FPS, model {fps:.2f} FPS "
                      f"({fps / measured - 1:+.1%}): {'ok' if ok else 'OFF by more than 25 %'}")
            if not all(ok for *_, ok in results):
                return 1
        return 0

    return exit_code_of(act)


if __name__ == "__main__":
    sys.exit(main())
