"""Configuration of the SLAM system: one dataclass, two presets (``paper`` and ``cpu``).

Methods (``egs``, ablations, ``monogs``) are overrides of these fields, not code forks; see
:mod:`egs_bench.slam.methods`. Every field is plain data so the resolved configuration is
stored verbatim in the run folder's ``config.yaml``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

from egs_bench.errors import ConfigError


@dataclass
class SlamConfig:
    """All knobs of EGS-SLAM / the MonoGS-style baseline.

    Values marked (paper) are from EGS-SLAM §V.B; (MonoGS) from MonoGS's Replica RGB-D
    single-process configuration (research note monogs_gsplat.md §1).
    """

    # ---- method ------------------------------------------------------------------------
    n_segments: int = 4                 # K: exposure segments; K+1 sub-poses (1 = no blur model)
    event_tracking: bool = True         # event loss in tracking
    event_mapping: bool = True          # event loss in mapping
    no_event_loss: bool = True          # L_NE on silent pixels
    crf: str = "learnable"              # learnable | srgb | identity
    crf_nodes: int = 16
    crf_alpha: float = 0.01             # (paper)
    # Initial curve of the learnable CRF: "linear" (evenly spaced nodes, the identity; the paper
    # does not say) or "srgb". Measured on `demo` (20 frames, cpu preset): the sRGB start
    # tracked worse (raw error 6.4 vs 1.6 cm; docs/notes/slam.md, third-session finding 3).
    crf_init: str = "linear"
    exposure_compensation: bool = True  # per-frame exp(a) I + b (MonoGS)
    theta: float | None = None          # event threshold; None = the sequence's pos/neg values
    lambda_ne: float = 0.4              # (paper)
    lambda_e: float = 0.05              # (paper, synthetic; real data 0.15)
    lambda_id: float = 0.95             # (paper, synthetic; real data 0.85)
    lambda_i: float = 0.9               # (paper)
    lambda_d: float = 0.1               # (paper)
    lambda_iso: float = 10.0            # (paper, MonoGS)
    # ---- tracking ----------------------------------------------------------------------
    tracking_iters: int = 100           # (MonoGS)
    lr_rot: float = 0.003               # (MonoGS)
    lr_trans: float = 0.001             # (MonoGS)
    lr_exposure: float = 0.01           # (MonoGS)
    converged_threshold: float = 1e-4   # (MonoGS) |twist| after a step
    tracking_lr_final: float = 1.0      # pose lr decays exponentially to this factor (1 = MonoGS)
    motion_model: str = "constant-position"  # or constant-velocity
    # Tracking estimates T_tau only and places T_0 on the path from the previous frame's T_tau
    # (constant velocity over the frame interval) instead of estimating both freely (paper).
    continuous_exposure: bool = False
    # ... and the same for a frame whose exposure lasts less than this fraction of the time
    # since the previous exposure ended (0 = never). Its blur then spans a small fraction of
    # the inter-frame motion, below what the image resolves, so a free T_0 is barely
    # constrained: on the unblurred `demo-sharp` (1 ms of 33 ms) at full resolution T_0 and
    # T_tau drifted 1-3 cm apart and egs tracked worse than monogs (docs/notes/slam.md,
    # finding 19). The built-in blurred sequences (25 of 33 ms, ratio 0.75) keep both poses
    # free, as in the paper, whose data are all blurred.
    short_exposure_ratio: float = 0.5
    use_edge_mask: bool = True          # (MonoGS) tracking photometric term on edges only
    edge_threshold: float = 4.0         # (MonoGS, Replica)
    edge_blocks: int | None = 32        # (MonoGS, Replica)
    rgb_boundary_threshold: float = 0.01  # (MonoGS)
    # Depth term on the alpha-normalised depth sum(w z) / sum(w) instead of MonoGS's sum(w z):
    # the latter is biased short wherever the map does not yet reach alpha = 1, which on a
    # sparse, briefly optimised map pulls the tracked pose forward. The division keeps alpha
    # in the graph: with alpha detached the term lowered every opacity where the depth was
    # too long and eroded the map into holes (docs/notes/slam.md, finding 16).
    expected_depth: bool = False
    # ---- keyframes / mapping -------------------------------------------------------------
    kf_interval: int = 4                # (MonoGS)
    kf_overlap: float = 0.95
    kf_min_translation: float = 0.02
    kf_translation: float = 0.04
    kf_cutoff: float = 0.4
    window_size: int = 10               # (paper)
    pose_window: int = 5                # (paper) latest keyframes whose trajectories are refined
    n_random_kfs: int = 2               # (paper, MonoGS)
    views_per_iter: int | None = None   # None = whole mapping set every iteration (MonoGS)
    init_iters: int = 1050              # (MonoGS) mapping iterations on frame 0
    mapping_iters: int = 150            # (MonoGS single process) per new keyframe
    prune_every: int = 150              # (MonoGS) opacity pruning period (mapping iterations)
    prune_offset: int = 50
    prune_opacity: float = 0.7          # (MonoGS gaussian_th)
    init_prune_opacity: float = 0.005   # (MonoGS init_gaussian_th)
    lr_means: float = 0.00016 * 6       # (MonoGS, times its spatial_lr_scale 6)
    lr_colors: float = 0.0025 * 0.28209479  # (MonoGS f_dc lr expressed on colours)
    lr_opacity: float = 0.05
    lr_scales: float = 0.001 * 6
    lr_quats: float = 0.001
    lr_crf: float = 0.005
    kf_pose_lr_scale: float = 0.5       # (MonoGS) keyframe pose lr = 0.5 x tracking lr
    # Final map refinement after the last frame, one random keyframe per iteration (0 = none).
    # MonoGS runs 26000 for its "after_opt" numbers only; the paper does not say whether
    # EGS-SLAM refines, so neither preset does.
    refine_iters: int = 0
    # ---- map ---------------------------------------------------------------------------
    pcd_downsample_init: int = 8        # keep 1 of this many valid pixels at frame 0
    pcd_downsample: int = 16            # ... at later keyframes
    point_size: float = 0.5             # scale^2 = point_size x mean sq. 3-NN distance
    near_plane: float = 0.2             # (MonoGS)
    # ---- runtime -----------------------------------------------------------------------
    resolution_scale: float = 1.0       # internal processing resolution factor
    backend: str = "auto"
    max_translation_jump: float = 0.5   # m between consecutive frames, else divergence
    max_rotation_jump: float = 0.6      # rad between consecutive frames, else divergence
    divergence_loss_factor: float = 20.0  # final loss > factor x running median -> divergence
    extra: dict[str, Any] = field(default_factory=dict)  # free-form, for user methods

    def validate(self) -> SlamConfig:
        """Raise :class:`ConfigError` on inconsistent values; returns self."""
        if self.n_segments < 1:
            raise ConfigError(f"n_segments must be >= 1, got {self.n_segments}")
        if self.crf not in ("learnable", "srgb", "identity"):
            raise ConfigError(f"crf must be learnable, srgb or identity, got {self.crf!r}")
        if self.crf_init not in ("linear", "srgb"):
            raise ConfigError(f"crf_init must be linear or srgb, got {self.crf_init!r}")
        if self.motion_model not in ("constant-position", "constant-velocity"):
            raise ConfigError(f"unknown motion_model {self.motion_model!r}")
        if not 0 <= self.short_exposure_ratio <= 1:
            raise ConfigError("short_exposure_ratio must be in [0, 1]")
        if not 0 < self.resolution_scale <= 1:
            raise ConfigError("resolution_scale must be in (0, 1]")
        if self.window_size < 3 or self.pose_window < 0:
            raise ConfigError("window_size must be >= 3 and pose_window >= 0")
        for name in ("tracking_iters", "mapping_iters", "init_iters", "refine_iters"):
            if getattr(self, name) < 0:
                raise ConfigError(f"{name} must be >= 0")
        if (self.event_tracking or self.event_mapping) and self.n_segments < 2:
            raise ConfigError("event losses need n_segments >= 2 (events live between sub-poses)")
        return self

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    def replace(self, **changes: Any) -> SlamConfig:
        unknown = set(changes) - {f.name for f in dataclasses.fields(self)}
        if unknown:
            raise ConfigError(f"unknown SLAM option(s): {', '.join(sorted(unknown))}")
        return dataclasses.replace(self, **changes)


def paper_preset() -> SlamConfig:
    """Paper / MonoGS values at full sequence resolution (GPU-sized work)."""
    return SlamConfig()


def cpu_preset() -> SlamConfig:
    """Same method, a fraction of the work: half resolution, K=3, few iterations, and each
    mapping iteration renders a random subset of the mapping set. Meant for 2 CPU cores."""
    return SlamConfig(
        n_segments=3,
        resolution_scale=0.5,
        motion_model="constant-velocity",
        tracking_iters=20,
        lr_rot=0.006,
        lr_trans=0.006,
        tracking_lr_final=0.1,
        converged_threshold=2e-4,
        init_iters=150,
        # The sparse CPU map leaves alpha < 1 in many pixels, where the accumulated depth
        # sum(w z) is far too short and pulls tracking forward; the alpha-normalised depth
        # removed that bias (monogs on `demo`, 20 frames: ATE 10.1 -> 2.5 cm).
        expected_depth=True,
        # 30 iterations x 3 views per keyframe: with 10 x 2 the map lagged behind the new
        # keyframes and both methods drifted (monogs on `demo`, 40 frames: raw error 12 -> 5 cm).
        mapping_iters=30,
        views_per_iter=3,
        # No keyframe-pose refinement in mapping: with these short mapping rounds it moved
        # keyframe poses by 10-20 cm (egs on `demo`; docs/notes/slam.md). The paper preset keeps
        # the paper's 5.
        pose_window=0,
        prune_every=20,
        prune_offset=19,
        prune_opacity=0.1,
        # 1 in 2 valid pixels at frame 0, 1 in 8 at keyframes: with 1 in 4 / 1 in 16 the map
        # was too coarse for the blur model (egs on `demo` 1.30 -> 0.52 cm, monogs 1.57 -> 1.29).
        pcd_downsample_init=2,
        pcd_downsample=8,
        edge_blocks=16,
        lr_colors=0.01,
        lr_opacity=0.05,
        lr_means=0.002,
        lr_scales=0.01,
    )


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
    """``["lambda_d=0.05", "crf=srgb", "theta=null"]`` -> ``{"lambda_d": 0.05, ...}``.

    Values are read as YAML scalars (numbers, true/false, null, strings); keys must be
    :class:`SlamConfig` fields.

    Raises:
        ConfigError: an item without ``=``, an unknown key, or a value of the wrong type.
    """
    import yaml

    kinds = {f.name: str(f.type) for f in dataclasses.fields(SlamConfig)}
    out: dict[str, Any] = {}
    for item in items:
        key, sep, raw = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ConfigError(f"option override {item!r} is not KEY=VALUE")
        if key not in kinds:
            raise ConfigError(f"unknown SLAM option {key!r} in {item!r}")
        out[key] = _typed(key, kinds[key], yaml.safe_load(raw) if raw.strip() else None)
    return out


def _typed(key: str, kind: str, value: Any) -> Any:
    """``value`` checked against the field's annotation (``float``, ``int | None``, ...)."""
    base, _, rest = kind.partition(" | ")
    if value is None and rest == "None":
        return None
    ok = {"float": isinstance(value, (int, float)) and not isinstance(value, bool),
          "int": isinstance(value, int) and not isinstance(value, bool),
          "bool": isinstance(value, bool), "str": isinstance(value, str)}.get(base)
    if ok is None:
        raise ConfigError(f"SLAM option {key!r} ({kind}) cannot be set from the command line")
    if not ok:
        raise ConfigError(f"SLAM option {key!r} needs a {kind} value, got {value!r}")
    return float(value) if base == "float" else value

