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
"""

from __future__ import annotations

import dataclasses
import math
import typing
from dataclasses import dataclass, field
from typing import Any, Literal

from egs_bench.errors import ConfigError
from egs_bench.slam.convergence import ConvergenceRule

CrfKind = Literal["learnable", "srgb", "identity"]
CrfInit = Literal["linear", "srgb"]
MotionModel = Literal["constant-position", "constant-velocity"]
Backend = Literal["auto", "numba", "reference", "gsplat"]
MappingMode = Literal["sequential", "concurrent"]


@dataclass(frozen=True)
class MethodConfig:
    """What defines a method (EGS-SLAM, its ablations, the MonoGS-style baseline)."""

    blur_model: bool = True             # K+1 sub-poses over the exposure (False: one pose)
    event_tracking: bool = True         # event loss in tracking
    event_mapping: bool = True          # event loss in mapping
    no_event_loss: bool = True          # L_NE on silent pixels
    crf: CrfKind = "learnable"
    crf_nodes: int = 16
    crf_alpha: float = 0.01             # (paper)
    # Initial curve of the learnable CRF: "linear" (evenly spaced nodes, the identity; the paper
    # does not say) or "srgb". Measured on `demo` (20 frames, cpu budget): the sRGB start
    # tracked worse (raw error 6.4 vs 1.6 cm; docs/notes/slam.md).
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
class TrackingConfig:
    """How a frame's exposure trajectory is predicted and estimated."""

    motion_model: MotionModel = "constant-velocity"
    # Tracking estimates T_tau only and places T_0 on the path from the previous frame's T_tau
    # (constant velocity over the frame interval) instead of estimating both freely (paper).
    continuous_exposure: bool = False
    # ... and the same for a frame whose exposure lasts less than this fraction of the time
    # since the previous exposure ended (0 = never). Its blur then spans a small fraction of
    # the inter-frame motion, below what the image resolves, so a free T_0 is barely
    # constrained: on the unblurred `demo-sharp` (1 ms of 33 ms) T_0 and T_tau drifted 1-3 cm
    # apart and egs tracked worse than monogs (docs/notes/slam.md). Blurred sequences (25 of
    # 33 ms, ratio 0.75) keep both poses free, as in the paper, whose data are all blurred.
    short_exposure_ratio: float = 0.5
    lr_exposure: float = 0.01           # (MonoGS)
    max_translation_jump: float = 0.5   # m between consecutive frames, else divergence
    max_rotation_jump: float = 0.6      # rad between consecutive frames, else divergence
    divergence_loss_factor: float = 20.0  # final loss > factor x running median -> divergence
    # When a frame may stop before its iteration budget (egs_bench/slam/convergence.py):
    # "fixed" runs the budget (MonoGS's absolute step threshold aside), "relative-step" /
    # "plateau" stop once the step / the loss's improvement has fallen below
    # convergence_tolerance (relative) for convergence_patience iterations.
    convergence: ConvergenceRule = "fixed"
    convergence_tolerance: float = 0.1
    convergence_patience: int = 3


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
class MappingConfig:
    """How the map (and keyframe poses, exposures, the CRF) are optimised."""

    refine_poses: bool = False          # refine the newest keyframes' trajectories in mapping
    # "sequential": a keyframe's mapping round runs before the next frame is tracked;
    # "concurrent": beside the next frames' tracking (egs_bench/slam/scheduling.py).
    mapping_mode: MappingMode = "sequential"
    n_random_kfs: int = 2               # (paper, MonoGS) older keyframes added per iteration
    kf_pose_lr_scale: float = 0.5       # (MonoGS) keyframe pose lr = 0.5 x tracking lr
    prune_opacity: float = 0.1          # periodic pruning below this opacity
    init_prune_opacity: float = 0.005   # (MonoGS init_gaussian_th)
    lr_quats: float = 0.001
    lr_crf: float = 0.005
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
    # error of a prediction. None = tracking_iters, in both presets: 100 at the cpu budget
    # fixed `office-l`'s failed start (120 frames, egs 3.26 -> 1.06 cm ATE) but moved `demo`'s
    # frame 1 from 0.88 to 1.24 cm off (12-frame ATE 0.47 -> 1.22 cm), and no test on the
    # first, short tracking told the two apart (docs/notes/slam.md finding 35).
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
    prune_offset: int = 50
    pcd_downsample_init: int = 8        # keep 1 of this many valid pixels at frame 0
    pcd_downsample: int = 16            # ... at later keyframes
    edge_blocks: int | None = 32        # (MonoGS, Replica) edge-mask grid; None = global
    lr_means: float = 0.00016 * 6       # (MonoGS, times its spatial_lr_scale 6)
    lr_colors: float = 0.0025 * 0.28209479  # (MonoGS f_dc lr expressed on colours)
    lr_opacity: float = 0.05
    lr_scales: float = 0.001 * 6


