"""Absolute trajectory error (ATE) with evo: association, Umeyama alignment, APE.

The numbers equal ``evo_ape tum GT EST -a`` (SE(3)) and ``... -as`` (Sim(3)) for the same
association tolerance and pose relation (``-r``), because the same evo functions are called in
the same order. :func:`trajectory_ate` is the Python API in that order (ground truth first);
:func:`compute_ate` and :func:`ate_from_files` take the estimate first (evaluation's order).

A time stamp that appears twice in one trajectory is never scored twice: the first pose of each
stamp is kept and the result's ``notes`` say what was dropped (evo would match one copy or
both, depending on which trajectory is the shorter).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, get_args

import numpy as np

from egs_bench.errors import ConfigError, InputError
from egs_bench.eval.protocols import Alignment
from egs_bench.geometry import Trajectory, read_tum

if TYPE_CHECKING:
    from evo.core.trajectory import PoseTrajectory3D

ALIGNMENTS: tuple[Alignment, ...] = get_args(Alignment)
MIN_MATCHED_POSES = 3  # Umeyama needs >= 3 non-collinear points for a unique rotation
DEFAULT_MAX_DIFF_S = 0.01  # evo's default association tolerance (TUM's scripts use 0.02 s)
#: Pose relations of the error (evo_ape's / evo_rpe's ``-r`` choices).
PoseRelation = Literal["trans_part", "angle_deg", "angle_rad", "rot_part", "full",
                       "point_distance"]
ErrorUnit = Literal["m", "deg", "rad", "none"]
DEFAULT_RELATION: PoseRelation = "trans_part"
RELATIONS: dict[PoseRelation, tuple[str, ErrorUnit]] = {
    # our name (= evo_ape's / evo_rpe's -r choice): (evo PoseRelation member, unit of the error)
    "trans_part": ("translation_part", "m"),
    "angle_deg": ("rotation_angle_deg", "deg"),
    "angle_rad": ("rotation_angle_rad", "rad"),
    "rot_part": ("rotation_part", "none"),
    "full": ("full_transformation", "none"),
    "point_distance": ("point_distance", "m"),
}


@dataclass(frozen=True)
class AteResult:
    """ATE of an estimate against ground truth (by default the translation part, metres).

    Attributes:
        rmse, mean, median, std, min, max: statistics of the per-pose error, in ``unit``
            (metres for the default ``trans_part``).
        n_matched: number of associated pose pairs.
        alignment: ``"se3"``, ``"sim3"`` or ``"none"``.
        max_diff_s: association tolerance used, seconds.
        scale: Sim(3) scale applied to the estimate (1.0 for se3/none).
        rotation: alignment rotation applied to the estimate, [3, 3].
        translation: alignment translation applied to the estimate, [3] metres.
        timestamps: timestamps of the associated estimate poses, [M] seconds.
        errors: per-pose error after alignment, [M] in ``unit``.
        est_positions: aligned estimate positions, [M, 3] metres.
        gt_positions: associated ground-truth positions, [M, 3] metres.
        relation: pose relation (a key of :data:`RELATIONS`, evo's ``-r``).
        unit: unit of the errors (``"m"``, ``"deg"``, ``"rad"`` or ``"none"``).
        notes: what was done to the input on the way (merged duplicate time stamps).
    """

    rmse: float
    mean: float
    median: float
    std: float
    min: float
    max: float
    n_matched: int
    alignment: Alignment
    max_diff_s: float
    scale: float
    rotation: np.ndarray
    translation: np.ndarray
    timestamps: np.ndarray
    errors: np.ndarray
    est_positions: np.ndarray
    gt_positions: np.ndarray
    relation: PoseRelation = DEFAULT_RELATION
    unit: ErrorUnit = "m"
    notes: tuple[str, ...] = field(default=())

    def summary(self) -> dict[str, Any]:
        """The scalar results as a plain dict (for ``metrics.json``); keys end in ``_m`` for
        the translation relation, otherwise ``relation`` and ``unit`` say what they hold."""
        if self.relation != DEFAULT_RELATION:
            return {"relation": self.relation, "unit": self.unit, "rmse": self.rmse,
                    "mean": self.mean, "median": self.median, "std": self.std, "min": self.min,
                    "max": self.max, "n_matched": self.n_matched, "alignment": self.alignment,
                    "max_diff_s": self.max_diff_s, "scale": self.scale}
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


def _to_evo(traj: Trajectory) -> PoseTrajectory3D:
    from evo.core.trajectory import PoseTrajectory3D

    return PoseTrajectory3D(poses_se3=list(traj.poses), timestamps=np.asarray(traj.timestamps))


def check_alignment(align: str) -> None:
    """Raise :class:`ConfigError` unless ``align`` is one of :data:`ALIGNMENTS`."""
    if align not in ALIGNMENTS:
        raise ConfigError(f"unknown alignment {align!r}; choose one of {', '.join(ALIGNMENTS)}")


def check_relation(relation: str, what: str = "ATE") -> None:
    """Raise :class:`ConfigError` unless ``relation`` is one of :data:`RELATIONS` (``what``
    names the metric in the message)."""
    if relation not in RELATIONS:
        raise ConfigError(f"unknown {what} relation {relation!r}; choose one of "
                          f"{', '.join(RELATIONS)}")


def merge_duplicate_stamps(traj: Trajectory, name: str | Path) -> tuple[Trajectory, str | None]:
    """``traj`` with each repeated time stamp kept once (its first pose), and a note naming the
    file (its name only: ``metrics.json`` holds no paths), how many poses were dropped and how
    far they lay from the kept ones; the note is ``None`` when no stamp repeats.

    Copies are found after a stable sort by time. They are dropped rather than refused because
    real ground truth has them (TUM's fr2/desk repeats a stamp with poses 1 mm apart), and
    scoring both would count one time twice.
    """
    stamps = np.asarray(traj.timestamps, dtype=np.float64)
    order = np.argsort(stamps, kind="stable")
    stamps, poses = stamps[order], np.asarray(traj.poses)[order]
    starts = np.r_[True, np.diff(stamps) != 0]  # the first pose of each distinct stamp
    if starts.all():
        return traj, None
    first = np.flatnonzero(starts)[np.cumsum(starts) - 1]  # [N] index of each stamp's first pose
    gap = float(np.linalg.norm(poses[:, :3, 3] - poses[first, :3, 3], axis=1).max())
    n_stamps = int(len(np.unique(stamps[~starts])))
    note = (f"{Path(name).name}: {n_stamps} time stamp(s) repeated; kept the first pose of "
            f"each, dropped {int((~starts).sum())} of {len(stamps)} poses (up to {gap:.3f} m "
            "from the kept ones)")
    return Trajectory(stamps[starts].copy(), poses[starts].copy()), note


def associate(est: Trajectory, gt: Trajectory, *, align: Alignment = "se3",
              max_diff_s: float = DEFAULT_MAX_DIFF_S, est_name: str | Path = "estimate",
              gt_name: str | Path = "ground truth", what: str = "ATE"
              ) -> tuple[PoseTrajectory3D, PoseTrajectory3D, tuple[str, ...]]:
    """Validate two trajectories and associate them by nearest timestamp, as ``evo_ape`` and
    ``evo_rpe`` do (``evo.core.sync.associate_trajectories``), after merging repeated time
    stamps (:func:`merge_duplicate_stamps`).

    Returns:
        ``(ref, est, notes)``: evo ``PoseTrajectory3D`` copies holding only the associated pose
        pairs, and notes on merged duplicates (a tuple of strings, empty when none).

    Raises:
        ConfigError: unknown ``align``.
        InputError: non-finite poses, fewer than 3 poses, no timestamp overlap or fewer than 3
            associated poses (``what`` names the metric in the message).
    """
    from evo.core import sync

    check_alignment(align)
    notes: list[str] = []
    checked = []
    for traj, name in ((est, est_name), (gt, gt_name)):
        if not np.isfinite(traj.poses).all() or not np.isfinite(traj.timestamps).all():
            bad = int(np.argmax(~np.isfinite(traj.poses).reshape(len(traj), -1).all(axis=1)))
            raise InputError(name, f"NaN or infinite value in pose {bad}")
        traj, note = merge_duplicate_stamps(traj, name)
        if note is not None:
            notes.append(note)
        checked.append(traj)
        if len(traj) < MIN_MATCHED_POSES:
            raise InputError(name, f"holds {len(traj)} poses, at least {MIN_MATCHED_POSES} needed "
                                   f"for {what}")
    est, gt = checked
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
    return ref_evo, est_evo, tuple(notes)


def compute_ate(
    est: Trajectory,
    gt: Trajectory,
    *,
    align: Alignment = "se3",
    max_diff_s: float = DEFAULT_MAX_DIFF_S,
    est_name: str | Path = "estimate",
    gt_name: str | Path = "ground truth",
    relation: PoseRelation = DEFAULT_RELATION,
) -> AteResult:
    """ATE of ``est`` against ``gt`` (evo: nearest-time association, Umeyama, APE); the
    estimate comes first here, :func:`trajectory_ate` takes evo's GT EST order.

    Args:
        est: estimated trajectory (poses ``T_wc``, timestamps in seconds).
        gt: ground-truth trajectory.
        align: ``"se3"`` (rigid Umeyama, RGB-D default), ``"sim3"`` (with scale, monocular)
            or ``"none"``.
        max_diff_s: maximum timestamp difference for associating two poses, seconds.
        est_name, gt_name: names (usually file paths) used in error messages.
        relation: pose relation of the error (evo_ape's ``-r``, a key of :data:`RELATIONS`):
            ``trans_part`` (metres, the ATE), ``angle_deg`` (rotation ATE, degrees), ...

    Raises:
        ConfigError: unknown ``align`` or ``relation``.
        InputError: non-finite poses, no timestamp overlap, fewer than 3 associated poses or
            a degenerate (e.g. collinear) trajectory that cannot be aligned.
    """
    from evo.core import metrics
    from evo.core.geometry import GeometryException

    check_relation(relation)
    ref_evo, est_evo, notes = associate(est, gt, align=align, max_diff_s=max_diff_s,
                                        est_name=est_name, gt_name=gt_name, what="ATE")
    rotation, translation, scale = np.eye(3), np.zeros(3), 1.0
    if align != "none":
        try:
            rotation, translation, scale = est_evo.align(ref_evo, correct_scale=align == "sim3")
        except GeometryException as exc:
            raise InputError(est_name, f"cannot align to {gt_name}: {exc}") from None
    ape = metrics.APE(getattr(metrics.PoseRelation, RELATIONS[relation][0]))
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
        relation=relation,
        unit=RELATIONS[relation][1],
        notes=notes,
    )


def ate_from_files(
    est_path: str | Path,
    gt_path: str | Path,
    *,
    align: Alignment = "se3",
    max_diff_s: float = DEFAULT_MAX_DIFF_S,
    relation: PoseRelation = DEFAULT_RELATION,
) -> AteResult:
    """ATE of two TUM files, estimate first (see :func:`compute_ate`; :func:`trajectory_ate`
    takes GT EST); bad files raise :class:`InputError`."""
    est = read_tum(est_path)
    gt = read_tum(gt_path)
    return compute_ate(est, gt, align=align, max_diff_s=max_diff_s, est_name=est_path,
                       gt_name=gt_path, relation=relation)


def load_trajectory(traj: Trajectory | str | Path, default_name: str) -> tuple[Trajectory,
                                                                            str | Path]:
    """A trajectory and the name its messages use: a :class:`Trajectory` as it is, a path read
    as a TUM file (:func:`~egs_bench.geometry.read_tum`)."""
    if isinstance(traj, Trajectory):
        return traj, default_name
    return read_tum(traj), traj


def trajectory_ate(
    gt: Trajectory | str | Path,
    est: Trajectory | str | Path,
    *,
    align: Alignment = "se3",
    relation: PoseRelation = DEFAULT_RELATION,
    max_diff_s: float = DEFAULT_MAX_DIFF_S,
) -> AteResult:
    """ATE of ``est`` against ``gt`` in evo's and the CLI's order, ground truth first:
    ``trajectory_ate(GT, EST, align="se3")`` = ``egs-bench ate GT EST`` = ``evo_ape tum GT EST
    -a`` (``align="sim3"``: ``-as``; ``relation="angle_deg"``: ``-r angle_deg``).

    Args:
        gt, est: trajectories (poses ``T_wc``, seconds) or paths of TUM files.
        align, relation, max_diff_s: as for :func:`compute_ate`.

    Raises:
        ConfigError, InputError: as for :func:`compute_ate` (bad files name the file).
    """
    gt_traj, gt_name = load_trajectory(gt, "ground truth")
    est_traj, est_name = load_trajectory(est, "estimate")
    return compute_ate(est_traj, gt_traj, align=align, max_diff_s=max_diff_s,
                       est_name=est_name, gt_name=gt_name, relation=relation)


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


def check_results_path(path: str | Path, *, overwrite: bool, inputs: list[str | Path],
                       option: str = "--save_results") -> Path:
    """Check, before anything is computed, that a results file may be written at ``path``:
    a ``.json`` name (evo's ``.zip`` archives are not written) and the ``--overwrite`` rules of
    :func:`egs_bench.outputs.prepare_output`.

    Raises:
        ConfigError: not a ``.json`` name.
        OutputError, UnwritableOutputError: see :func:`~egs_bench.outputs.prepare_output`.
    """
    from egs_bench.outputs import prepare_output

    path = Path(path)
    if path.suffix.lower() != ".json":
        raise ConfigError(f"{option} {path}: egs-bench writes the results as JSON; name a .json "
                          "file (evo's .zip result archives are not written)")
    return prepare_output(path, "results", overwrite=overwrite, inputs=inputs, option=option)


def results_json(result: Any, *, metric: str, reference: str | Path,
                 estimate: str | Path) -> str:
    """An :class:`AteResult` or :class:`~egs_bench.eval.rpe.RpeResult` as JSON text: the
    files, the settings, evo's six statistics (``stats``, the keys of evo's ``stats.json``),
    the notes, the tool versions, and per pose (ATE) or pair (RPE) the time stamp (seconds) and
    the error (in ``unit``).

    Args:
        metric: ``"ATE"`` or ``"RPE"``.
        reference, estimate: the ground-truth and estimate files as the user named them.
    """
    import importlib.metadata
    import json

    from egs_bench import __version__

    stat_keys = ("rmse", "mean", "median", "std", "min", "max")
    settings = {k: v for k, v in result.summary().items()
                if k.removesuffix("_m") not in stat_keys}
    settings.setdefault("relation", result.relation)
    settings.setdefault("unit", result.unit)
    data = {
        "metric": metric,
        "reference": str(reference),
        "estimate": str(estimate),
        "settings": settings,
        "stats": {k: float(getattr(result, k)) for k in stat_keys},
        "notes": list(result.notes),
        "tools": {"egs_bench": __version__, "evo": importlib.metadata.version("evo")},
        "timestamps_s": np.asarray(result.timestamps).tolist(),
        "errors": np.asarray(result.errors).tolist(),
    }
    return json.dumps(data, indent=1) + "\n"
