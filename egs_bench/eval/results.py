"""Per-run results of a folder of run folders: one robust record per run, never an abort.

Leaderboards, paper tables, regression checks and sweep summaries all start from
:func:`collect_results`. Each run folder becomes one :class:`RunResult` with its identity
(method, sequence, seed, settings), a status and its metric values; a folder that cannot be read
(binary or malformed ``run.yaml`` / ``status.json`` / ``trajectory.txt``, a wrongly typed
``metrics.json``) becomes a result with status ``broken`` and a reason naming the file, so one
bad folder never hides the others.

Statuses (``RunResult.status``):

=================  =====================================================================
``ok``             finished, evaluated, covers every frame of its sequence
``incomplete``     finished and evaluated, but covers fewer frames than the sequence
``tracking_lost``  the method reported a tracking loss (tables show ``L``)
``failed``         the method failed (crash, time limit, interruption)
``running``        not finished (still running, or killed without a final status)
``not_evaluated``  finished, but no metrics under the requested protocol and evaluation was off
``broken``         a file of the run folder is unreadable or malformed
=================  =====================================================================

Metric values are stored in the units of ``metrics.json`` (ATE in metres, PSNR in dB).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from egs_bench.errors import EgsBenchError, InputError, reraise_interruption
from egs_bench.eval.metrics_file import RunMetrics, parse_metrics, read_metrics
from egs_bench.eval.protocols import DEFAULT_PROTOCOL, get_protocol
from egs_bench.runs.folder import (
    CONFIG_FILE,
    KEYFRAMES_FILE,
    METRICS_FILE,
    RUN_FILE,
    STATUS_FILE,
    TIMING_FILE,
    TRAJECTORY_FILE,
    RunFolder,
    find_runs,
)

STATUSES = ("ok", "incomplete", "tracking_lost", "failed", "running", "not_evaluated", "broken")
#: Statuses whose metric values are meaningful (``incomplete`` only over the frames it covers).
EVALUATED = ("ok", "incomplete")
#: Written by ``egs-bench sweep`` next to the method's files (see :mod:`egs_bench.experiments`).
SWEEP_RECORD_FILE = "sweep.json"
#: Configuration keys that do not define the settings of a run: the seed varies inside a
#: group, ``frames`` follows the sequence length (coverage is tracked separately), and the
#: method is already the row.
NON_SETTINGS_KEYS = ("seed", "frames", "method")
_TEXT_FILES = (RUN_FILE, STATUS_FILE, CONFIG_FILE, TRAJECTORY_FILE, KEYFRAMES_FILE, TIMING_FILE,
               METRICS_FILE, SWEEP_RECORD_FILE)


@dataclass(frozen=True)
class MetricSpec:
    """A metric of the result tables.

    Attributes:
        key: short name (``ate``, ``psnr``, ...).
        column: CSV column name with its unit (the value as stored, e.g. ``ate_rmse_m``).
        label: table header with the displayed unit.
        scale: factor from the stored value to the displayed one (ATE: metres -> cm).
        higher_is_better: direction of "better".
        decimals: displayed decimals (ranks use the displayed, rounded values).
    """

    key: str
    column: str
    label: str
    scale: float
    higher_is_better: bool
    decimals: int


METRICS: dict[str, MetricSpec] = {
    "ate": MetricSpec("ate", "ate_rmse_m", "ATE [cm]", 100.0, False, 2),
    "psnr": MetricSpec("psnr", "psnr_db", "PSNR [dB]", 1.0, True, 2),
    "ssim": MetricSpec("ssim", "ssim", "SSIM", 1.0, True, 3),
    "lpips": MetricSpec("lpips", "lpips", "LPIPS", 1.0, False, 3),
    "fps": MetricSpec("fps", "fps", "FPS", 1.0, True, 2),
    "render_fps": MetricSpec("render_fps", "render_fps", "Render FPS", 1.0, True, 1),
    # the SLAM loop's speed without frame 0 (the map's initialisation), and frame 0's seconds:
    # `fps` already leaves out the kernels' compilation (timing.json's compile_s)
    "fps_after_init": MetricSpec("fps_after_init", "fps_after_init", "FPS after frame 0", 1.0,
                                 True, 2),
    "init_s": MetricSpec("init_s", "init_s", "Frame 0 [s]", 1.0, False, 1),
}
DEFAULT_METRICS = ("ate", "psnr", "ssim", "lpips")


@dataclass(frozen=True)
class RunResult:
    """One run folder's identity, status and metric values.

    Attributes:
        path: the run folder.
        rel: its path relative to the collected root (for messages).
        method, sequence: names from ``run.yaml`` (``None`` when ``run.yaml`` is unreadable).
        seed: the run's seed from ``config.yaml`` or the sweep record, if known.
        settings: the run's flattened configuration without the seed, frame count and method
            (``{"preset": "cpu", "slam.lambda_d": 0.1, ...}``); runs with equal settings are
            repeats of one experiment.
        settings_key: 10-hex-digit hash of ``settings``.
        settings_name: a name given to the settings by a sweep (``None`` otherwise).
        status: one of :data:`STATUSES`.
        reason: why the run is not ``ok`` (one line, names the file when a file is at fault).
        values: metric key -> value in the stored unit (ATE metres, PSNR dB, ...).
        frames_processed, frames_in_sequence: coverage from evaluation (``None`` if unknown).
        code_revision: ``{"commit", "modified"}`` of the code that wrote the run
            (:attr:`RunFolder.code_revision`; ``None`` when not recorded).
    """

    path: Path
    rel: str
    method: str | None
    sequence: str | None
    seed: int | None = None
    settings: dict[str, Any] = field(default_factory=dict)
    settings_key: str = ""
    settings_name: str | None = None
    status: str = "broken"
    reason: str | None = None
    values: dict[str, float] = field(default_factory=dict)
    frames_processed: int | None = None
    frames_in_sequence: int | None = None
    code_revision: dict[str, Any] | None = None

    @property
    def settings_known(self) -> bool:
        """Whether the settings were read: a run whose ``config.yaml`` (or a file read before
        it) is unreadable has none, and must not make the other runs' settings differ."""
        return bool(self.settings_key)

    @property
    def complete(self) -> bool:
        """Covers every frame of its sequence (or the coverage is unknown, e.g. imports)."""
        if self.frames_processed is None or self.frames_in_sequence is None:
            return True
        return self.frames_processed >= self.frames_in_sequence