@dataclass(frozen=True)
class RuntimeConfig:
    """Execution choices that do not change the result beyond floating-point effects."""

    backend: Backend = "auto"


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
    # Free-form values for user components (``extra.NAME``), e.g. the weight of a loss term
    # that a researcher adds (docs/guide/extending.md).
    extra: dict[str, Any] = field(default_factory=dict)

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
        for key, value in changes.items():
            if key.startswith(EXTRA_PREFIX):
                extra[_extra_name(key)] = value
                continue
            group, name = resolve_key(key)
            by_group.setdefault(group, {})[name] = value
        new: dict[str, Any] = {g: dataclasses.replace(getattr(self, g), **v)
                               for g, v in by_group.items()}
        return dataclasses.replace(self, **new, extra=extra)

    def get(self, key: str) -> Any:
        """The value of ``group.field`` or a short name."""
        group, name = resolve_key(key)
        return getattr(getattr(self, group), name)

    def to_dict(self) -> dict[str, Any]:
        """Nested plain data (stored as the run's resolved configuration)."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> SlamConfig:
        """Inverse of :meth:`to_dict` (unknown keys raise :class:`ConfigError`)."""
        groups = {}
        for group, values in data.items():
            if group == "extra":
                continue
            if group not in GROUPS or not isinstance(values, dict):
                raise ConfigError(f"unknown SLAM configuration group {group!r}")
            known = {f.name for f in dataclasses.fields(GROUPS[group])}
            unknown = set(values) - known
            if unknown:
                raise ConfigError(f"unknown SLAM option(s) in {group}: "
                                  f"{', '.join(sorted(unknown))}")
            groups[group] = GROUPS[group](**values)
        return cls(**groups, extra=dict(data.get("extra") or {}))

    # ------------------------------------------------------------------ checking
    def validate(self) -> SlamConfig:
        """Check every field's type and range; returns self.

        Raises:
            ConfigError: naming the option (``group.field``) and what is wrong.
        """
        for group, cls in GROUPS.items():
            hints = typing.get_type_hints(cls)
            for f in dataclasses.fields(cls):
                _check_type(f"{group}.{f.name}", hints[f.name],
                            getattr(getattr(self, group), f.name))
        m, lo, t, k, mp, b = (self.method, self.loss, self.tracking, self.keyframes,
                              self.mapping, self.budget)
        _require(m.crf_nodes >= 2, "method.crf_nodes", "must be >= 2")
        _require(m.crf_alpha >= 0, "method.crf_alpha", "must be >= 0")
        _require(m.theta is None or m.theta > 0, "method.theta", "must be > 0 (or null)")
        for name in ("lambda_ne", "lambda_e", "lambda_id", "lambda_i", "lambda_d", "lambda_iso",
                     "edge_threshold", "rgb_boundary_threshold"):
            _require(getattr(lo, name) >= 0, f"loss.{name}", "must be >= 0")
        _require(0 <= t.short_exposure_ratio <= 1, "tracking.short_exposure_ratio",
                 "must be in [0, 1]")
        for name in ("lr_exposure", "max_translation_jump", "max_rotation_jump",
                     "divergence_loss_factor"):
            _require(getattr(t, name) > 0, f"tracking.{name}", "must be > 0")
        _require(0 < t.convergence_tolerance < 1, "tracking.convergence_tolerance",
                 "must be in (0, 1)")
        _require(t.convergence_patience >= 1, "tracking.convergence_patience", "must be >= 1")
        _require(k.interval >= 1, "keyframes.interval", "must be >= 1")
        _require(b.mapping_iters_per_frame is None or b.mapping_iters_per_frame >= 1,
                 "budget.mapping_iters_per_frame", "must be >= 1 (or null)")
        for name in ("overlap", "cutoff"):
            _require(0 <= getattr(k, name) <= 1, f"keyframes.{name}", "must be in [0, 1]")
        _require(k.min_translation >= 0 and k.translation >= 0, "keyframes.translation",
                 "thresholds must be >= 0")
        _require(k.protected >= 1, "keyframes.protected", "must be >= 1")
        for name in ("n_random_kfs", "refine_iters"):
            _require(getattr(mp, name) >= 0, f"mapping.{name}", "must be >= 0")
        for name in ("kf_pose_lr_scale", "lr_quats", "lr_crf", "point_size", "near_plane"):
            _require(getattr(mp, name) > 0, f"mapping.{name}", "must be > 0")
        for name in ("prune_opacity", "init_prune_opacity"):
            _require(0 <= getattr(mp, name) < 1, f"mapping.{name}", "must be in [0, 1)")
        _require(0 < b.resolution_scale <= 1, "budget.resolution_scale", "must be in (0, 1]")
        _require(b.segments >= 1, "budget.segments", "must be >= 1")
        for name in ("tracking_iters", "init_iters", "mapping_iters", "pose_window"):
            _require(getattr(b, name) >= 0, f"budget.{name}", "must be >= 0")
        _require(b.tracking_iters_no_prior is None or b.tracking_iters_no_prior >= 0,
                 "budget.tracking_iters_no_prior", "must be >= 0 (or null: tracking_iters)")
        _require(b.window_size >= 3, "budget.window_size", "must be >= 3")
        _require(b.window_size > k.protected, "budget.window_size",
                 "must exceed keyframes.protected")
        _require(b.views_per_iter is None or b.views_per_iter >= 1, "budget.views_per_iter",
                 "must be >= 1 (or null: every view)")
        _require(b.edge_blocks is None or b.edge_blocks >= 1, "budget.edge_blocks",
                 "must be >= 1 (or null)")
        for name in ("pcd_downsample_init", "pcd_downsample", "prune_every"):
            _require(getattr(b, name) >= 1, f"budget.{name}", "must be >= 1")
        _require(b.prune_offset >= 0, "budget.prune_offset", "must be >= 0")
        _require(0 < b.tracking_lr_final <= 1, "budget.tracking_lr_final", "must be in (0, 1]")
        for name in ("lr_rot", "lr_trans", "lr_means", "lr_colors", "lr_opacity", "lr_scales"):
            _require(getattr(b, name) > 0, f"budget.{name}", "must be > 0")
        _require(b.converged_threshold >= 0, "budget.converged_threshold", "must be >= 0")
        if (m.event_tracking or m.event_mapping) and not m.blur_model:
            raise ConfigError("method.event_tracking/event_mapping need method.blur_model "
                              "(events live between sub-poses)")
        return self


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


def resolve_key(key: str) -> tuple[str, str]:
    """``"loss.lambda_d"`` or ``"lambda_d"`` -> ``("loss", "lambda_d")``.

    Raises:
        ConfigError: unknown group or field.
    """
    path = ALIASES.get(key, key)
    group, sep, name = path.partition(".")
    if not sep or group not in GROUPS or name not in {
            f.name for f in dataclasses.fields(GROUPS[group])}:
        raise ConfigError(f"unknown SLAM option {key!r} (options are group.field, e.g. "
                          f"loss.lambda_d, or a field name: {', '.join(sorted(ALIASES))})")
    return group, name


# ---------------------------------------------------------------------- presets (budgets)

def paper_preset() -> SlamConfig:
    """The paper's / MonoGS's budget at full sequence resolution (GPU-sized work)."""
    return SlamConfig()


CPU_BUDGET = BudgetConfig(
    # Half resolution and K = 3: each rendered pixel costs a numba kernel on 2 cores.
    resolution_scale=0.5,
    segments=3,
    # 20 tracking iterations with larger, decaying steps instead of 100 at MonoGS's rates.
    tracking_iters=20,
    lr_rot=0.006,
    lr_trans=0.006,
    tracking_lr_final=0.1,
    converged_threshold=2e-4,
    init_iters=150,
    # 30 iterations x 3 views per keyframe: with 10 x 2 the map lagged behind the new keyframes
    # and both methods drifted (monogs on `demo`, 40 frames: raw error 12 -> 5 cm).
    mapping_iters=30,
    views_per_iter=3,
    prune_every=20,
    prune_offset=19,
    # 1 in 2 valid pixels at frame 0, 1 in 8 at keyframes: with 1 in 4 / 1 in 16 the map was
    # too coarse for the blur model (egs on `demo` 1.30 -> 0.52 cm, monogs 1.57 -> 1.29).
    pcd_downsample_init=2,
    pcd_downsample=8,
    # The same block size in pixels as 32 blocks at the full resolution.
    edge_blocks=16,
    # Larger Gaussian steps for 30 instead of 150 iterations per keyframe.
    lr_colors=0.01,
    lr_opacity=0.05,
    lr_means=0.002,
    lr_scales=0.01,
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


def parse_overrides(items: list[str]) -> dict[str, Any]:
    """``["lambda_d=0.05", "method.crf=srgb", "theta=null"]`` -> ``{"loss.lambda_d": 0.05,
    "method.crf": "srgb", "method.theta": None}`` (keys as ``group.field`` paths).

    Values are read as YAML scalars (numbers, true/false, null, strings) and checked against
    the field's type.

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
        group, name = resolve_key(key)
        kind = typing.get_type_hints(GROUPS[group])[name]
        if kind is float or float in typing.get_args(kind):
            if isinstance(value, int) and not isinstance(value, bool):
                value = float(value)
        _check_type(f"{group}.{name}", kind, value)
        out[f"{group}.{name}"] = value
    return out
