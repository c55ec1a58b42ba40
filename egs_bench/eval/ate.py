"""Absolute trajectory error (ATE) with evo: association, Umeyama alignment, translation APE.

The numbers equal ``evo_ape tum GT EST -a`` (SE(3)) and ``... -as`` (Sim(3)) for the same
association tolerance, because the same evo functions are called in the same order.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from egs_bench.errors import ConfigError, InputError
from egs_bench.geometry import Trajectory, read_tum

ALIGNMENTS = ("se3", "sim3", "none")
MIN_MATCHED_POSES = 3  # Umeyama needs >= 3 non-collinear points for a unique rotation
DEFAULT_MAX_DIFF_S = 0.01  # evo's default association tolerance (TUM's scripts use 0.02 s)


@dataclass(frozen=True)
class AteResult:
    """ATE of an estimate against ground truth (translation part, metres).

    Attributes:
        rmse, mean, median, std, min, max: statistics of the per-pose position error, metres.
        n_matched: number of associated pose pairs.
        alignment: ``"se3"``, ``"sim3"`` or ``"none"``.
        max_diff_s: association tolerance used, seconds.
        scale: Sim(3) scale applied to the estimate (1.0 for se3/none).
        rotation: alignment rotation applied to the estimate, [3, 3].
        translation: alignment translation applied to the estimate, [3] metres.
        timestamps: timestamps of the associated estimate poses, [M] seconds.
        errors: per-pose position error after alignment, [M] metres.
        est_positions: aligned estimate positions, [M, 3] metres.
        gt_positions: associated ground-truth positions, [M, 3] metres.
    """

    rmse: float
    mean: float
    median: float
    std: float
    min: float
    max: float
    n_matched: int
    alignment: str
    max_diff_s: float
    scale: float
    rotation: np.ndarray
    translation: np.ndarray
    timestamps: np.ndarray
    errors: np.ndarray
    est_positions: np.ndarray
    gt_positions: np.ndarray

    def summary(self) -> dict[str, Any]:
        """The scalar results as a plain dict (for ``metrics.json``)."""
        return {
            "rmse_m": self.rmse,
            "mean_m": self.mean,
            "median_m": self.median,
            "std_m": self.std,
            "min_m": self.min,
            "max_m": self.max,
            "n_matched": self.n_matched,
            "alignment": self.alignment,
            "max_diff_s": self.max_diff_s,
            "scale": self.scale,
        }


def _to_evo(traj: Trajectory):  # -> evo.core.trajectory.PoseTrajectory3D
    from evo.core.trajectory import PoseTrajectory3D

    return PoseTrajectory3D(poses_se3=list(traj.poses), timestamps=np.asarray(traj.timestamps))


def check_alignment(align: str) -> None:
    """Raise :class:`ConfigError` unless ``align`` is one of :data:`ALIGNMENTS`."""
    if align not in ALIGNMENTS:
        raise ConfigError(f"unknown alignment {align!r}; choose one of {', '.join(ALIGNMENTS)}")


def associate(est: Trajectory, gt: Trajectory, *, align: str = "se3",
              max_diff_s: float = DEFAULT_MAX_DIFF_S, est_name: str | Path = "estimate",
              gt_name: str | Path = "ground truth", what: str = "ATE"):
    """Validate two trajectories and associate them by nearest timestamp, as ``evo_ape`` and
    ``evo_rpe`` do (``evo.core.sync.associate_trajectories``).

    Returns:
        ``(ref, est)`` evo ``PoseTrajectory3D`` copies holding only the associated pose pairs.

    Raises:
        ConfigError: unknown ``align``.
        InputError: non-finite poses, fewer than 3 poses, no timestamp overlap or fewer than 3
            associated poses (``what`` names the metric in the message).
    """
    from evo.core import sync

    check_alignment(align)
    for traj, name in ((est, est_name), (gt, gt_name)):
        if not np.isfinite(traj.poses).all() or not np.isfinite(traj.timestamps).all():
            bad = int(np.argmax(~np.isfinite(traj.poses).reshape(len(traj), -1).all(axis=1)))
            raise InputError(name, f"NaN or infinite value in pose {bad}")
        if len(traj) < MIN_MATCHED_POSES:
            raise InputError(name, f"holds {len(traj)} poses, at least {MIN_MATCHED_POSES} needed "
                                   f"for {what}")
    ref_evo, est_evo = _to_evo(gt), _to_evo(est)
    try:
        ref_evo, est_evo = sync.associate_trajectories(ref_evo, est_evo, max_diff=max_diff_s)
    except sync.SyncException:
        raise InputError(
            est_name,
            f"no timestamp overlap with {gt_name} within {max_diff_s} s (estimate spans "
            f"{est.timestamps[0]:.3f}..{est.timestamps[-1]:.3f} s, ground truth "
            f"{gt.timestamps[0]:.3f}..{gt.timestamps[-1]:.3f} s)",
        ) from None
    if est_evo.num_poses < MIN_MATCHED_POSES:
        raise InputError(est_name, f"only {est_evo.num_poses} poses match {gt_name} within "
                                   f"{max_diff_s} s, at least {MIN_MATCHED_POSES} needed")
    return ref_evo, est_evo


def compute_ate(
    est: Trajectory,
    gt: Trajectory,
    *,
    align: str = "se3",
    max_diff_s: float = DEFAULT_MAX_DIFF_S,
    est_name: str | Path = "estimate",
    gt_name: str | Path = "ground truth",
) -> AteResult:
    """ATE of ``est`` against ``gt`` (evo: nearest-time association, Umeyama, APE translation).

    Args:
        est: estimated trajectory (poses ``T_wc``, timestamps in seconds).
        gt: ground-truth trajectory.
        align: ``"se3"`` (rigid Umeyama, RGB-D default), ``"sim3"`` (with scale, monocular)
            or ``"none"``.
        max_diff_s: maximum timestamp difference for associating two poses, seconds.
        est_name, gt_name: names (usually file paths) used in error messages.

    Raises:
        ConfigError: unknown ``align``.
        InputError: non-finite poses, no timestamp overlap, fewer than 3 associated poses or a
            degenerate (e.g. collinear) trajectory that cannot be aligned.
    """
    from evo.core import metrics
    from evo.core.geometry import GeometryException

    ref_evo, est_evo = associate(est, gt, align=align, max_diff_s=max_diff_s,
                                 est_name=est_name, gt_name=gt_name, what="ATE")
    rotation, translation, scale = np.eye(3), np.zeros(3), 1.0
    if align != "none":
        try:
            rotation, translation, scale = est_evo.align(ref_evo, correct_scale=align == "sim3")
        except GeometryException as exc:
            raise InputError(est_name, f"cannot align to {gt_name}: {exc}") from None
    ape = metrics.APE(metrics.PoseRelation.translation_part)
    ape.process_data((ref_evo, est_evo))
    stats = ape.get_all_statistics()
    return AteResult(
        rmse=float(stats["rmse"]),
        mean=float(stats["mean"]),
        median=float(stats["median"]),
        std=float(stats["std"]),
        min=float(stats["min"]),
        max=float(stats["max"]),
        n_matched=int(est_evo.num_poses),
        alignment=align,
        max_diff_s=float(max_diff_s),
        scale=float(scale),
        rotation=np.asarray(rotation, dtype=np.float64),
        translation=np.asarray(translation, dtype=np.float64),
        timestamps=np.asarray(est_evo.timestamps, dtype=np.float64),
        errors=np.asarray(ape.error, dtype=np.float64),
        est_positions=np.asarray(est_evo.positions_xyz, dtype=np.float64),
        gt_positions=np.asarray(ref_evo.positions_xyz, dtype=np.float64),
    )


def ate_from_files(
    est_path: str | Path,
    gt_path: str | Path,
    *,
    align: str = "se3",
    max_diff_s: float = DEFAULT_MAX_DIFF_S,
) -> AteResult:
    """ATE of two TUM files (see :func:`compute_ate`); bad files raise :class:`InputError`."""
    est = read_tum(est_path)
    gt = read_tum(gt_path)
    return compute_ate(est, gt, align=align, max_diff_s=max_diff_s, est_name=est_path,
                       gt_name=gt_path)


_GT_NAME = re.compile(r"ground[_\-]?truth|(^|[^a-z0-9])gt([^a-z0-9]|$)", re.IGNORECASE)
_EST_NAMES = ("cameratrajectory", "keyframetrajectory", "stamped_traj_estimate", "trj_final")


def file_role_hint(path: str | Path) -> str | None:
    """``"groundtruth"``, ``"estimate"`` or ``None``: what a trajectory file's name and place say
    it is.

    Ground truth: a name containing ``groundtruth`` / ``ground_truth`` or the token ``gt``
    (TUM's and egs-bench's ``groundtruth.txt``, RampVO's ``stamped_groundtruth.txt``). Estimate:
    a run folder's ``trajectory.txt``, a name containing ``estimate``, or the file names
    ORB-SLAM2/3, Photo-SLAM, RampVO and MonoGS write (``CameraTrajectory*``,
    ``KeyFrameTrajectory*``, ``stamped_traj_estimate``, ``trj_final``).
    """
    from egs_bench.runs.folder import TRAJECTORY_FILE, RunFolder

    path = Path(path)
    name = path.name.lower()
    is_gt = bool(_GT_NAME.search(path.stem))
    is_est = ("estimate" in name or any(name.startswith(n) for n in _EST_NAMES)
              or (path.name == TRAJECTORY_FILE and RunFolder.is_run_folder(path.parent)))
    if is_gt == is_est:
        return None
    return "groundtruth" if is_gt else "estimate"


def check_argument_order(gt_path: str | Path, est_path: str | Path, *, command: str,
                         swap_hint: str) -> None:
    """Refuse file arguments whose names say they are swapped (``GT`` named like an estimate or
    ``EST`` named like ground truth), so that the old ``EST GT`` order never gives different
    (Sim(3)) numbers silently.

    Raises:
        ConfigError: the names indicate swapped roles; the message says how to proceed.
    """
    gt_hint, est_hint = file_role_hint(gt_path), file_role_hint(est_path)
    if gt_hint == "estimate" or est_hint == "groundtruth":
        why = []
        if gt_hint == "estimate":
            why.append(f"the ground truth {gt_path} looks like an estimate")
        if est_hint == "groundtruth":
            why.append(f"the estimate {est_path} looks like ground truth")
        raise ConfigError(f"{command} takes GT EST (evo's order), but {' and '.join(why)}: "
                          f"swap them ({swap_hint})")
