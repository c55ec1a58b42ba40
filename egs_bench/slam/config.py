"""Configuration of the SLAM system: typed groups, one algorithm, two compute budgets.

A :class:`SlamConfig` is a set of groups. Everything that defines *the method* (which losses,
which response, how poses are predicted and refined) lives in ``method``, ``loss``,
``tracking``, ``keyframes`` and ``mapping`` and has one value for every preset; the presets
(``paper``, ``cpu``) differ only in the :class:`BudgetConfig` group (resolution, iteration
counts, K, insertion density, window sizes and the step sizes tied to the iteration counts).
Methods (``egs``, ablations, ``monogs``) are overrides of method-defining fields
(:mod:`egs_bench.slam.methods`), not code forks.

Every field is typed (``Literal`` choices, ``int``/``float``/``bool``, optional values) and
checked by :meth:`SlamConfig.validate`; the resolved configuration is stored, nested by group,
in the run folder's ``config.yaml``. Overrides (``--set``, ``replace``) name a field by its
path (``loss.lambda_d``) or by its unique field name (``lambda_d``).

A component with settings of its own (``egs_bench.slam.components``) declares a subclass of
the group it reads, with ``RANGES`` for its fields; :meth:`SlamConfig.with_groups` puts that
class in the group, and the same overrides, checks and reference page then cover its fields.
"""

from __future__ import annotations

import dataclasses
import math
import re
import typing
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

from egs_bench.errors import ConfigError

CrfKind = Literal["learnable", "srgb", "identity"]
CrfInit = Literal["linear", "srgb"]
MotionModel = Literal["constant-position", "constant-velocity"]
Backend = Literal["auto", "numba", "reference", "gsplat"]
MappingMode = Literal["sequential", "concurrent"]
#: when tracking may stop before its iteration budget (:mod:`egs_bench.slam.convergence`)
ConvergenceRule = Literal["fixed", "relative-step", "plateau", "net-motion"]
InsertionRule = Literal["all", "uncovered"]


@dataclass(frozen=True)
class MethodConfig:
    """What defines a method (EGS-SLAM, its ablations, the MonoGS-style baseline)."""

    blur_model: bool = True             # K+1 sub-poses over the exposure (False: one pose)
    event_tracking: bool = True         # event loss in tracking
    event_mapping: bool = True          # event loss in mapping
    no_event_loss: bool = True          # L_NE on silent pixels
    crf: CrfKind = "learnable"         # camera response: learned curve, fixed sRGB or none
    crf_nodes: int = 16                 # nodes of the learnable response curve
    crf_alpha: float = 0.01             # (paper)
    # Initial curve of the learnable CRF: "linear" (evenly spaced nodes, the identity; the paper
    # does not say) or "srgb". "linear" because the sRGB start tracked worse
    # (docs/notes/slam_config_measurements_2026-12-04.md).
    crf_init: CrfInit = "linear"
    exposure_compensation: bool = True  # per-frame exp(a) I + b (MonoGS)
    theta: float | None = None          # event threshold; None = the sequence's pos/neg values


@dataclass(frozen=True)
class LossConfig:
    """Loss weights and masks (paper §V.B; MonoGS)."""

    lambda_ne: float = 0.4              # (paper)
    lambda_e: float = 0.05              # (paper, synthetic; real data 0.15)
    lambda_id: float = 0.95             # (paper, synthetic; real data 0.85)
    lambda_i: float = 0.9               # (paper)
    lambda_d: float = 0.1               # (paper)
    lambda_iso: float = 10.0            # (paper, MonoGS)
    # Depth term on the alpha-normalised depth sum(w z) / sum(w) instead of MonoGS's sum(w z):
    # the latter is biased short wherever the map does not yet reach alpha = 1, which on a
    # sparse, briefly optimised map pulls the tracked pose forward. The division keeps alpha
    # in the graph: with alpha detached the term lowered every opacity where the depth was
    # too long and eroded the map into holes (docs/notes/slam.md).
    expected_depth: bool = True
    use_edge_mask: bool = True          # (MonoGS) tracking photometric term on edges only
    edge_threshold: float = 4.0         # (MonoGS, Replica)
    rgb_boundary_threshold: float = 0.01  # (MonoGS)


@dataclass(frozen=True)
class ConvergenceConfig:
    """What the convergence rule (:class:`~egs_bench.slam.convergence.ConvergenceTest`) reads:
    when a frame may stop before its iteration budget. Part of the ``tracking`` group (its
    fields are ``tracking.convergence*``), which the tracker that runs the rule reads."""

    # "fixed" runs the budget (MonoGS's absolute step threshold aside), "relative-step" /
    # "plateau" / "net-motion" stop once the step / the loss's improvement / the net motion
    # has fallen below convergence_tolerance (relative) for convergence_patience iterations.
    convergence: ConvergenceRule = "fixed"
    convergence_tolerance: float = 0.1  # relative tolerance of the convergence rule
    convergence_patience: int = 3       # iterations the rule must hold before a frame stops


