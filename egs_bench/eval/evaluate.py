"""Evaluate one run folder under a protocol and write its ``metrics.json``.

``metrics.json`` holds every number (summary and per frame), the full protocol, the run's identity
and status, and the versions of the tools that computed it. It contains no time stamps or
machine-specific paths, so evaluating the same run twice writes byte-identical files. It is read
back with :func:`egs_bench.eval.metrics_file.read_metrics`.
"""

from __future__ import annotations

import importlib.metadata
import json
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from egs_bench import __version__
from egs_bench.errors import InputError
from egs_bench.eval.ate import MIN_MATCHED_POSES, AteResult, compute_ate
from egs_bench.eval.image_metrics import psnr, psnr_masked, ssim
from egs_bench.eval.metrics_file import METRICS_SCHEMA_VERSION
from egs_bench.eval.protocols import DEFAULT_PROTOCOL, Alignment, Protocol, get_protocol
from egs_bench.fileio import write_text_atomic
from egs_bench.geometry import Trajectory, read_tum
from egs_bench.progress import tracked
from egs_bench.runs.folder import RunFolder

if TYPE_CHECKING:
    from egs_bench.datasets.sequence import Sequence

def _tool_versions() -> dict[str, str]:
    out = {"egs_bench": __version__}
    for dist in ("evo", "kornia", "torch", "numpy"):
        try:
            out[dist] = importlib.metadata.version(dist)
        except importlib.metadata.PackageNotFoundError:
            out[dist] = "not installed"
    return out