@dataclass
class ResultSet:
    """All runs found under ``root`` and the protocol their metrics were taken under."""

    root: Path
    runs: list[RunResult]
    protocol: str = DEFAULT_PROTOCOL


def flatten(data: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """``{"a": {"b": 1}}`` -> ``{"a.b": 1}`` (lists are kept as values)."""
    out: dict[str, Any] = {}
    for key, value in data.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            out.update(flatten(value, name + "."))
        else:
            out[name] = value
    return out


def settings_of(config: Mapping[str, Any]) -> dict[str, Any]:
    """The settings that define an experiment: the flattened config without the seed etc."""
    return {k: v for k, v in sorted(flatten(config).items())
            if k.split(".", 1)[0] not in NON_SETTINGS_KEYS}


def settings_hash(settings: Mapping[str, Any]) -> str:
    """Short stable hash of a settings mapping (canonical JSON, sha256, 10 hex digits)."""
    text = json.dumps(settings, sort_keys=True, default=str, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:10]


def _check_text_files(run_dir: Path, names: tuple[str, ...]) -> None:
    """Raise :class:`InputError` naming the first of ``names`` that is not UTF-8 text."""
    for name in names:
        path = run_dir / name
        if path.is_file():
            try:
                path.read_bytes().decode("utf-8")
            except UnicodeDecodeError:
                raise InputError(path, "not a text file (binary content)") from None


def metric_values(metrics: RunMetrics) -> dict[str, float]:
    """Metric key of :data:`METRICS` -> value (stored unit), for the metrics a run has."""
    out = {"ate": metrics.ate_rmse_m, "psnr": metrics.psnr_db, "ssim": metrics.ssim,
           "lpips": metrics.lpips, "fps": metrics.fps, "render_fps": metrics.render_fps,
           "fps_after_init": metrics.fps_after_init, "init_s": metrics.init_s}
    return {k: v for k, v in out.items() if v is not None}


def _read_sweep_record(run_dir: Path) -> dict[str, Any]:
    path = run_dir / SWEEP_RECORD_FILE
    if not path.is_file():
        return {}
    try:
        data = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError):
        return {}
    return data if isinstance(data, dict) else {}