@dataclass(frozen=True)
class TrackingConfig(ConvergenceConfig):
    """How a frame's exposure trajectory is predicted and estimated (and, from
    :class:`ConvergenceConfig`, when its estimation may stop)."""

    motion_model: MotionModel = "constant-velocity"  # how a frame's start pose is predicted
    # Tracking estimates T_tau only and places T_0 on the path from the previous frame's T_tau
    # (constant velocity over the frame interval) instead of estimating both freely (paper).
    continuous_exposure: bool = False
    # ... and the same for a frame whose exposure lasts less than this fraction of the time
    # since the previous exposure ended (0 = never). Its blur then spans a small fraction of
    # the inter-frame motion, below what the image resolves, so a free T_0 is barely
    # constrained and drifts from T_tau on unblurred frames
    # (docs/notes/slam_config_measurements_2026-12-04.md). Blurred sequences (25 of 33 ms,
    # ratio 0.75) keep both poses free, as in the paper, whose data are all blurred.
    short_exposure_ratio: float = 0.5
    lr_exposure: float = 0.01           # (MonoGS)
    max_translation_jump: float = 0.5   # m between consecutive frames, else divergence
    max_rotation_jump: float = 0.6      # rad between consecutive frames, else divergence
    divergence_loss_factor: float = 20.0  # final loss > factor x running median -> divergence


@dataclass(frozen=True)
class KeyframeConfig:
    """MonoGS keyframe selection and window maintenance (Replica values; research note §1.4)."""

    interval: int = 4                   # minimum frames since the last keyframe
    overlap: float = 0.95               # IoU of visible Gaussians below which a new KF is wanted
    min_translation: float = 0.02       # x median depth, together with low overlap
    translation: float = 0.04           # x median depth, alone
    cutoff: float = 0.4                 # Szymkiewicz-Simpson overlap at which a KF may go
    protected: int = 2                  # newest window entries never removed


@dataclass(frozen=True)
class ScheduleConfig:
    """What the mapping schedule (:mod:`egs_bench.slam.scheduling`) reads: when a keyframe's
    mapping round runs. Part of the ``mapping`` group (``mapping.mapping_mode``); the size of
    a concurrent slice is a compute budget (``budget.mapping_iters_per_frame``)."""

    # "sequential": a keyframe's mapping round runs before the next frame is tracked;
    # "concurrent": beside the next frames' tracking.
    mapping_mode: MappingMode = "sequential"


@dataclass(frozen=True)
class MappingConfig(ScheduleConfig):
    """How the map (and keyframe poses, exposures, the CRF) are optimised (and, from
    :class:`ScheduleConfig`, when)."""

    refine_poses: bool = False          # refine the newest keyframes' trajectories in mapping
    n_random_kfs: int = 2               # (paper, MonoGS) older keyframes added per iteration
    kf_pose_lr_scale: float = 0.5       # (MonoGS) keyframe pose lr = 0.5 x tracking lr
    prune_opacity: float = 0.1          # periodic pruning below this opacity
    init_prune_opacity: float = 0.005   # (MonoGS init_gaussian_th)
    lr_quats: float = 0.001             # Gaussian rotations' learning rate
    lr_crf: float = 0.005               # the learnable response curve's learning rate
    point_size: float = 0.5             # new Gaussians: scale^2 = point_size x mean sq. 3-NN
    near_plane: float = 0.2             # (MonoGS)
    # Final map refinement after the last frame, one random keyframe per iteration (0 = none).
    # MonoGS runs 26000 for its "after_opt" numbers only; the paper does not say whether
    # EGS-SLAM refines.
    refine_iters: int = 0


