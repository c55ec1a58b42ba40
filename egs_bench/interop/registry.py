"""The one registry of external systems: every system egs-bench exports to or imports from.

A new system is one module (``interop/<system>.py``, defining its reader and camera files and
``SYSTEM = ExternalSystem(...)``, see :mod:`egs_bench.interop.systems`) plus one entry in
:data:`SYSTEMS` (or, from outside the package, one :func:`register_system` call). Exports write
the camera files of every system that reads their layout, in this order; ``import-run --from
KEY`` reads with the system's reader, and the command line lists every system here, the
registered ones included, in its choices and help (read when a command needs them, so that
importing the CLI does not import this module). There is no entry-point group for systems:
a package adds its system by calling :func:`register_system` before the command runs.
"""

from __future__ import annotations

from egs_bench.errors import ConfigError
from egs_bench.interop import monogs, nice_slam, orbslam2, photoslam, rampvo
from egs_bench.interop.systems import ExternalSystem

#: the built-in systems, in the order an export lists their camera files
SYSTEMS: tuple[ExternalSystem, ...] = (
    monogs.SYSTEM,
    orbslam2.SYSTEM,
    photoslam.SYSTEM,
    nice_slam.SYSTEM,
    rampvo.SYSTEM,
)
#: ``import-run --from`` for a plain TUM trajectory (no system's own files)
TUM = "tum"

_REGISTERED: dict[str, ExternalSystem] = {}


def register_system(system: ExternalSystem) -> None:
    """Add ``system`` to the registry (after the built-in ones; replaces a system registered
    before under the same key).

    Raises:
        ConfigError: its key is a built-in system's or ``tum``.
    """
    if system.key == TUM or any(s.key == system.key for s in SYSTEMS):
        raise ConfigError(f"{system.key!r} is a built-in import format; choose another key")
    _REGISTERED[system.key] = system


def all_systems() -> tuple[ExternalSystem, ...]:
    """The built-in systems, then the registered ones."""
    return SYSTEMS + tuple(_REGISTERED.values())


def importable_systems() -> tuple[ExternalSystem, ...]:
    """The systems ``import-run --from KEY`` reads (those with a reader), in registry order."""
    return tuple(s for s in all_systems() if s.read is not None)


def import_formats() -> tuple[str, ...]:
    """What ``import-run --from`` takes: ``tum``, then the key of every system with a reader,
    built-in then registered, in registry order."""
    return (TUM, *(s.key for s in importable_systems()))


def systems_reading(layout: str) -> list[ExternalSystem]:
    """The systems with a camera file for the export ``layout``, in registry order."""
    return [s for s in all_systems() if layout in s.camera_files]


def importable_system(key: str) -> ExternalSystem:
    """The system ``import-run --from key`` reads (``tum`` is read apart, by
    :func:`egs_bench.interop.importing.import_tum_run`).

    Raises:
        ConfigError: no system of that key has a reader.
    """
    for system in importable_systems():
        if system.key == key:
            return system
    raise ConfigError(f"unknown import format {key!r}; choose one of "
                      f"{', '.join(import_formats())}")
