"""The method registry: what ``egs-bench run`` can run, independent of how a method works.

A method is any object with a ``name``, a one-line ``description`` and
``run(sequence, out, *, preset, device, seed, max_frames, progress) -> RunFolder`` that writes
a run folder (:mod:`egs_bench.runs.folder`, created with :meth:`RunFolder.create`, which takes
the folder's lock and refuses to replace an existing run). Methods that also accept
``overwrite: bool`` support ``egs-bench run --overwrite``. The built-in SLAM methods register
themselves from :mod:`egs_bench.slam.methods`; users add methods by

* an entry point in the group ``egs_bench.methods`` (value: a method object, or a callable
  returning one), e.g. in ``pyproject.toml``::

      [project.entry-points."egs_bench.methods"]
      my-slam = "my_pkg.slam:METHOD"

* an import path given instead of a name: ``--method my_pkg.slam:METHOD``;
* :func:`register_method` from Python.
"""

from __future__ import annotations

import importlib
import inspect
from importlib.metadata import entry_points
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

from egs_bench.errors import ConfigError

if TYPE_CHECKING:
    from egs_bench.datasets.sequence import Sequence
    from egs_bench.runs.folder import RunFolder

ENTRY_POINT_GROUP = "egs_bench.methods"

# Modules whose import registers the built-in methods (kept as names so that importing the
# registry does not import torch).
_BUILTIN_MODULES = ("egs_bench.slam.methods", "egs_bench.baselines.monogs_edi")


@runtime_checkable
class Method(Protocol):
    """What ``egs-bench run`` needs from a method."""

    name: str
    description: str

    def run(self, sequence: Sequence, out: Path, *, preset: str = "auto", device: str = "auto",
            seed: int = 0, max_frames: int | None = None, progress: bool = True) -> RunFolder:
        """Process ``sequence`` and write a complete run folder at ``out``.

        Methods may also accept ``overwrite: bool = False`` (passed on to
        :meth:`RunFolder.create`); ``egs-bench run --overwrite`` needs it.
        """
        ...


_BUILTIN: dict[str, Method] = {}
_USER: dict[str, Method] = {}


def register_builtin(method: Method) -> None:
    """Register a method shipped with egs-bench (called by the modules in ``_BUILTIN_MODULES``)."""
    _BUILTIN[method.name] = method


def register_method(method: Method) -> None:
    """Register a method object under ``method.name`` (overrides entry points of that name)."""
    if not isinstance(method, Method):
        raise ConfigError(f"{method!r} is not a method (needs name, description and run())")
    _USER[method.name] = method


def builtin_methods() -> dict[str, Method]:
    """The methods shipped with egs-bench, by name."""
    for module in _BUILTIN_MODULES:
        importlib.import_module(module)
    return dict(_BUILTIN)


def _instantiate(obj: Any, origin: str) -> Method:
    # Only a class or a Python function written to return a method is called: a builtin
    # named on the command line (os:system) would run with unchecked effects.
    if not isinstance(obj, Method) and (isinstance(obj, type) or inspect.isfunction(obj)):
        try:
            obj = obj()
        except TypeError as exc:
            raise ConfigError(f"{origin}: cannot create the method without arguments "
                              f"({exc})") from None
    if not isinstance(obj, Method):
        raise ConfigError(f"{origin} does not provide a method (name, description, run())")
    return obj


def _entry_point_methods() -> dict[str, Any]:
    return {ep.name: ep for ep in entry_points(group=ENTRY_POINT_GROUP)}


def available_methods() -> dict[str, str]:
    """Method names -> descriptions (built-in, registered and entry points)."""
    out = {name: m.description for name, m in builtin_methods().items()}
    for name, ep in _entry_point_methods().items():
        out.setdefault(name, f"(plugin {ep.value})")
    for name, m in _USER.items():
        out[name] = m.description
    return out


def get_method(name: str) -> Method:
    """Resolve a method by name, or by import path ``module:attribute``."""
    if name in _USER:
        return _USER[name]
    builtin = builtin_methods()
    if name in builtin:
        return builtin[name]
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


def supports_overwrite(method: Method) -> bool:
    """Whether ``method.run`` accepts ``overwrite`` (needed by ``egs-bench run --overwrite``)."""

    try:
        params = inspect.signature(method.run).parameters
    except (TypeError, ValueError):
        return False
    return "overwrite" in params or any(p.kind is p.VAR_KEYWORD for p in params.values())


def with_options(method: Method, options: dict[str, Any]) -> Method:
    """``method`` with configuration fields overridden (``--set``, a sweep's ``set``).

    Raises:
        ConfigError: ``options`` given for a method that has no configuration fields (one
            without ``with_options``, e.g. a user method with its own ``run``).
    """
    if not options:
        return method
    configure = getattr(method, "with_options", None)
    if configure is None:
        raise ConfigError(f"--set applies to methods with a SLAM configuration; {method.name!r} "
                          "has none")
    return configure(options)


def describe_run(method: Method, sequence: Sequence, *, preset: str, device: str,
                 seed: int) -> str:
    """The first line ``egs-bench run`` prints: what the method says it will do
    (``describe``), or its name, the requested preset and device and the seed."""
    describe = getattr(method, "describe", None)
    if callable(describe):
        return str(describe(sequence, preset=preset, device=device, seed=seed))
    return f"{method.name} on {sequence.name}: preset {preset}, device {device}, seed {seed}"
