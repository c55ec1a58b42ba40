"""The built-in SLAM methods: EGS-SLAM, its ablations and the MonoGS-style baseline.

Each is a configuration of the one SLAM system (:class:`ConfiguredSlamMethod`), registered in
:mod:`egs_bench.runs.registry` on import.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Self

from egs_bench.runs.registry import register_builtin

if TYPE_CHECKING:
    from egs_bench.datasets.sequence import Sequence
    from egs_bench.runs.folder import RunFolder
    from egs_bench.slam.components import SlamComponents
    from egs_bench.slam.config import SlamConfig


@dataclass
class ConfiguredSlamMethod:
    """A built-in method: the SLAM system with ``overrides`` applied on top of a preset.

    Attributes:
        overrides: the method's own configuration fields (what makes it this method).
        options: further fields set for one study (``--set``, a sweep's ``set``), applied
            after ``overrides``; see :meth:`with_options`.
        components: the tracker, mapper and keyframe policy (None: the built-in ones); a
            method with its own components is how a researcher plugs in a new part
            (:mod:`egs_bench.slam.components`).
    """

    name: str
    description: str
    overrides: dict[str, Any] = field(default_factory=dict)
    options: dict[str, Any] = field(default_factory=dict)
    components: SlamComponents | None = None

    def config(self, preset: str = "paper", meta: dict[str, Any] | None = None) -> SlamConfig:
        """The preset, then what the sequence's ``meta`` implies (real data: the paper's
        real-data values), then this method's own overrides, then its options."""
        from egs_bench.slam.config import preset as make_preset
        from egs_bench.slam.sequence_defaults import sequence_slam_defaults

        base = make_preset(preset).with_groups(self.config_classes())
        base = base.replace(**sequence_slam_defaults(meta or {}))
        return base.replace(**self.overrides).validate().replace(**self.options).validate()

    def config_classes(self) -> dict[str, type]:
        """By configuration group, the config class of the part that reads it (a component's
        own config adds fields to its group; :meth:`SlamComponents.config_classes`)."""
        from egs_bench.slam.components import SlamComponents

        return (self.components or SlamComponents()).config_classes()

    def with_options(self, options: dict[str, Any]) -> Self:
        """This method with single configuration fields overridden on top of the preset and
        its own settings (sensitivity studies; stored in the run folder's resolved
        configuration)."""
        return dataclasses.replace(self, options={**self.options, **options})

    def describe(self, sequence: Sequence, *, preset: str = "auto", device: str = "auto",
                 seed: int = 0) -> str:
        """One line saying what :meth:`run` with these arguments will do: the method, the
        preset and device ``auto`` resolves to, the processing resolution (and its share of
        the sequence's) and the seed."""
        from egs_bench.slam.config import resolve_device, resolve_preset
        from egs_bench.slam.frames import internal_intrinsics

        device = resolve_device(device)
        preset = resolve_preset(preset, device)
        cfg = self.config(preset, sequence.meta)
        full = sequence.intrinsics
        cam = internal_intrinsics(full, cfg.budget.resolution_scale)
        size = f"{cam.width}x{cam.height}"
        if (cam.width, cam.height) != (full.width, full.height):
            size += f" (reduced from the sequence's {full.width}x{full.height})"
        return (f"{self.name} on {sequence.name}: preset {preset}, device {device}, "
                f"processing at {size}, seed {seed}")

    def run(self, sequence: Sequence, out: Path, *, preset: str = "auto", device: str = "auto",
            seed: int = 0, max_frames: int | None = None, progress: bool = True,
            overwrite: bool = False) -> RunFolder:
        """Run on ``sequence``; ``overwrite`` replaces an existing run folder at ``out``.
        ``device="auto"`` picks CUDA when present; ``preset="auto"`` the paper budget on CUDA
        and the cpu budget on a CPU."""
        from egs_bench.slam.config import resolve_device, resolve_preset
        from egs_bench.slam.runner import RunSettings, run_slam

        device = resolve_device(device)
        preset = resolve_preset(preset, device)
        return run_slam(sequence, out, method_name=self.name,
                        config=self.config(preset, sequence.meta),
                        settings=RunSettings(preset, device, seed, max_frames, progress,
                                             overwrite),
                        components=self.components)


def parse_method_options(method: object, items: list[str]) -> dict[str, Any]:
    """``--set`` items for ``method``, parsed and type-checked
    (:func:`~egs_bench.slam.config.parse_overrides`) against its groups: a method whose
    components declare their own config takes their fields too (``keyframes.n``)."""
    from egs_bench.slam.config import GROUPS, parse_overrides

    classes = method.config_classes() if isinstance(method, ConfiguredSlamMethod) else GROUPS
    return parse_overrides(items, classes)


