"""A run's configuration next to its method's preset: which values a study changed.

A built-in method's run stores its resolved SLAM configuration (``config.yaml``: ``method``,
``preset``, ``seed``, ``device``, ``frames``, ``slam: {group: {field: value}}``). The baseline
is what the same method gives with the same preset on the same sequence and no options
(:meth:`egs_bench.slam.methods.ConfiguredSlamMethod.config`); a value that differs from it was
set by ``--set`` or a sweep's ``set`` / ``settings``. Other methods (imports, plugins) have no
preset to compare with: their rows are listed without a baseline.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from egs_bench.errors import EgsBenchError
from egs_bench.eval.results import flatten

_MISSING = object()


@dataclass(frozen=True)
class ConfigRow:
    """One configuration value.

    Attributes:
        key: dotted key (``slam.loss.lambda_d``).
        value: the run's value.
        preset: the method's preset value (``None`` when there is no baseline or the key is
            not part of it; see ``compared``).
        compared: the key has a baseline value.
        changed: compared and different from the baseline.
    """

    key: str
    value: Any
    preset: Any = None
    compared: bool = False
    changed: bool = False


def preset_baseline(method: str, preset: str | None, meta: Mapping[str, Any] | None
                    ) -> dict[str, Any] | None:
    """The flattened ``slam.*`` configuration of built-in ``method`` under ``preset`` for a
    sequence with ``meta`` (its ``meta.yaml``); ``None`` when ``method`` is not a built-in
    SLAM method or ``preset`` is unknown."""
    from egs_bench.runs.registry import builtin_methods
    from egs_bench.slam.methods import ConfiguredSlamMethod

    found = builtin_methods().get(method)
    if not isinstance(found, ConfiguredSlamMethod) or not isinstance(preset, str):
        return None
    try:
        config = found.config(preset, dict(meta or {}))
    except EgsBenchError:
        return None
    return flatten({"slam": config.to_dict()})


def config_rows(config: Mapping[str, Any], baseline: Mapping[str, Any] | None
                ) -> list[ConfigRow]:
    """Every flattened key of ``config`` with its baseline value and whether it changed.

    Values compare as stored: a YAML round trip keeps ints, floats, strings, lists and
    booleans, so equal values compare equal.
    """
    rows = []
    for key, value in flatten(config).items():
        base = _MISSING if baseline is None else baseline.get(key, _MISSING)
        if base is _MISSING:
            rows.append(ConfigRow(key, value))
        else:
            rows.append(ConfigRow(key, value, base, True, _differs(value, base)))
    return rows


def _differs(value: Any, base: Any) -> bool:
    if isinstance(value, list | tuple) and isinstance(base, list | tuple):
        return len(value) != len(base) or any(_differs(a, b) for a, b in zip(value, base,
                                                                               strict=True))
    if isinstance(value, bool) or isinstance(base, bool):
        return value is not base
    if isinstance(value, int | float) and isinstance(base, int | float):
        return float(value) != float(base)
    return value != base