def _load_metrics(run: RunFolder, protocol: str, evaluate_missing: bool) -> RunMetrics | None:
    """The run's metrics under ``protocol`` (evaluated if needed), ``None`` if not available."""
    from egs_bench.eval.evaluate import evaluate_run

    data = None
    if run.metrics_path.is_file():
        data = read_metrics(run.path)
        if data.protocol != protocol:
            data = None
    if data is None and evaluate_missing:
        # another protocol's metrics.json is left alone; a missing one is written
        data = parse_metrics(evaluate_run(run.path, protocol,
                                          write=not run.metrics_path.is_file()),
                             run.metrics_path)
    return data


def read_run_result(path: Path, root: Path, protocol: str = DEFAULT_PROTOCOL,
                    evaluate_missing: bool = True) -> RunResult:
    """Read one run folder into a :class:`RunResult`; never raises for a bad folder."""
    rel = str(path.relative_to(root)) if path != root else path.name
    base: dict[str, Any] = {"path": path, "rel": rel, "method": None, "sequence": None}
    try:
        _check_text_files(path, (RUN_FILE,))
        run = RunFolder.open(path)
    except (EgsBenchError, OSError, ValueError) as exc:
        return RunResult(**base, status="broken", reason=str(exc))
    base.update(method=run.method, sequence=run.sequence_name, code_revision=run.code_revision)
    # the settings first: another broken file of the run (status.json) keeps them known
    try:
        _check_text_files(path, (CONFIG_FILE, SWEEP_RECORD_FILE))
        record = _read_sweep_record(path)
        config = run.read_config() if (path / CONFIG_FILE).is_file() else {}
    except (EgsBenchError, OSError, ValueError) as exc:
        return RunResult(**base, status="broken", reason=str(exc))
    seed = config.get("seed", record.get("seed"))
    settings = settings_of(config)
    base.update(seed=seed if isinstance(seed, int) and not isinstance(seed, bool) else None,
                settings=settings, settings_key=settings_hash(settings),
                settings_name=record.get("settings_name") if isinstance(
                    record.get("settings_name"), str) else None)
    try:
        _check_text_files(path, _TEXT_FILES)
    except EgsBenchError as exc:
        return RunResult(**base, status="broken", reason=str(exc))
    try:
        status = run.read_status()
    except (EgsBenchError, OSError, ValueError) as exc:
        return RunResult(**base, status="broken", reason=str(exc))
    if status.state == "failed":
        return RunResult(**base, status="tracking_lost" if status.tracking_lost else "failed",
                         reason=status.reason or "no reason given")
    if status.state != "done":
        at = f" at {status.progress_text()}" if status.progress else ""
        return RunResult(**base, status="running", reason=f"status is {status.state!r}{at}")
    try:
        data = _load_metrics(run, protocol, evaluate_missing)
        if data is None:
            return RunResult(**base, status="not_evaluated",
                             reason=f"not evaluated under protocol {protocol!r}")
        values = metric_values(data)
        done, total = data.frames_processed, data.frames_in_sequence
    except EgsBenchError as exc:
        return RunResult(**base, status="broken", reason=str(exc))
    except Exception as exc:  # a bad folder must become a footnote, not an abort
        reraise_interruption(exc)
        return RunResult(**base, status="broken",
                         reason=f"{path}: evaluation failed ({type(exc).__name__}: {exc})")
    result = RunResult(**base, status="ok", values=values, frames_processed=done,
                       frames_in_sequence=total)
    if not result.complete:
        return dataclasses.replace(result, status="incomplete",
                                   reason=f"covers {done} of {total} frames")
    return result


def collect_results(runs_root: str | Path, protocol: str = DEFAULT_PROTOCOL,
                    evaluate_missing: bool = True) -> ResultSet:
    """Read every run folder under ``runs_root`` (recursively).

    Runs without ``metrics.json`` for ``protocol`` are evaluated when ``evaluate_missing`` (a
    missing ``metrics.json`` is written; another protocol's file is left alone).

    Raises:
        ConfigError: ``protocol`` is not a known protocol (checked first: an unknown name would
            otherwise only show as every run being "not evaluated").
        InputError: ``runs_root`` is missing or holds no run folder.
    """
    get_protocol(protocol)
    root = Path(runs_root)
    paths = find_runs(root)
    if not paths:
        raise InputError(root, "holds no run folders (no run.yaml found)")
    return ResultSet(root, [read_run_result(p, root, protocol, evaluate_missing) for p in paths],
                     protocol)