def rerun(config_file: str | Path, out: str | Path | None = None, *,
          sequence: str | Path | None = None,
          method: str | None = None, progress: bool = True, overwrite: bool = False
          ) -> RunFolder:
    """Run again what a run folder's ``config.yaml`` records: the same method, preset, seed,
    device, frame count and every SLAM setting, on the same sequence (``sequence``: another
    one), into ``out`` (None: where ``egs-bench run`` puts a run without ``--out``,
    :func:`~egs_bench.runs.locations.run_location`). On the same machine the trajectory is the
    same, byte for byte (the CPU backend is deterministic).

    The method is looked up by its recorded name, or where ``method`` says (a
    ``module:attribute`` path, for a method that is not registered under its name); it must
    have the recorded name, and its components the recorded import paths, so a run made with
    other parts (an oracle's) is refused rather than re-run with the built-in ones.

    Raises:
        InputError: the file is missing or is not a SLAM run's resolved configuration.
        ConfigError: the method is unknown or not a SLAM-system method, its components differ
            from the recorded ones, or a stored setting is invalid.
        OutputError: ``out`` may not be written.
    """
    from egs_bench.datasets.registry import load_sequence
    from egs_bench.errors import ConfigError, InputError
    from egs_bench.runs.folder import CONFIG_FILE
    from egs_bench.runs.folder import RunFolder as Folder
    from egs_bench.runs.registry import get_method
    from egs_bench.slam.components import SlamComponents, fixed_parts_record
    from egs_bench.slam.config import SlamConfig
    from egs_bench.slam.runner import RunSettings, run_slam

    path = Path(config_file)
    if path.is_dir():
        path = path / CONFIG_FILE
    if not path.is_file():
        raise InputError(path, "no such file (give a run folder's config.yaml)")
    stored = Folder.open(path.parent).read_config()
    kinds = {"method": str, "preset": str, "device": str, "seed": int, "frames": int,
             "slam": dict}
    for key, kind in kinds.items():
        if not isinstance(stored.get(key), kind) or isinstance(stored.get(key), bool):
            raise InputError(path, f"'{key}' must be a {kind.__name__}: not a SLAM run's "
                                   "resolved configuration")
    found = get_method(method or stored["method"])
    if not isinstance(found, ConfiguredSlamMethod):
        raise ConfigError(f"method {found.name!r} is not configured by a SlamConfig; "
                          "only SLAM-system methods can be re-run from config.yaml")
    if found.name != stored["method"]:
        raise ConfigError(f"{path} is a run of method {stored['method']!r}, not of "
                          f"{found.name!r}")
    own = (found.components or SlamComponents()).record()
    recorded = stored.get("components")
    if isinstance(recorded, dict):
        recorded = {**fixed_parts_record(), **recorded}
    if recorded is not None and recorded != own:
        recorded = recorded if isinstance(recorded, dict) else {}
        differ = [f"{role} {_part_name(recorded.get(role))} (the method's: "
                  f"{_part_name(part)})" for role, part in own.items()
                  if recorded.get(role) != part]
        raise ConfigError(f"{path}: the run was made with other parts than method "
                          f"{found.name!r} has: {'; '.join(differ)}")
    config = SlamConfig.from_dict(stored["slam"], found.config_classes()).validate()
    source = sequence if sequence is not None else Folder.open(path.parent).sequence_path
    if source is None:
        raise InputError(path.parent, "the run names no sequence folder; give the sequence")
    seq = load_sequence(source, progress=progress)
    if out is None:
        from egs_bench.runs.locations import run_location

        out = run_location(Path(), seq.name, found.name)
    settings = RunSettings(stored["preset"], stored["device"], stored["seed"], stored["frames"],
                           progress, overwrite)
    return run_slam(seq, out, method_name=found.name, config=config, settings=settings,
                    components=found.components)


def _part_name(record: Any) -> str:
    """A recorded part in a message: its import path, or its loss terms' names."""
    if isinstance(record, str):
        return record
    if isinstance(record, dict):
        return str(record.get("target"))
    if isinstance(record, list):
        return "[" + ", ".join(str(t.get("name")) if isinstance(t, dict) else str(t)
                               for t in record) + "]"
    return "none"


_MONOGS = {
    "blur_model": False, "event_tracking": False, "event_mapping": False, "no_event_loss": False,
    "crf": "identity", "exposure_compensation": True,
    # MonoGS RGB-D loss: alpha L_rgb + (1 - alpha) L_depth with alpha = 0.95 (Replica).
    "lambda_e": 0.0, "lambda_id": 1.0, "lambda_i": 0.95, "lambda_d": 0.05,
}

BUILTIN: dict[str, ConfiguredSlamMethod] = {
    m.name: m
    for m in [
        ConfiguredSlamMethod("egs", "EGS-SLAM: blur-aware event + RGB-D tracking and mapping, "
                             "learnable CRF, no-event loss"),
        ConfiguredSlamMethod("egs-no-event-tracking", "EGS-SLAM without the event loss in "
                             "tracking", {"event_tracking": False}),
        ConfiguredSlamMethod("egs-no-event-mapping", "EGS-SLAM without the event loss in "
                             "mapping", {"event_mapping": False}),
        ConfiguredSlamMethod("egs-no-events", "blur model only (deblur SLAM on RGB-D, the "
                             "paper's no-event row)",
                             {"event_tracking": False, "event_mapping": False}),
        ConfiguredSlamMethod("egs-no-crf", "EGS-SLAM with the identity response instead of the "
                             "learnable CRF", {"crf": "identity"}),
        ConfiguredSlamMethod("egs-no-ne-loss", "EGS-SLAM without the no-event loss",
                             {"no_event_loss": False}),
        ConfiguredSlamMethod("monogs", "MonoGS-style RGB-D baseline: one pose per frame, no "
                             "events, no CRF, MonoGS losses and exposure compensation", _MONOGS),
    ]
}

for _method in BUILTIN.values():
    register_builtin(_method)
