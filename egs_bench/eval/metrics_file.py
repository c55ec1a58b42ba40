"""A run's ``metrics.json`` read back into a typed, validated :class:`RunMetrics`.

:func:`egs_bench.eval.evaluate.evaluate_run` writes the file (docs/design.md §7). Everything
that reads it (result tables, sweep summaries and decisions, benchmarks) goes through
:func:`read_metrics`, or :func:`parse_metrics` for the mapping ``evaluate_run`` returns.

Layout (top-level keys; ``per_frame`` lists and the other details stay in the sections)::

    schema_version  int
    run             {method, sequence, status}
    protocol        the protocol's settings, with its ``name``      (required)
    tools           {distribution: version}
    ate             {rmse_m, ..., per_pose}                          (required)
    rpe             {per_frame, per_metre, ...}    absent in files before RPE was scored
    rendering       {psnr_db, ssim, lpips, ..., per_frame}   null: no renders scored
    speed           {fps, total_wall_s, frames, render_fps, compile_s, init_s,
                    fps_after_init}  null: no timing.json (fps excludes compile_s)
    coverage        {frames_processed, frames_in_sequence}   null: no sequence; absent in
                                                             files before coverage existed
    notes           [str]

Units are as stored: ATE in metres, PSNR in dB. JSON has no NaN or infinity: a number that
was not finite is stored as ``null`` (and a non-finite number in the file reads as ``None``).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from egs_bench.errors import InputError
from egs_bench.fileio import read_text
from egs_bench.runs.folder import METRICS_FILE

METRICS_SCHEMA_VERSION = 1


@dataclass(frozen=True)
class RpeSummary:
    """The RPE RMSEs of one pair spacing (per frame or per metre of path).

    Attributes:
        translation_m: RMSE of the relative translation error, metres.
        rotation_deg: RMSE of the relative rotation angle, degrees.
        n_pairs: relative-pose pairs scored.
    """

    translation_m: float | None
    rotation_deg: float | None
    n_pairs: int


@dataclass(frozen=True)
class RunMetrics:
    """The content of one ``metrics.json``.

    Attributes:
        protocol: the name of the protocol the numbers are under (``egs``, ``monogs``).
        ate_rmse_m: ATE RMSE [m] (None when not finite).
        psnr_db, ssim, lpips: mean image metrics of the scored renders (None when not
            computed, e.g. no renders, no sharp ground truth, no LPIPS weights).
        fps, render_fps: the method's frames per second and renders per second (None
            without ``timing.json``).
        fps_after_init, init_s: frames per second without frame 0, and frame 0's seconds
            (the map's initialisation); None in files written before the split.
        ate_poses: the pose pairs the ATE associated (None when the file does not say).
        renders_scored: the renders the image metrics average (None without renders).
        rpe_per_frame, rpe_per_metre: the RPE of consecutive frames and of 1 m of path (None
            in files without RPE, or where the trajectory has no such pair).
        frames_processed, frames_in_sequence: the frames the run covers, of how many (None
            without a sequence, or in files that predate coverage).
        method, sequence, status: the run's identity and state when it was evaluated (None
            when the file does not say).
        schema_version: the file's layout version (None when the file does not say).
        notes: what the numbers do not cover, one sentence each.
        tools: the versions of the tools that computed the numbers.
        protocol_settings: the whole protocol as recorded (``Protocol.to_dict()``).
        ate, rpe, rendering, speed: the sections as written, details and per-frame lists
            included (``rpe``, ``rendering``, ``speed`` are None when absent or null).
    """

    protocol: str
    ate_rmse_m: float | None
    psnr_db: float | None
    ssim: float | None
    lpips: float | None
    fps: float | None
    render_fps: float | None
    frames_processed: int | None
    frames_in_sequence: int | None
    method: str | None
    sequence: str | None
    status: str | None
    schema_version: int | None
    notes: tuple[str, ...]
    tools: Mapping[str, str]
    protocol_settings: Mapping[str, Any]
    ate: Mapping[str, Any]
    rpe: Mapping[str, Any] | None
    rendering: Mapping[str, Any] | None
    speed: Mapping[str, Any] | None
    fps_after_init: float | None = None
    init_s: float | None = None
    ate_poses: int | None = None
    renders_scored: int | None = None
    rpe_per_frame: RpeSummary | None = None
    rpe_per_metre: RpeSummary | None = None


def read_metrics(run_dir: str | Path) -> RunMetrics:
    """Read and validate ``<run_dir>/metrics.json``.

    Raises:
        InputError: naming the file: missing, not UTF-8 JSON, or a field missing or of the
            wrong type.
    """
    path = Path(run_dir) / METRICS_FILE
    if not path.is_file():
        raise InputError(path, "not found (run `egs-bench eval` first)")
    try:
        data = json.loads(read_text(path))
    except json.JSONDecodeError as exc:
        raise InputError(path, f"not valid JSON ({exc})") from None
    return parse_metrics(data, path)


def parse_metrics(data: Any, where: Path) -> RunMetrics:
    """Validate the decoded content of a ``metrics.json`` (or what ``evaluate_run`` returns).

    Raises:
        InputError: naming ``where``: a required section is missing, or a field has the wrong
            type.
    """
    if not isinstance(data, Mapping) or "protocol" not in data or "ate" not in data:
        raise InputError(where, "not an egs-bench metrics file (no 'protocol'/'ate')")
    protocol = data["protocol"]
    if not isinstance(protocol, Mapping) or not isinstance(protocol.get("name"), str):
        raise InputError(where, "'protocol' must be a mapping with a 'name'")
    ate = _section(data, "ate", "rmse_m", where)
    if ate is None:
        raise InputError(where, "'ate' must be a mapping with 'rmse_m', found None")
    ate_rmse_m = _number(ate, "rmse_m", where)
    rendering = _section(data, "rendering", "psnr_db", where)
    psnr_db, ssim, lpips = (_number(rendering, k, where) for k in ("psnr_db", "ssim", "lpips"))
    speed = _section(data, "speed", "fps", where)
    fps, render_fps, fps_after_init, init_s = (
        _number(speed, k, where) for k in ("fps", "render_fps", "fps_after_init", "init_s"))
    done, total = _coverage(data.get("coverage"), where)
    run = data.get("run") or {}
    if not isinstance(run, Mapping):
        raise InputError(where, "'run' must be a mapping")
    rpe = data.get("rpe")
    if rpe is not None and not isinstance(rpe, Mapping):
        raise InputError(where, "'rpe' must be a mapping")
    tools = data.get("tools") or {}
    if not isinstance(tools, Mapping) or not all(isinstance(v, str) for v in tools.values()):
        raise InputError(where, "'tools' must map tool names to version strings")
    notes = data.get("notes") or []
    if not isinstance(notes, list) or not all(isinstance(n, str) for n in notes):
        raise InputError(where, "'notes' must be a list of strings")
    version = data.get("schema_version")
    if version is not None and not _is_int(version):
        raise InputError(where, f"'schema_version' must be an integer, found {version!r}")
    return RunMetrics(
        protocol=protocol["name"],
        ate_rmse_m=ate_rmse_m, psnr_db=psnr_db, ssim=ssim, lpips=lpips, fps=fps,
        render_fps=render_fps, frames_processed=done, frames_in_sequence=total,
        method=_text(run, "method", where), sequence=_text(run, "sequence", where),
        status=_text(run, "status", where),
        schema_version=version, notes=tuple(notes), tools=tools, protocol_settings=protocol,
        ate=ate, rpe=rpe, rendering=rendering, speed=speed, fps_after_init=fps_after_init,
        init_s=init_s, ate_poses=_count(ate, "n_matched", where),
        renders_scored=_count(rendering, "n_frames", where),
        rpe_per_frame=_rpe(rpe, "per_frame", where), rpe_per_metre=_rpe(rpe, "per_metre", where))


def _is_int(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _section(data: Mapping[str, Any], name: str, key: str, where: Path
             ) -> Mapping[str, Any] | None:
    """Section ``name`` of ``data``: a mapping, or None when absent or null."""
    section = data.get(name)
    if section is not None and not isinstance(section, Mapping):
        raise InputError(where, f"expected a mapping with {key!r}, found "
                                f"{type(section).__name__}")
    return section


def _number(section: Mapping[str, Any] | None, key: str, where: Path) -> float | None:
    """``section[key]`` as a float; None when the section or the value is absent, null or not
    finite."""
    value = None if section is None else section.get(key)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InputError(where, f"{key!r} must be a number, found {value!r}")
    return float(value) if math.isfinite(value) else None


def _count(section: Mapping[str, Any] | None, key: str, where: Path) -> int | None:
    """``section[key]`` as a non-negative integer; None when the section or value is absent."""
    value = None if section is None else section.get(key)
    if value is None:
        return None
    if not _is_int(value) or value < 0:
        raise InputError(where, f"{key!r} must be a non-negative integer, found {value!r}")
    return int(value)


def _rpe(rpe: Mapping[str, Any] | None, spacing: str, where: Path) -> RpeSummary | None:
    """The translation and rotation RMSE of ``rpe[spacing]``; None when the file has no RPE or
    no pair at that spacing (``translation`` null, with a note)."""
    entry = None if rpe is None else rpe.get(spacing)
    if entry is None:
        return None
    if not isinstance(entry, Mapping):
        raise InputError(where, f"'rpe.{spacing}' must be a mapping")
    translation = _section(entry, "translation", "rmse", where)
    rotation = _section(entry, "rotation", "rmse", where)
    if translation is None or rotation is None:
        return None
    n_pairs = _count(translation, "n_pairs", where)
    if n_pairs is None:
        raise InputError(where, f"'rpe.{spacing}.translation' needs 'n_pairs'")
    return RpeSummary(_number(translation, "rmse", where), _number(rotation, "rmse", where),
                      n_pairs)


def _text(section: Mapping[str, Any], key: str, where: Path) -> str | None:
    value = section.get(key)
    if value is not None and not isinstance(value, str):
        raise InputError(where, f"{key!r} must be a string, found {value!r}")
    return value


def _coverage(cov: Any, where: Path) -> tuple[int | None, int | None]:
    if cov is None:
        return None, None
    if not isinstance(cov, Mapping):
        raise InputError(where, "'coverage' must be a mapping")
    done, total = cov.get("frames_processed"), cov.get("frames_in_sequence")
    if not (_is_int(done) and _is_int(total)):
        raise InputError(where, "'coverage' needs integer frames_processed / frames_in_sequence")
    return done, total