@dataclass(frozen=True)
class BudgetConfig:
    """Compute budget: what the ``paper`` and ``cpu`` presets choose differently.

    Defaults are the paper / MonoGS values (GPU-sized work at the sequence's resolution)."""

    resolution_scale: float = 1.0       # internal processing resolution factor
    segments: int = 4                   # K exposure segments of the blur model (paper)
    tracking_iters: int = 100           # (MonoGS)
    # Iterations for a frame whose prediction has no velocity yet (frame 1 under the
    # constant-velocity model): its start is off by the whole inter-frame motion, not by the
    # error of a prediction. None = tracking_iters (the paper's 100 already catch it); the cpu
    # preset's 30 do not (docs/notes/engine_cost_2026-12-06.md §8).
    tracking_iters_no_prior: int | None = None
    lr_rot: float = 0.003               # (MonoGS)
    lr_trans: float = 0.001             # (MonoGS)
    tracking_lr_final: float = 1.0      # pose lr decays exponentially to this factor
    converged_threshold: float = 1e-4   # (MonoGS) |twist| after a step
    init_iters: int = 1050              # (MonoGS) mapping iterations on frame 0
    mapping_iters: int = 150            # (MonoGS single process) per new keyframe
    # Concurrent mapping: iterations run beside each frame (None: mapping_iters spread over
    # keyframes.interval frames, so a round ends before the next keyframe can arrive).
    mapping_iters_per_frame: int | None = None
    views_per_iter: int | None = None   # None = whole mapping set every iteration (MonoGS)
    window_size: int = 10               # (paper)
    pose_window: int = 5                # (paper) newest keyframes refined when refine_poses
    prune_every: int = 150              # (MonoGS) pruning period (mapping iterations)
    prune_offset: int = 50              # pruning runs at iterations = offset mod prune_every
    # Pruning also removes the Gaussians in view of the window's keyframes that blend less than
    # this many pixels summed over them (at mapping's coarse level; 0 = off):
    # egs_bench/slam/contribution.py.
    prune_contribution: float = 0.0
    pcd_downsample_init: int = 8        # keep 1 of this many valid pixels at frame 0
    pcd_downsample: int = 16            # ... at later keyframes
    edge_blocks: int | None = 32        # (MonoGS, Replica) edge-mask grid; None = global
    lr_means: float = 0.00016 * 6       # (MonoGS, times its spatial_lr_scale 6)
    lr_colors: float = 0.0025 * 0.28209479  # (MonoGS f_dc lr expressed on colours)
    lr_opacity: float = 0.05            # (MonoGS)
    lr_scales: float = 0.001 * 6        # (MonoGS, times its spatial_lr_scale 6)
    # Weight of a prior lambda (a^2 + b^2) on each frame's exposure compensation exp(a) I + b,
    # added wherever a and b are optimised (DSO's affine brightness prior). The map's radiance
    # and the window's exposures trade against each other; frame 0 (a = b = 0) anchors that
    # gauge only when a mapping iteration draws it, so the fewer mapping iterations per
    # keyframe, the further the exposures drift, even on sequences of constant exposure
    # (docs/notes/engine_cost_2026-12-06.md §8.2, §9). 0 = off (paper, MonoGS).
    lambda_exposure_prior: float = 0.0
    # Coarse-to-fine (egs_bench/slam/levels.py): the first fraction of each tracking call's and
    # mapping round's iterations render at coarse_scale x the internal resolution, about
    # scale^2 of a fine iteration's blends; the last iteration is always fine.
    tracking_coarse_scale: float = 1.0     # coarse level of tracking (1.0 = off)
    tracking_coarse_fraction: float = 0.0  # share of tracking iterations at that level
    mapping_coarse_scale: float = 1.0      # coarse level of mapping rounds (1.0 = off)
    mapping_coarse_fraction: float = 0.0   # share of mapping iterations at that level
    # Exposure segments rendered at the coarse levels (None: budget.segments; a larger value
    # than budget.segments means budget.segments). A blur of b pixels spans s b pixels at scale
    # s, so fewer sub-poses describe it there: the coarse level keeps every (K / Kc)-th sub-pose
    # and sums the events of the segments it merges (egs_bench/slam/levels.py).
    tracking_coarse_segments: int | None = None  # Kc of tracking's coarse level
    mapping_coarse_segments: int | None = None   # Kc of mapping's coarse level
    # Early end of tracking's coarse level (0 = off): once T_tau has moved less than
    # tracking_coarse_tolerance of the path its steps took over the last this-many coarse
    # iterations (the net-motion rule, egs_bench/slam/convergence.py), the steps go back and
    # forth around the coarse optimum, and tracking goes on with the fine iterations, at the
    # learning rate their place in the schedule gives them. Off: it saved 10-22 % of the
    # time per frame for +49 to +116 % ATE on 30 frames of office-l
    # (docs/notes/engine_cost_2026-12-06.md §12).
    tracking_coarse_patience: int = 0
    tracking_coarse_tolerance: float = 0.3  # net motion / path below which the coarse level ends
    # Which pixels of a new keyframe may become Gaussians (1 in pcd_downsample of them):
    # "all" valid ones (MonoGS), or "uncovered": rendered opacity below insertion_alpha or
    # expected depth off by more than insertion_depth_error x the measured depth.
    insertion: InsertionRule = "all"
    insertion_alpha: float = 0.5           # "uncovered": opacity below which a pixel is new
    insertion_depth_error: float = 0.1     # "uncovered": relative depth error that is new


@dataclass(frozen=True)
class RuntimeConfig:
    """Execution choices that do not change the result beyond floating-point effects."""

    backend: Backend = "auto"           # rasteriser: gsplat on CUDA, numba on the CPU
    # A noise floor for comparisons: N > 0 moves frame 0's starting pose by 1e-6 rad and
    # 1e-6 m in directions drawn from seed N, far below anything measurable, so the spread
    # over N shows how much a run's result moves with floating-point-sized input changes.
    perturbation: int = 0


