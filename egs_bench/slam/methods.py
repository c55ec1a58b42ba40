"""Method registry: built-in EGS-SLAM variants, the MonoGS-style baseline, and user methods.

A method is any object with a ``name``, a one-line ``description`` and
``run(sequence, out, *, preset, device, seed, max_frames, progress) -> RunFolder`` that writes
a run folder (:mod:`egs_bench.eval.run_folder`). Built-in methods are configurations of the one
SLAM system (:class:`ConfiguredSlamMethod`). Users add methods by

* an entry point in the group ``egs_bench.methods`` (value: a method object, or a callable
  returning one), e.g. in ``pyproject.toml``::

      [project.entry-points."egs_bench.methods"]
      my-slam = "my_pkg.slam:METHOD"

* an import path given instead of a name: ``--method my_pkg.slam:METHOD``;
* :func:`register_method` from Python.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass, field
from importlib.metadata import entry_points
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

from egs_bench.errors import ConfigError

if TYPE_CHECKING:
    from egs_bench.datasets.sequence import Sequence
    from egs_bench.eval.run_folder import RunFolder

ENTRY_POINT_GROUP = "egs_bench.methods"


@runtime_checkable
class Method(Protocol):
    """What ``egs-bench run`` needs from a method."""

    name: str
    description: str

    def run(self, sequence: Sequence, out: Path, *, preset: str = "paper", device: str = "cpu",
            seed: int = 0, max_frames: int | None = None, progress: bool = True) -> RunFolder:
        """Process ``sequence`` and write a complete run folder at ``out``."""
        ...


@dataclass
class ConfiguredSlamMethod:
    """A built-in method: the SLAM system with ``overrides`` applied on top of a preset."""

    name: str
    description: str
    overrides: dict[str, Any] = field(default_factory=dict)

    def config(self, preset: str = "paper"):  # -> SlamConfig
        from egs_bench.slam.config import preset as make_preset

        return make_preset(preset).replace(**self.overrides).validate()

    def run(self, sequence: Sequence, out: Path, *, preset: str = "paper", device: str = "cpu",
            seed: int = 0, max_frames: int | None = None, progress: bool = True,
            options: dict[str, Any] | None = None) -> RunFolder:
        """Run on ``sequence``; ``options`` override single configuration fields on top of the
        preset and the method's own settings (sensitivity studies; stored in the run folder's
        resolved configuration)."""
        from egs_bench.slam.runner import run_slam

        config = self.config(preset).replace(**(options or {})).validate()
        return run_slam(sequence, out, method_name=self.name, config=config,
                        preset=preset, device=device, seed=seed, max_frames=max_frames,
                        progress=progress)


_MONOGS = {
    "n_segments": 1, "event_tracking": False, "event_mapping": False, "no_event_loss": False,
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

_USER: dict[str, Method] = {}


def register_method(method: Method) -> None:
    """Register a method object under ``method.name`` (overrides entry points of that name)."""
    if not isinstance(method, Method):
        raise ConfigError(f"{method!r} is not a method (needs name, description and run())")
    _USER[method.name] = method


def _instantiate(obj: Any, origin: str) -> Method:
    if not isinstance(obj, Method) and isinstance(obj, Callable):
        obj = obj()
    if not isinstance(obj, Method):
        raise ConfigError(f"{origin} does not provide a method (name, description, run())")
    return obj


def _entry_point_methods() -> dict[str, Any]:
    return {ep.name: ep for ep in entry_points(group=ENTRY_POINT_GROUP)}


def available_methods() -> dict[str, str]:
    """Method names -> descriptions (built-in, registered and entry points)."""
    out = {name: m.description for name, m in BUILTIN.items()}
    for name, ep in _entry_point_methods().items():
        out.setdefault(name, f"(plugin {ep.value})")
    for name, m in _USER.items():
        out[name] = m.description
    return out


def get_method(name: str) -> Method:
    """Resolve a method by name, or by import path ``module:attribute``."""
    if name in _USER:
        return _USER[name]
    if name in BUILTIN:
        return BUILTIN[name]
    eps = _entry_point_methods()
    if name in eps:
        try:
            obj = eps[name].load()
        except Exception as exc:  # a broken plugin must not crash with a deep traceback
            raise ConfigError(f"method plugin {name!r} ({eps[name].value}) failed to load: "
                              f"{exc}") from exc
        return _instantiate(obj, f"entry point {name!r}")
    if ":" in name:
        module_name, _, attr = name.partition(":")
        try:
            obj = getattr(importlib.import_module(module_name), attr)
        except (ImportError, AttributeError) as exc:
            raise ConfigError(f"cannot import method {name!r}: {exc}") from exc
        return _instantiate(obj, name)
    raise ConfigError(f"unknown method {name!r}; available: {', '.join(available_methods())} "
                      "(or give an import path module:attribute)")