def _finite_or_none(value: Any) -> Any:
    """JSON has no inf/nan: store them as null (e.g. PSNR of identical images)."""
    if isinstance(value, dict):
        return {k: _finite_or_none(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_finite_or_none(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def open_sequence(path: Path) -> Sequence:
    """Open the run's sequence (import deferred: evaluation of trajectory-only runs needs none)."""
    from egs_bench.datasets.sequence import Sequence

    return Sequence.open(path, check_images=False)


def _ground_truth(run: RunFolder, seq: Sequence | None) -> tuple[Trajectory, str]:
    """The run's ground truth (its own file, else its sequence's) and the name to report."""
    if run.groundtruth_path is not None:
        return read_tum(run.groundtruth_path), str(run.groundtruth_path)
    if seq is None:
        raise ValueError(f"{run.path}: the run names neither a ground-truth file nor a "
                         "sequence, and no sequence was given")
    return Trajectory(np.asarray(seq.timestamps_s, dtype=np.float64),
                      np.asarray(seq.poses, dtype=np.float64)), str(seq.path / "groundtruth.txt")


def evaluate_ate(run: RunFolder, protocol: Protocol, seq: Sequence | None = None) -> dict[str, Any]:
    """ATE of the run under ``protocol``; returns the summary dict stored in ``metrics.json``."""
    return ate_summary(run, protocol, compute_run_ate(run, protocol, seq))


def ate_summary(run: RunFolder, protocol: Protocol, result: AteResult) -> dict[str, Any]:
    """The ``ate`` entry of ``metrics.json`` for a run's :class:`AteResult`."""
    summary = result.summary()
    summary["frames"] = protocol.ate_frames
    summary["estimate_poses"] = run.estimate["poses"]
    summary["per_pose"] = {"timestamp_s": result.timestamps.tolist(),
                           "error_m": result.errors.tolist()}
    return summary


def evaluate_rpe(run: RunFolder, protocol: Protocol, seq: Sequence | None = None) -> dict[str, Any]:
    """RPE of the run's whole estimated trajectory (per frame and per metre, translation and
    rotation; :func:`~egs_bench.eval.rpe.standard_rpe`): the summary stored in
    ``metrics.json``."""
    from egs_bench.eval.rpe import standard_rpe

    gt, gt_name = _ground_truth(run, seq)
    out = standard_rpe(run.read_trajectory(), gt, max_diff_s=protocol.ate_max_diff_s,
                       est_name=run.trajectory_path, gt_name=gt_name)
    out["frames"] = protocol.rpe_frames
    return out


def compute_run_ate(run: RunFolder, protocol: Protocol, seq: Sequence | None = None
                    ) -> AteResult:
    """The :class:`~egs_bench.eval.ate.AteResult` of a run under ``protocol``.

    Raises:
        InputError: a bad file of the run or sequence; under a keyframe protocol also a missing
            ``keyframes.txt``, or one listing fewer keyframes than the alignment needs (the
            message names ``keyframes.txt``, not the trajectories cut down to it).
    """
    est = run.read_trajectory()
    gt, gt_name = _ground_truth(run, seq)
    if protocol.ate_frames == "keyframes":
        keyframes = run.read_keyframes()
        if keyframes is None:
            raise InputError(run.path / "keyframes.txt",
                             f"not found; protocol {protocol.name!r} evaluates ATE on keyframes")
        if len(keyframes) < MIN_MATCHED_POSES:
            raise InputError(run.path / "keyframes.txt",
                             f"lists {len(keyframes)} keyframe(s); protocol {protocol.name!r} "
                             f"evaluates ATE on keyframes and the alignment needs at least "
                             f"{MIN_MATCHED_POSES} (use --protocol egs for all frames)")
        if seq is not None and run.groundtruth_path is None:
            if keyframes.max(initial=-1) >= len(gt):
                raise InputError(run.path / "keyframes.txt",
                                 f"keyframe {int(keyframes.max())} beyond the sequence's "
                                 f"{len(gt)} frames")
            gt = Trajectory(gt.timestamps[keyframes], gt.poses[keyframes])
        else:
            if keyframes.max(initial=-1) >= len(est):
                raise InputError(run.path / "keyframes.txt",
                                 f"keyframe {int(keyframes.max())} beyond the estimate's "
                                 f"{len(est)} poses")
            est = Trajectory(est.timestamps[keyframes], est.poses[keyframes])
    return compute_ate(est, gt, align=run_alignment(run, protocol),
                       max_diff_s=protocol.ate_max_diff_s, est_name=run.trajectory_path,
                       gt_name=gt_name)


def run_alignment(run: RunFolder, protocol: Protocol) -> Alignment:
    """The protocol's ATE alignment, except Sim(3) instead of SE(3) for a scale-free
    (monocular) imported estimate, whose metric scale is unknown."""
    if run.estimate["scale_free"] and protocol.ate_alignment == "se3":
        return "sim3"
    return protocol.ate_alignment


def _estimate_notes(run: RunFolder, protocol: Protocol, ate: dict[str, Any],
                    covered: int | None) -> list[str]:
    """Notes on what an (imported) estimate covers, so tables never pass it off as more."""
    est = run.estimate
    notes = []
    if ate["alignment"] != protocol.ate_alignment:
        notes.append(f"ATE with {ate['alignment']} alignment instead of the protocol's "
                     f"{protocol.ate_alignment}: the estimate is scale-free (monocular)")
    if est["poses"] != "all" and protocol.ate_frames == "all":
        of = f" of {covered}" if covered is not None else ""
        notes.append(f"ATE over {ate['n_matched']}{of} frames: the estimate holds "
                     f"{est['poses']} poses only")
    elif covered is not None and protocol.ate_frames == "all" and ate["n_matched"] < covered:
        notes.append(f"ATE over {ate['n_matched']} of {covered} frames: the estimate has no "
                     "pose for the others")
    if est["poses"] != "all":
        notes.append(f"RPE per frame pairs consecutive poses of the estimate ({est['poses']}), "
                     "not consecutive frames")
    if est["scale_free"]:
        notes.append("RPE translation is in the estimate's own scale (not aligned): not "
                     "comparable with metric estimates")
    return notes


def _partial_renders_note(run: RunFolder, protocol: Protocol, num_frames: int) -> str | None:
    """Why the renders of an estimate marked as partial (e.g. an import with keyframe renders
    only) cannot be scored under ``protocol``; None when they can (or the run is complete)."""
    kind = run.estimate["renders"]
    if kind == "all" or not run.render_indices():
        return None
    keyframes = run.read_keyframes()
    have = set(run.render_indices())
    if protocol.render_skip_keyframes and keyframes is None:
        return f"renders not scored: protocol {protocol.name!r} needs keyframes.txt"
    wanted = rendering_frames(num_frames, protocol, keyframes)
    if wanted and all(f in have for f in wanted):
        return None
    return (f"renders not scored: the estimate has renders of {kind} frames only "
            f"({len(have)}), protocol {protocol.name!r} scores every {protocol.render_stride}th "
            "frame")


def rendering_frames(num_frames: int, protocol: Protocol,
                     keyframes: np.ndarray | None) -> list[int]:
    """Frame indices whose renders the protocol scores."""
    frames = list(range(0, num_frames, protocol.render_stride))
    if protocol.render_skip_keyframes:
        if keyframes is None:
            raise ValueError("keyframes needed")
        kf = set(int(k) for k in keyframes)
        frames = [f for f in frames if f not in kf]
    return frames


def processed_frames(run: RunFolder, protocol: Protocol, seq: Sequence) -> int:
    """Number of leading sequence frames the run covers: those up to its last estimated pose.

    A run stopped early (e.g. ``--max-frames``) is scored on the frames it processed; the
    coverage is recorded in ``metrics.json`` and shown by leaderboards. An import whose
    estimate holds keyframes only records the frames the system read (``run.yaml``
    ``estimate.frames_processed``): its last keyframe is not where it stopped.
    """
    recorded = run.estimate.get("frames_processed")
    if isinstance(recorded, int) and not isinstance(recorded, bool) and recorded > 0:
        return min(recorded, len(seq))
    last = float(run.read_trajectory().timestamps[-1])
    stamps = np.asarray(seq.timestamps_s, dtype=np.float64)
    return int(np.searchsorted(stamps, last + protocol.ate_max_diff_s, side="right"))


def evaluate_renders(run: RunFolder, protocol: Protocol, seq: Sequence,
                     num_frames: int | None = None, progress: bool = False) -> dict[str, Any]:
    """PSNR / SSIM / LPIPS of the run's renders under ``protocol`` (per frame and mean).

    Without LPIPS weights (see :func:`egs_bench.eval.lpips.find_weights`) PSNR and SSIM are
    still computed; ``lpips`` is then ``None`` and ``lpips_weights.unavailable`` says why.

    Args:
        num_frames: score only frames below this index (default: the whole sequence).
    """
    from egs_bench.eval.lpips import LPIPS, LpipsWeightsError, load_lpips, lpips_distance

    keyframes = run.read_keyframes()
    if protocol.render_skip_keyframes and keyframes is None:
        raise InputError(run.path / "keyframes.txt",
                         f"not found; protocol {protocol.name!r} skips keyframes in rendering")
    frames = rendering_frames(len(seq) if num_frames is None else num_frames, protocol, keyframes)
    missing = [f for f in frames if not run.render_path(f).is_file()]
    if missing:
        raise InputError(run.render_path(missing[0]),
                         f"not found: protocol {protocol.name!r} scores {len(frames)} renders "
                         f"(every {protocol.render_stride}th frame), {len(missing)} are missing")
    try:
        model: LPIPS | None = load_lpips(protocol.lpips_net)
        lpips_problem = None
    except LpipsWeightsError:
        model = None
        lpips_problem = f"no pretrained LPIPS-{protocol.lpips_net} weights found (docs/guide/" \
                        "evaluation.md, LPIPS weights)"
    except InputError as exc:  # metrics.json holds no machine-specific paths: file name only
        model, lpips_problem = None, f"LPIPS weights unreadable ({exc.path.name}: {exc.problem})"
    per_frame: dict[str, list] = {"frame": [], "psnr_db": [], "ssim": [], "lpips": []}
    for i in tracked(frames, f"eval {run.method}/{run.sequence_name}", unit="frame",
                     enabled=progress):
        render = run.read_render(i)
        if protocol.reference_images == "sharp":
            ref = seq.sharp(i)
            if ref is None:
                raise InputError(seq.path, f"has no sharp ground truth for frame {i}; protocol "
                                           f"{protocol.name!r} compares renders with it")
        else:
            ref = seq.rgb(i)
        if render.shape != ref.shape:
            raise InputError(run.render_path(i),
                             f"render is {render.shape[1]}x{render.shape[0]}, the sequence's "
                             f"frames are {ref.shape[1]}x{ref.shape[0]}")
        p = psnr_masked(render, ref) if protocol.psnr == "masked" else psnr(render, ref)
        per_frame["frame"].append(i)
        per_frame["psnr_db"].append(p)
        per_frame["ssim"].append(ssim(render, ref, variant=protocol.ssim))
        per_frame["lpips"].append(lpips_distance(render, ref, net=protocol.lpips_net)
                                  if model is not None else None)
    lpips_mean = float(np.mean(per_frame["lpips"])) if frames and model is not None else None
    return {
        "n_frames": len(frames),
        "psnr_db": float(np.mean(per_frame["psnr_db"])) if frames else None,
        "ssim": float(np.mean(per_frame["ssim"])) if frames else None,
        "lpips": lpips_mean,
        "lpips_weights": {"net": protocol.lpips_net, "source": model.source,
                          "sha256": model.sha256} if model is not None
        else {"net": protocol.lpips_net, "unavailable": lpips_problem},
        "per_frame": per_frame,
    }


def _missing_renders(run: RunFolder, protocol: Protocol, seq: Sequence, num_frames: int) -> int:
    """How many of the renders ``protocol`` scores are missing (0 when keyframes are needed but
    missing: :func:`evaluate_renders` then names that file)."""
    keyframes = run.read_keyframes()
    if protocol.render_skip_keyframes and keyframes is None:
        return 0
    frames = rendering_frames(num_frames, protocol, keyframes)
    return sum(not run.render_path(f).is_file() for f in frames)


def evaluate_run(run_dir: str | Path, protocol: str | Protocol = DEFAULT_PROTOCOL, *,
                 write: bool = True, progress: bool = False) -> dict[str, Any]:
    """Evaluate a finished run folder; optionally write ``metrics.json`` (atomically).

    Args:
        run_dir: the run folder.
        protocol: protocol name or object (see :mod:`egs_bench.eval.protocols`).
        write: write ``<run_dir>/metrics.json``.
        progress: show a progress bar over the scored frames.

    Returns:
        The ``metrics.json`` content. ``rendering`` is ``None`` for runs without renders or
        without a sequence (trajectory-only imports); ``speed`` is ``None`` without
        ``timing.json``.

    An ``interrupted`` run (stopped by a signal, or its process is gone) is scored on what it
    wrote, with a note; what it did not write is named in the error or the notes.

    Raises:
        InputError: the run is missing, still running, failed, interrupted before writing a
            trajectory, or any of its files is bad (the message names the file).
    """
    proto = get_protocol(protocol) if isinstance(protocol, str) else protocol
    run = RunFolder.open(run_dir)
    status = run.read_status()
    notes: list[str] = []
    if status.state == "failed":
        raise InputError(run.path, f"run failed ({status.reason}); nothing to evaluate")
    if status.state == "running":
        who = f" (pid {status.pid} on {status.host})" if status.pid is not None else ""
        raise InputError(run.path, f"run is still running{who}; evaluate it once it is done")
    if status.state == "interrupted":
        if not run.trajectory_path.is_file():
            raise InputError(run.path, f"run was interrupted ({status.reason}) before it wrote "
                                       f"{run.trajectory_path.name}: nothing to evaluate")
        notes.append(f"the run was interrupted ({status.reason}); metrics cover what it wrote")
    seq = open_sequence(run.sequence_path) if run.sequence_path is not None else None

    ate_result = compute_run_ate(run, proto, seq)
    ate = ate_summary(run, proto, ate_result)
    notes += ate_result.notes
    rpe = evaluate_rpe(run, proto, seq)
    rendering = None
    coverage = None
    covered = 0
    if seq is not None:
        covered = processed_frames(run, proto, seq)
        coverage = {"frames_processed": covered, "frames_in_sequence": len(seq)}
        if proto.ate_frames == "all" and run.estimate["poses"] != "all":
            # the protocol scores every frame's pose and the estimate has only some: it covers
            # the frames it matched (a keyframe-only run is partial here, complete under a
            # protocol that scores keyframes)
            coverage["frames_processed"] = min(covered, int(ate["n_matched"]))
        if covered < len(seq):
            notes.append(f"the run covers {covered} of the sequence's {len(seq)} frames; "
                         "metrics are over those")
    notes += _estimate_notes(run, proto, ate, covered if coverage else None)
    partial = (_partial_renders_note(run, proto, covered)
               if coverage is not None else None)
    if seq is None:
        if run.render_indices():
            notes.append("renders not scored: the run has no sequence folder with reference "
                         "images")
    elif not run.render_indices():
        notes.append("no renders in the run folder: rendering metrics not computed")
    elif proto.reference_images == "sharp" and not seq.has_sharp:
        notes.append("image metrics unavailable: the sequence has no sharp ground truth (a real "
                     "recording); ATE only")
    elif partial:
        notes.append(partial)
    elif status.state == "interrupted" and _missing_renders(run, proto, seq, covered):
        notes.append(f"the interrupted run lacks {_missing_renders(run, proto, seq, covered)} of "
                     "the renders the protocol scores: rendering metrics not computed")
    else:
        rendering = evaluate_renders(run, proto, seq, covered, progress=progress)
        if rendering["lpips"] is None and rendering["n_frames"]:
            notes.append(f"LPIPS not computed: {rendering['lpips_weights']['unavailable']}")
    timing = run.read_timing()
    speed = None
    if timing is not None:
        speed = {"fps": timing.fps, "total_wall_s": timing.total_wall_s,
                 "frames": int(len(timing.per_frame_s)), "render_fps": timing.render_fps,
                 "compile_s": timing.compile_s, "init_s": timing.init_s,
                 "fps_after_init": timing.fps_after_init}
    metrics = {
        "schema_version": METRICS_SCHEMA_VERSION,
        "run": {"method": run.method, "sequence": run.sequence_name, "status": status.state},
        "protocol": proto.to_dict(),
        "tools": _tool_versions(),
        "ate": ate,
        "rpe": rpe,
        "rendering": rendering,
        "speed": speed,
        "coverage": coverage,
        "notes": notes,
    }
    metrics = _finite_or_none(metrics)
    if write:
        write_text_atomic(run.metrics_path, json.dumps(metrics, indent=1) + "\n")
    return metrics
