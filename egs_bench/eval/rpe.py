"""Relative pose error (RPE) with evo: association, optional alignment, ``evo.core.metrics.RPE``.

The numbers equal ``evo_rpe tum GT EST -r RELATION -d DELTA -u UNIT [--all_pairs] [-a|-as]``
for the same association tolerance (``--t_max_diff``), because the same evo calls run in the
same order as in ``evo.main_rpe.rpe``: nearest-time association, Umeyama alignment if asked,
then the metric. The two measures the benchmark reports:

* **per frame**: ``delta = 1`` frame, consecutive pairs (drift between neighbouring poses);
* **per metre**: ``delta = 1`` m of travelled path, consecutive pairs (drift over one metre).

Each comes as translation (``trans_part``, metres) and rotation (``angle_deg``, degrees).
Pairs are taken on the estimate's poses (evo's default; ``--pairs_from_reference`` is not
offered). SE(3) alignment does not change RPE (relative poses are invariant to a rigid motion
of the whole trajectory); Sim(3) alignment does, through its scale.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from egs_bench.errors import ConfigError, InputError
from egs_bench.eval.ate import (
    DEFAULT_MAX_DIFF_S,
    RELATIONS,
    ErrorUnit,
    PoseRelation,
    associate,
    check_relation,
    load_trajectory,
)
from egs_bench.eval.protocols import Alignment
from egs_bench.geometry import Trajectory, read_tum

__all__ = ["DELTA_UNITS", "RELATIONS", "RpeResult", "compute_rpe", "rpe_from_files",
           "standard_rpe", "trajectory_rpe"]

#: evo_rpe's ``-u`` letters and their long names.
DeltaUnit = Literal["f", "frames", "m", "meters", "d", "deg", "degrees", "r", "rad", "radians"]
EvoUnit = Literal["frames", "meters", "degrees", "radians"]
DELTA_UNITS: dict[DeltaUnit, EvoUnit] = {
    # evo_rpe's -u letters and their long names: evo Unit member
    "f": "frames", "frames": "frames",
    "m": "meters", "meters": "meters",
    "d": "degrees", "deg": "degrees", "degrees": "degrees",
    "r": "radians", "rad": "radians", "radians": "radians",
}
DEFAULT_REL_DELTA_TOL = 0.1  # evo_rpe's --delta_tol (used with --all_pairs only)


@dataclass(frozen=True)
class RpeResult:
    """RPE of an estimate against ground truth.

    Attributes:
        relation: pose relation (a key of :data:`RELATIONS`).
        unit: unit of the errors (``"m"``, ``"deg"``, ``"rad"`` or ``"none"``).
        delta, delta_unit: the pair spacing (``delta_unit`` is evo's: frames, meters, degrees,
            radians).
        all_pairs: every pair ``delta`` apart (within the tolerance) instead of consecutive ones.
        alignment: ``"se3"``, ``"sim3"`` or ``"none"``; scale: the Sim(3) scale (1 otherwise).
        n_matched: associated pose pairs; n_pairs: relative-pose pairs scored.
        rmse, mean, median, std, min, max: statistics of the per-pair error, in ``unit``.
        timestamps: time of the second pose of each pair, [P] seconds.
        errors: per-pair error, [P] in ``unit``.
        notes: what was done to the input on the way (merged duplicate time stamps).
    """

    relation: PoseRelation
    unit: ErrorUnit
    delta: float
    delta_unit: EvoUnit
    all_pairs: bool
    alignment: Alignment
    scale: float
    n_matched: int
    n_pairs: int
    rmse: float
    mean: float
    median: float
    std: float
    min: float
    max: float
    timestamps: np.ndarray
    errors: np.ndarray
    notes: tuple[str, ...] = field(default=())

    def summary(self) -> dict[str, Any]:
        """The scalar results as a plain dict (for ``metrics.json``)."""
        return {
            "relation": self.relation, "unit": self.unit, "delta": self.delta,
            "delta_unit": self.delta_unit, "all_pairs": self.all_pairs,
            "alignment": self.alignment, "scale": self.scale, "n_matched": self.n_matched,
            "n_pairs": self.n_pairs, "rmse": self.rmse, "mean": self.mean,
            "median": self.median, "std": self.std, "min": self.min, "max": self.max,
        }


def compute_rpe(
    est: Trajectory,
    gt: Trajectory,
    *,
    relation: PoseRelation = "trans_part",
    delta: float = 1.0,
    delta_unit: DeltaUnit = "f",
    all_pairs: bool = False,
    align: Alignment = "none",
    max_diff_s: float = DEFAULT_MAX_DIFF_S,
    rel_delta_tol: float = DEFAULT_REL_DELTA_TOL,
    est_name: str | Path = "estimate",
    gt_name: str | Path = "ground truth",
) -> RpeResult:
    """RPE of ``est`` against ``gt`` (evo: association, alignment, ``metrics.RPE``); the
    estimate comes first here, :func:`trajectory_rpe` takes evo's GT EST order.

    Args:
        est: estimated trajectory (poses ``T_wc``, timestamps in seconds).
        gt: ground-truth trajectory.
        relation: a key of :data:`RELATIONS` (evo_rpe's ``-r``): ``trans_part`` (metres),
            ``angle_deg`` (degrees), ...
        delta: pair spacing, in ``delta_unit`` (an integer for frames).
        delta_unit: ``f`` frames, ``m`` metres of path, ``d`` / ``r`` degrees / radians of
            rotation (evo_rpe's ``-u``; long names accepted).
        all_pairs: all pairs ``delta`` apart instead of consecutive pairs (``--all_pairs``).
        align: ``"none"`` (evo_rpe's default), ``"se3"`` (``-a``) or ``"sim3"`` (``-as``).
        max_diff_s: association tolerance, seconds (``--t_max_diff``).
        rel_delta_tol: relative tolerance of ``delta`` with ``all_pairs`` (``--delta_tol``).
        est_name, gt_name: names (usually file paths) used in error messages.

    Raises:
        ConfigError: unknown relation, delta unit or alignment, or a non-positive delta.
        InputError: bad trajectories (see :func:`~egs_bench.eval.ate.associate`), no pose pair
            ``delta`` apart, or a degenerate trajectory that cannot be aligned.
    """
    from evo.core import metrics
    from evo.core.filters import FilterException
    from evo.core.geometry import GeometryException

    check_relation(relation, "RPE")
    if delta_unit not in DELTA_UNITS:
        raise ConfigError(f"unknown delta unit {delta_unit!r}; choose one of f, m, d, r")
    unit = DELTA_UNITS[delta_unit]
    if not delta > 0:
        raise ConfigError(f"RPE delta must be > 0, got {delta}")
    if unit == "frames" and float(delta) != int(delta):
        raise ConfigError(f"RPE delta in frames must be an integer, got {delta}")
    ref_evo, est_evo, notes = associate(est, gt, align=align, max_diff_s=max_diff_s,
                                        est_name=est_name, gt_name=gt_name, what="RPE")
    n_matched = int(est_evo.num_poses)
    scale = 1.0
    if align != "none":
        try:
            scale = float(est_evo.align(ref_evo, correct_scale=align == "sim3")[2])
        except GeometryException as exc:
            raise InputError(est_name, f"cannot align to {gt_name}: {exc}") from None
    metric = metrics.RPE(getattr(metrics.PoseRelation, RELATIONS[relation][0]),
                         delta=int(delta) if unit == "frames" else float(delta),
                         delta_unit=getattr(metrics.Unit, unit), rel_delta_tol=rel_delta_tol,
                         all_pairs=all_pairs)
    no_pairs = InputError(est_name, f"no pose pair {delta:g} {unit} apart among the "
                                    f"{n_matched} poses matched with {gt_name}")
    try:
        metric.process_data((ref_evo, est_evo))
    except FilterException:
        raise no_pairs from None
    if len(metric.error) == 0:
        raise no_pairs
    stats = metric.get_all_statistics()
    stamps = np.asarray(est_evo.timestamps, dtype=np.float64)[np.asarray(metric.delta_ids,
                                                                         dtype=np.int64)]
    return RpeResult(
        relation=relation, unit=RELATIONS[relation][1], delta=float(delta), delta_unit=unit,
        all_pairs=bool(all_pairs), alignment=align, scale=scale, n_matched=n_matched,
        n_pairs=int(len(metric.error)), rmse=float(stats["rmse"]), mean=float(stats["mean"]),
        median=float(stats["median"]), std=float(stats["std"]), min=float(stats["min"]),
        max=float(stats["max"]), timestamps=stamps,
        errors=np.asarray(metric.error, dtype=np.float64), notes=notes,
    )


def rpe_from_files(est_path: str | Path, gt_path: str | Path, **options: Any) -> RpeResult:
    """RPE of two TUM files, estimate first (``options`` as for :func:`compute_rpe`;
    :func:`trajectory_rpe` takes GT EST); bad files raise :class:`InputError` naming the file."""
    return compute_rpe(read_tum(est_path), read_tum(gt_path), est_name=est_path,
                       gt_name=gt_path, **options)


def trajectory_rpe(gt: Trajectory | str | Path, est: Trajectory | str | Path, *,
                   relation: PoseRelation = "trans_part", delta: float = 1.0,
                   delta_unit: DeltaUnit = "f",
                   all_pairs: bool = False, align: Alignment = "none",
                   max_diff_s: float = DEFAULT_MAX_DIFF_S,
                   rel_delta_tol: float = DEFAULT_REL_DELTA_TOL) -> RpeResult:
    """RPE of ``est`` against ``gt`` in evo's and the CLI's order, ground truth first:
    ``trajectory_rpe(GT, EST, relation="angle_deg", delta=1, delta_unit="m")`` =
    ``egs-bench rpe GT EST -r angle_deg -d 1 -u m`` = ``evo_rpe tum GT EST -r angle_deg -d 1 -u
    m``.

    Args:
        gt, est: trajectories (poses ``T_wc``, seconds) or paths of TUM files.
        relation, delta, delta_unit, all_pairs, align, max_diff_s, rel_delta_tol: as for
            :func:`compute_rpe`.

    Raises:
        ConfigError, InputError: as for :func:`compute_rpe` (bad files name the file).
    """
    gt_traj, gt_name = load_trajectory(gt, "ground truth")
    est_traj, est_name = load_trajectory(est, "estimate")
    return compute_rpe(est_traj, gt_traj, relation=relation, delta=delta, delta_unit=delta_unit,
                       all_pairs=all_pairs, align=align, max_diff_s=max_diff_s,
                       rel_delta_tol=rel_delta_tol, est_name=est_name, gt_name=gt_name)


def standard_rpe(est: Trajectory, gt: Trajectory, *, max_diff_s: float = DEFAULT_MAX_DIFF_S,
                 est_name: str | Path = "estimate", gt_name: str | Path = "ground truth"
                 ) -> dict[str, Any]:
    """The benchmark's RPE summary: translation (m) and rotation (deg) per frame and per metre.

    A trajectory shorter than 1 m of path has no per-metre pair; that entry is ``None`` with
    the reason in ``"note"``. Errors other than that one propagate.
    """
    out: dict[str, Any] = {}
    spacings: tuple[tuple[str, DeltaUnit], ...] = (("per_frame", "f"), ("per_metre", "m"))
    parts: tuple[tuple[str, PoseRelation], ...] = (("translation", "trans_part"),
                                                  ("rotation", "angle_deg"))
    for key, delta_unit in spacings:
        entry: dict[str, Any] = {}
        try:
            for name, relation in parts:
                res = compute_rpe(est, gt, relation=relation, delta=1, delta_unit=delta_unit,
                                  max_diff_s=max_diff_s, est_name=est_name, gt_name=gt_name)
                entry[name] = res.summary()
        except InputError as exc:
            if "no pose pair" not in str(exc):
                raise
            entry = {"translation": None, "rotation": None, "note": str(exc)}
        out[key] = entry
    return out