GROUPS: dict[str, type] = {
    "method": MethodConfig, "loss": LossConfig, "tracking": TrackingConfig,
    "keyframes": KeyframeConfig, "mapping": MappingConfig, "budget": BudgetConfig,
    "runtime": RuntimeConfig,
}


def _build_aliases() -> dict[str, str]:
    """Short names -> ``group.field``: every field name that is unique across the groups, and
    the flat names of earlier versions (kept so stored commands keep working)."""
    seen: dict[str, list[str]] = {}
    for group, cls in GROUPS.items():
        for f in dataclasses.fields(cls):
            seen.setdefault(f.name, []).append(f"{group}.{f.name}")
    aliases = {name: paths[0] for name, paths in seen.items() if len(paths) == 1}
    aliases.update({
        "n_segments": "budget.segments", "kf_interval": "keyframes.interval",
        "kf_overlap": "keyframes.overlap", "kf_min_translation": "keyframes.min_translation",
        "kf_translation": "keyframes.translation", "kf_cutoff": "keyframes.cutoff",
    })
    return aliases


ALIASES = _build_aliases()


@dataclass(frozen=True)
class SlamConfig:
    """All settings of EGS-SLAM / the MonoGS-style baseline, by group (see the module doc)."""

    method: MethodConfig = field(default_factory=MethodConfig)
    loss: LossConfig = field(default_factory=LossConfig)
    tracking: TrackingConfig = field(default_factory=TrackingConfig)
    keyframes: KeyframeConfig = field(default_factory=KeyframeConfig)
    mapping: MappingConfig = field(default_factory=MappingConfig)
    budget: BudgetConfig = field(default_factory=BudgetConfig)
    runtime: RuntimeConfig = field(default_factory=RuntimeConfig)
    # Free-form values for user components (``extra.NAME``), stored but not checked; settings
    # that need their type and range checked go into the component's own config class
    # (:meth:`with_groups`, docs/guide/extending.md).
    extra: dict[str, Any] = field(default_factory=dict)

    # ------------------------------------------------------------------ groups
    def groups(self) -> dict[str, type]:
        """Each group's config class: the built-in one (:data:`GROUPS`) or a component's
        subclass of it, which adds that component's fields (:meth:`with_groups`)."""
        return {group: type(getattr(self, group)) for group in GROUPS}

    def with_groups(self, classes: Mapping[str, type]) -> SlamConfig:
        """A copy whose groups ``classes`` names are of those classes (a component's config,
        a subclass of the group's built-in class), keeping every value the two share and
        taking the new fields' defaults.

        Raises:
            TypeError: a class that does not extend its group's built-in class (the other
                parts read the built-in fields of every group).
        """
        new: dict[str, Any] = {}
        for group, cls in classes.items():
            if not (isinstance(cls, type) and issubclass(cls, GROUPS[group])
                    and dataclasses.is_dataclass(cls)):
                raise TypeError(f"the config of group {group!r} must be a dataclass extending "
                                f"{GROUPS[group].__name__}, got {cls!r}")
            old = getattr(self, group)
            if type(old) is not cls:
                kept = {f.name: getattr(old, f.name) for f in dataclasses.fields(cls)
                        if f.init and hasattr(old, f.name)}
                new[group] = cls(**kept)
        return dataclasses.replace(self, **new)

    # ------------------------------------------------------------------ derived values
    @property
    def n_segments(self) -> int:
        """K: exposure segments rendered (1 without the blur model, then one pose)."""
        return self.budget.segments if self.method.blur_model else 1

    # ------------------------------------------------------------------ editing
    def replace(self, **changes: Any) -> SlamConfig:
        """A copy with fields changed; keys are ``group.field`` paths or short names
        (:data:`ALIASES`). Values are checked by :meth:`validate`, not here.

        Raises:
            ConfigError: an unknown key.
        """
        by_group: dict[str, dict[str, Any]] = {}
        extra = dict(self.extra)
        groups = self.groups()
        for key, value in changes.items():
            if key.startswith(EXTRA_PREFIX):
                extra[_extra_name(key)] = value
                continue
            group, name = resolve_key(key, groups)
            by_group.setdefault(group, {})[name] = value
        new: dict[str, Any] = {g: dataclasses.replace(getattr(self, g), **v)
                               for g, v in by_group.items()}
        return dataclasses.replace(self, **new, extra=extra)

    def get(self, key: str) -> Any:
        """The value of ``group.field`` or a short name."""
        group, name = resolve_key(key, self.groups())
        return getattr(getattr(self, group), name)

    def to_dict(self) -> dict[str, Any]:
        """Nested plain data (stored as the run's resolved configuration)."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any], classes: Mapping[str, type] | None = None
                  ) -> SlamConfig:
        """Inverse of :meth:`to_dict`, with the groups of ``classes`` (components' configs,
        see :meth:`with_groups`; None: the built-in :data:`GROUPS`).

        Also reads the flat layout of earlier versions: a key that is not a group is an
        option name (:data:`ALIASES`), applied over the built-in defaults.

        Raises:
            ConfigError: an unknown group or option.
        """
        kinds = {**GROUPS, **(classes or {})}
        groups: dict[str, Any] = {}
        flat: dict[str, Any] = {}
        for group, values in data.items():
            if group == "extra":
                continue
            if group not in kinds:
                flat[group] = values
                continue
            if not isinstance(values, dict):
                raise ConfigError(f"SLAM configuration group {group!r} is not a mapping")
            known = {f.name for f in dataclasses.fields(kinds[group])}
            unknown = set(values) - known
            if unknown:
                raise ConfigError(f"unknown SLAM option(s) in {group}: "
                                  f"{', '.join(sorted(unknown))}")
            groups[group] = kinds[group](**values)
        missing = {g: k() for g, k in kinds.items() if g not in groups and k is not GROUPS[g]}
        config = cls(**groups, **missing, extra=dict(data.get("extra") or {}))
        return config.replace(**flat)

    # ------------------------------------------------------------------ checking
    def validate(self) -> SlamConfig:
        """Check every field's type and range; returns self.

        Raises:
            ConfigError: naming the option (``group.field``) and what is wrong.
        """
        groups = self.groups()
        for group, cls in groups.items():
            hints = typing.get_type_hints(cls)
            for f in dataclasses.fields(cls):
                _check_type(f"{group}.{f.name}", hints[f.name],
                            getattr(getattr(self, group), f.name))
        for key, bounds in ranges(groups).items():
            value = self.get(key)
            if value is not None:
                _require(bounds.contains(value), key, f"must be {bounds.describe()}"
                         + _null_note(key, bounds, groups))
        m, k, b = self.method, self.keyframes, self.budget
        _require(b.window_size > k.protected, "budget.window_size",
                 "must exceed keyframes.protected")
        if (m.event_tracking or m.event_mapping) and not m.blur_model:
            raise ConfigError("method.event_tracking/event_mapping need method.blur_model "
                              "(events live between sub-poses)")
        return self


@dataclass(frozen=True)
class Bounds:
    """The range a number field must lie in (checked by :meth:`SlamConfig.validate`, shown in
    the configuration reference); a bound of ``None`` is open-ended.

    Attributes:
        low, high: the bounds (``None``: unbounded on that side).
        low_open, high_open: the bound itself is excluded (``> low``, ``< high``).
        null: what ``None`` means for an optional field (``""``: not worth a word).
    """

    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    null: str = ""

    def contains(self, value: float) -> bool:
        """Whether ``value`` lies in the range."""
        above = self.low is None or (value > self.low if self.low_open else value >= self.low)
        below = self.high is None or (value < self.high if self.high_open else value <= self.high)
        return above and below

    def describe(self) -> str:
        """``">= 0"``, ``"> 0"``, ``"in (0, 1]"`` or ``"in [1, 1000000]"``."""
        low, high = _number(self.low), _number(self.high)
        if self.high is None:
            return f"{'>' if self.low_open else '>='} {low}"
        if self.low is None:
            return f"{'<' if self.high_open else '<='} {high}"
        return (f"in {'(' if self.low_open else '['}{low}, {high}"
                f"{')' if self.high_open else ']'}")


def _number(value: float | None) -> str:
    """A bound as written in messages: whole numbers in full (``1000000``, not ``1e+06``)."""
    if value is None:
        return ""
    return str(int(value)) if float(value).is_integer() else f"{value:g}"


_NON_NEGATIVE = Bounds(low=0)
_POSITIVE = Bounds(low=0, low_open=True)
_FRACTION = Bounds(low=0, high=1)
# Every integer field has an upper bound: a count or size is allocated (nodes, sub-poses,
# views) or looped over, and an unchecked 10^20 fails deep inside numpy or torch with the run
# folder already made. The bounds lie far above any useful value (paper and presets: 16 CRF
# nodes, K = 4, 10 keyframes, 1050 iterations).
_MAX_COUNT = 1000  # keyframes, views, sub-poses: each one is rendered or stored
_MAX_ITERATIONS = 1_000_000  # per frame or per keyframe; also frame intervals and periods
_ITERATIONS = Bounds(low=0, high=_MAX_ITERATIONS)
_AT_LEAST_ONE = Bounds(low=1, high=_MAX_ITERATIONS)


def _each(group: str, names: str, bounds: Bounds) -> dict[str, Bounds]:
    return {f"{group}.{name}": bounds for name in names.split()}


#: the range of every number field, by ``group.field`` (a test checks that none is missing)
RANGES: dict[str, Bounds] = {
    "method.crf_nodes": Bounds(low=2, high=1024),
    "method.crf_alpha": _NON_NEGATIVE,
    "method.theta": Bounds(low=0, low_open=True, null="the sequence's thresholds"),
    **_each("loss", "lambda_ne lambda_e lambda_id lambda_i lambda_d lambda_iso edge_threshold "
            "rgb_boundary_threshold", _NON_NEGATIVE),
    "tracking.short_exposure_ratio": _FRACTION,
    **_each("tracking", "lr_exposure max_translation_jump max_rotation_jump "
            "divergence_loss_factor", _POSITIVE),
    "tracking.convergence_tolerance": Bounds(low=0, high=1, low_open=True, high_open=True),
    "tracking.convergence_patience": _AT_LEAST_ONE,
    "keyframes.interval": _AT_LEAST_ONE,
    **_each("keyframes", "overlap cutoff", _FRACTION),
    **_each("keyframes", "min_translation translation", _NON_NEGATIVE),
    "keyframes.protected": Bounds(low=1),  # and below budget.window_size
    "mapping.n_random_kfs": Bounds(low=0, high=_MAX_COUNT),
    "mapping.refine_iters": _ITERATIONS,
    **_each("mapping", "kf_pose_lr_scale lr_quats lr_crf point_size near_plane", _POSITIVE),
    **_each("mapping", "prune_opacity init_prune_opacity", Bounds(low=0, high=1, high_open=True)),
    "budget.resolution_scale": Bounds(low=0, high=1, low_open=True),
    "budget.segments": Bounds(low=1, high=64),
    **_each("budget", "tracking_iters init_iters mapping_iters", _ITERATIONS),
    "budget.pose_window": Bounds(low=0, high=_MAX_COUNT),
    "budget.tracking_iters_no_prior": Bounds(low=0, high=_MAX_ITERATIONS, null="tracking_iters"),
    "budget.mapping_iters_per_frame": Bounds(low=1, high=_MAX_ITERATIONS,
                                             null="mapping_iters / keyframes.interval"),
    "budget.views_per_iter": Bounds(low=1, high=_MAX_COUNT, null="every view"),
    "budget.window_size": Bounds(low=3, high=_MAX_COUNT),
    "budget.edge_blocks": Bounds(low=1, high=4096, null="one global threshold"),
    **_each("budget", "pcd_downsample_init pcd_downsample prune_every", _AT_LEAST_ONE),
    "budget.prune_contribution": _NON_NEGATIVE,
    "budget.prune_offset": _ITERATIONS,
    "budget.tracking_lr_final": Bounds(low=0, high=1, low_open=True),
    **_each("budget", "lr_rot lr_trans lr_means lr_colors lr_opacity lr_scales", _POSITIVE),
    "budget.lambda_exposure_prior": _NON_NEGATIVE,
    "budget.converged_threshold": _NON_NEGATIVE,
    "budget.tracking_coarse_patience": _ITERATIONS,
    "budget.tracking_coarse_tolerance": Bounds(low=0, high=1, low_open=True, high_open=True),
    **_each("budget", "tracking_coarse_scale mapping_coarse_scale",
            Bounds(low=0, high=1, low_open=True)),
    **_each("budget", "tracking_coarse_fraction mapping_coarse_fraction insertion_alpha",
            _FRACTION),
    "budget.insertion_depth_error": _POSITIVE,
    **_each("budget", "tracking_coarse_segments mapping_coarse_segments",
            Bounds(low=1, high=64, null="budget.segments")),
    "runtime.perturbation": Bounds(low=0, high=1_000_000),
}


def ranges(groups: Mapping[str, type] = GROUPS) -> dict[str, Bounds]:
    """The range of every number field of ``groups`` by ``group.field``: :data:`RANGES`, and
    for a component's config class (a subclass of a built-in group) the ranges of its own
    fields, declared as its class attribute ``RANGES: ClassVar[dict[str, Bounds]]`` by field
    name."""
    out = dict(RANGES)
    for group, cls in groups.items():
        if cls is not GROUPS[group]:
            out.update({f"{group}.{name}": bounds
                        for name, bounds in getattr(cls, "RANGES", {}).items()})
    return out


def _null_note(key: str, bounds: Bounds, groups: Mapping[str, type] = GROUPS) -> str:
    """`` (or null: meaning)`` for a field that may be None, else ``""``."""
    group, name = key.split(".")
    if type(None) not in typing.get_args(typing.get_type_hints(groups[group])[name]):
        return ""
    return f" (or null: {bounds.null})" if bounds.null else " (or null)"


def _require(ok: bool, key: str, problem: str) -> None:
    if not ok:
        raise ConfigError(f"SLAM option {key} {problem}")


def _check_type(key: str, kind: Any, value: Any) -> None:
    """``value`` against a field annotation (``float``, ``int | None``, ``Literal[...]``)."""
    if not _type_ok(kind, value):
        raise ConfigError(f"SLAM option {key} needs {_type_name(kind)}, got {value!r}")


def _type_ok(kind: Any, value: Any) -> bool:
    origin = typing.get_origin(kind)
    if origin is Literal:
        return value in typing.get_args(kind)
    if origin in (typing.Union, getattr(__import__("types"), "UnionType", None)):
        return any(_type_ok(k, value) for k in typing.get_args(kind))
    if kind is type(None):
        return value is None
    if kind is bool:
        return isinstance(value, bool)
    if kind is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if kind is float:
        return (isinstance(value, int | float) and not isinstance(value, bool)
                and math.isfinite(value))
    return True


def _type_name(kind: Any) -> str:
    origin = typing.get_origin(kind)
    if origin is Literal:
        return "one of " + ", ".join(repr(a) for a in typing.get_args(kind))
    if origin is not None:
        return " or ".join(_type_name(k) for k in typing.get_args(kind))
    if kind is type(None):
        return "null"
    return {"float": "a finite number", "int": "an integer", "bool": "true or false"}.get(
        getattr(kind, "__name__", str(kind)), str(kind))


EXTRA_PREFIX = "extra."


def _extra_name(key: str) -> str:
    """``"extra.lambda_tv"`` -> ``"lambda_tv"``; refuses an empty or dotted name."""
    name = key[len(EXTRA_PREFIX):]
    if not name.isidentifier():
        raise ConfigError(f"SLAM option {key!r}: extra.NAME needs a name made of letters, "
                          "digits and underscores")
    return name


def resolve_key(key: str, groups: Mapping[str, type] = GROUPS) -> tuple[str, str]:
    """``"loss.lambda_d"`` or ``"lambda_d"`` -> ``("loss", "lambda_d")``; ``groups``: the
    config class of each group (a component's own fields are reached as ``group.field``).

    Raises:
        ConfigError: unknown group or field.
    """
    path = ALIASES.get(key, key)
    group, sep, name = path.partition(".")
    if not sep or group not in groups or name not in {
            f.name for f in dataclasses.fields(groups[group])}:
        raise ConfigError(f"unknown SLAM option {key!r} (options are group.field, e.g. "
                          f"loss.lambda_d, or a field name: {', '.join(sorted(ALIASES))})")
    return group, name


# ---------------------------------------------------------------------- presets (budgets)

def paper_preset() -> SlamConfig:
    """The paper's / MonoGS's budget at full sequence resolution (GPU-sized work)."""
    return SlamConfig()


CPU_BUDGET = BudgetConfig(
    # The sequence's full resolution, with most iterations at a coarse level: more accurate
    # than half the resolution for fewer blends; on 2 cores 1.13x its time over 24 frames of
    # demo-blur, 0.84-0.96x over 150 frames of 448x256, where pruning by contribution keeps
    # the map small (BENCHMARKS.md "Accuracy per work"; docs/notes/engine_cost_2026-12-06.md,
    # contribution_pruning_2026-12-07.md). K = 3: each sub-pose is a render; the coarse
    # levels render K = 2 (3 sub-poses): their blur spans a half or a quarter of the pixels
    # (K = 1 there doubled the ATE).
    resolution_scale=1.0,
    segments=3,
    tracking_coarse_segments=2,
    mapping_coarse_segments=2,
    # 30 tracking iterations with larger, decaying steps instead of 100 at MonoGS's rates; the
    # first 28 at a quarter of the resolution, the last 2 at the full one. 20 (18 coarse) left
    # fast motion behind, 14 tracked worse still, 40 gained nothing over 30.
    tracking_iters=30,
    tracking_coarse_scale=0.25,
    tracking_coarse_fraction=0.934,
    # The frame without a velocity (frame 1) starts off by the whole motion since frame 0:
    # 100 iterations let it catch a fast start (office-l: 5 cm and 2.8 deg per frame), where
    # 20 confused the translation with a rotation and the error grew to 22 cm.
    tracking_iters_no_prior=100,
    lr_rot=0.006,
    lr_trans=0.006,
    tracking_lr_final=0.1,
    converged_threshold=2e-4,
    # Map initialisation and keyframe rounds: all but the last 5 % at half the resolution.
    init_iters=100,
    mapping_coarse_scale=0.5,
    mapping_coarse_fraction=0.95,
    # 20 iterations x 2 views per keyframe: 30 gained nothing measurable at the full
    # resolution; a third view cost more and gained nothing either
    # (docs/notes/slam_config_measurements_2026-12-04.md).
    mapping_iters=20,
    views_per_iter=2,
    prune_every=20,
    prune_offset=19,
    # At each keyframe, the Gaussians that blend less than 0.2 pixel summed over the window's
    # keyframes go: over 150 frames of office-l, livingroom-l and corridor-l the map ends 2.5x
    # smaller, at ATE -5 to +6 % and PSNR -0.2 to +0.2 dB (one seed each); on corridor-l a
    # frame takes 0.64x the time (docs/notes/contribution_pruning_2026-12-07.md).
    prune_contribution=0.2,
    # 1 in 2 valid pixels at frame 0, 1 in 8 at keyframes: sparser maps at the full resolution
    # tracked worse, and the end-to-end test's accuracy bound failed (the same note).
    pcd_downsample_init=2,
    pcd_downsample=8,
    # 16 edge-mask blocks, measured at this budget's resolution (MonoGS uses 32 on Replica's
    # 1200x680).
    edge_blocks=16,
    # Larger Gaussian steps for 20 instead of 150 iterations per keyframe.
    lr_colors=0.01,
    lr_opacity=0.05,
    lr_means=0.002,
    lr_scales=0.01,
    # 20 mapping iterations x 2 views per keyframe let the per-frame exposures drift on
    # sequences of constant exposure (a = -0.22 after 24 frames of demo-blur). 0.1 holds them
    # within 0.01 there (egs +1.0 dB, monogs +0.5 dB, ATE within the seeds' spread). On a
    # real gain change egs still does as well as without it (monogs: +0.6 dB, but +18 % ATE);
    # 1 held the exposure against the change (docs/notes/engine_cost_2026-12-06.md §9).
    lambda_exposure_prior=0.1,
)


def cpu_preset() -> SlamConfig:
    """The same method with a fraction of the work (:data:`CPU_BUDGET`), for 2 CPU cores."""
    return SlamConfig(budget=CPU_BUDGET)


PRESETS = {"paper": paper_preset, "cpu": cpu_preset}


def resolve_device(device: str) -> str:
    """``auto`` -> ``cuda`` when a CUDA GPU is available, else ``cpu``; checks the others.

    Raises:
        ConfigError: an unknown device, or ``cuda`` without a GPU.
    """
    import torch

    if device == "auto":
        return "cuda" if torch.cuda.is_available() else "cpu"
    if device.startswith("cuda"):
        if not torch.cuda.is_available():
            raise ConfigError(f"--device {device} requested but no CUDA GPU is available")
        return device
    if device != "cpu":
        raise ConfigError(f"unknown device {device!r} (auto, cpu, cuda or cuda:N)")
    return device


def resolve_preset(name: str, device: str) -> str:
    """``auto`` -> the GPU budget (``paper``) on CUDA, the ``cpu`` budget otherwise."""
    if name == "auto":
        return "paper" if device.startswith("cuda") else "cpu"
    if name not in PRESETS:
        raise ConfigError(f"unknown preset {name!r} (choose from auto, {', '.join(PRESETS)})")
    return name


def preset(name: str) -> SlamConfig:
    """The named preset (``paper`` or ``cpu``)."""
    try:
        return PRESETS[name]()
    except KeyError:
        raise ConfigError(f"unknown preset {name!r} (choose from {', '.join(PRESETS)})") from None


# A decimal number as YAML 1.2 writes it. PyYAML follows YAML 1.1, whose float needs a dot
# and a signed exponent, so `1e-3` and `5e2` arrive as strings.
_DECIMAL = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def _as_float(value: Any) -> Any:
    """``value`` as a float where it is an integer or a decimal string (``"1e-3"``); anything
    else unchanged, for the type check to refuse."""
    if isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if isinstance(value, str) and _DECIMAL.fullmatch(value.strip()):
        return float(value)
    return value


def parse_overrides(items: list[str], groups: Mapping[str, type] = GROUPS) -> dict[str, Any]:
    """``["lambda_d=0.05", "method.crf=srgb", "theta=null"]`` -> ``{"loss.lambda_d": 0.05,
    "method.crf": "srgb", "method.theta": None}`` (keys as ``group.field`` paths).

    Values are read as YAML scalars (numbers, true/false, null, strings) and checked against
    the field's type; a number field also takes a decimal string such as ``"1e-3"`` (which
    YAML 1.1 reads as a string), so ``--set`` and a sweep file's ``set:`` accept it.
    ``groups``: the config class of each group, for a method whose components add fields
    (:meth:`SlamConfig.groups`).

    Raises:
        ConfigError: an item without ``=``, an unknown key, or a value of the wrong type.
    """
    import yaml

    out: dict[str, Any] = {}
    for item in items:
        key, sep, raw = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ConfigError(f"option override {item!r} is not KEY=VALUE")
        try:
            value = yaml.safe_load(raw) if raw.strip() else None
        except yaml.YAMLError:
            value = raw
        if isinstance(value, str) and value.lower() in ("nan", "inf", "-inf", ".nan", ".inf"):
            value = float(value.lstrip("."))
        if key.startswith(EXTRA_PREFIX):
            name = _extra_name(key)
            if isinstance(value, float) and not math.isfinite(value):
                raise ConfigError(f"{key} must be a finite number, got {raw!r}")
            out[f"{EXTRA_PREFIX}{name}"] = value
            continue
        group, name = resolve_key(key, groups)
        kind = typing.get_type_hints(groups[group])[name]
        if kind is float or float in typing.get_args(kind):
            value = _as_float(value)
        _check_type(f"{group}.{name}", kind, value)
        out[f"{group}.{name}"] = value
    return out
