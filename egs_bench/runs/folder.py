"""The run folder: the contract between a method run (ours, a baseline, an import) and evaluation.

Every method run writes one folder; ``egs-bench eval`` reads it and adds ``metrics.json``::

    <run>/run.yaml          identity: method name, sequence name + path, egs-bench version,
                            optional ``groundtruth`` (a TUM file, for runs with no sequence folder),
                            optional ``estimate`` (imports: what the external output covers)
    <run>/config.yaml       the method's fully resolved configuration
    <run>/status.json       {"state": "running"|"done"|"failed", "reason", "tracking_lost", ...}
    <run>/trajectory.txt    estimated T_wc, TUM format, one pose per frame at its exposure end
    <run>/keyframes.txt     frame indices (0-based) of the keyframes, one per line
    <run>/renders/%06d.png  LDR sRGB renders from the estimated poses, named by frame index
    <run>/timing.json       total wall time, per-frame wall time, rendering FPS
    <run>/log.txt           free-form human-readable log (append-only)
    <run>/metrics.json      written by evaluation (never by the method)
    <run>/plots/            written by ``egs-bench plot``

Every file except the append-only log is written atomically (temp file + rename), so a reader
never sees a half-written file. A typical method run::

    run = RunFolder.create(out_dir, method="egs", sequence_name=seq.name,
                           sequence_path=seq.path, config=resolved_cfg)
    with run.failure_guard():          # marks the run failed (with the reason) on an exception
        for i in range(len(seq)):
            ...
            run.write_render(i, ldr_uint8)
        run.write_trajectory(seq.timestamps_s, est_poses)
        run.write_keyframes(keyframe_ids)
        run.write_timing(total_wall_s=..., per_frame_s=..., render_fps=...)
        run.mark_done()
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import json
import re
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from egs_bench import __version__
from egs_bench.errors import InputError
from egs_bench.fileio import atomic_path, to_plain, write_text_atomic
from egs_bench.geometry import Trajectory, read_tum, write_tum

RUN_FILE = "run.yaml"
CONFIG_FILE = "config.yaml"
STATUS_FILE = "status.json"
TRAJECTORY_FILE = "trajectory.txt"
KEYFRAMES_FILE = "keyframes.txt"
RENDERS_DIR = "renders"
TIMING_FILE = "timing.json"
LOG_FILE = "log.txt"
METRICS_FILE = "metrics.json"
PLOTS_DIR = "plots"

STATES = ("running", "done", "failed")
#: ``run.yaml`` ``estimate`` keys and their values for a method's own run (every frame has a
#: pose and a render, metric scale). Imports of external outputs record what they really hold.
ESTIMATE_DEFAULTS: dict[str, Any] = {"poses": "all", "renders": "all", "scale_free": False}
ESTIMATE_COVERAGE = ("all", "keyframes", "subset", "none")
_RENDER_NAME = re.compile(r"^(\d{6,})\.png$")


@dataclass(frozen=True)
class RunStatus:
    """Content of ``status.json``.

    Attributes:
        state: ``"running"``, ``"done"`` or ``"failed"``.
        reason: why the run failed (``None`` unless failed).
        tracking_lost: the failure was a tracking loss (leaderboards show ``L``, not ``--``).
        updated_utc: ISO-8601 UTC time of the last status change.
    """

    state: str
    reason: str | None = None
    tracking_lost: bool = False
    updated_utc: str = ""


@dataclass(frozen=True)
class RunTiming:
    """Content of ``timing.json``.

    Attributes:
        total_wall_s: wall time of the whole SLAM loop (tracking + mapping), seconds.
        per_frame_s: wall time per processed frame, shape [N], seconds.
        render_fps: rendering speed of the final map (frames per second), if measured.
    """

    total_wall_s: float
    per_frame_s: np.ndarray
    render_fps: float | None

    @property
    def fps(self) -> float:
        """Processed frames per second of wall time of the SLAM loop."""
        return len(self.per_frame_s) / self.total_wall_s if self.total_wall_s > 0 else float("nan")


def _now_utc() -> str:
    return _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


def _read_json(path: Path) -> dict[str, Any]:
    if not path.is_file():
        raise InputError(path, "file not found")
    try:
        data = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise InputError(path, f"not valid JSON ({exc})") from None
    if not isinstance(data, dict):
        raise InputError(path, "expected a JSON object")
    return data


def _read_yaml(path: Path) -> dict[str, Any]:
    if not path.is_file():
        raise InputError(path, "file not found")
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise InputError(path, f"not valid YAML ({exc})") from None
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise InputError(path, "expected a YAML mapping")
    return data


def _dump_yaml(data: Mapping[str, Any]) -> str:
    return yaml.safe_dump(to_plain(data), sort_keys=False, default_flow_style=False)


class RunFolder:
    """One method run on one sequence (see the module docstring for the layout).

    Use :meth:`create` to start a run and :meth:`open` to read an existing one.
    """

    def __init__(self, path: Path, info: dict[str, Any]) -> None:
        self.path = path
        self._info = info

    # ---------------------------------------------------------------- creation / opening
    @classmethod
    def create(
        cls,
        path: str | Path,
        *,
        method: str,
        sequence_name: str,
        sequence_path: str | Path | None,
        config: Mapping[str, Any] | None = None,
        groundtruth: str | Path | None = None,
        overwrite: bool = False,
        estimate: Mapping[str, Any] | None = None,
    ) -> RunFolder:
        """Create a run folder, write ``run.yaml`` + ``config.yaml`` and mark it ``running``.

        Args:
            path: the folder to create (parents are created).
            method: method name as it should appear in leaderboards (e.g. ``"egs"``).
            sequence_name: name of the sequence (leaderboard column).
            sequence_path: folder of the canonical sequence the run used (stored absolute), or
                ``None`` for imported runs that only have a ground-truth trajectory.
            config: the method's resolved configuration (plain data, stored as YAML).
            groundtruth: optional TUM ground-truth file; used by evaluation instead of the
                sequence's ``groundtruth.txt`` (required when ``sequence_path`` is ``None``).
            overwrite: allow reusing a folder that already holds a run (its files are replaced;
                stale renders and metrics are removed).
            estimate: what the estimate covers, for imported external outputs: ``poses`` and
                ``renders`` each ``"all"``, ``"keyframes"``, ``"subset"`` or ``"none"``,
                ``scale_free`` (monocular: evaluated with Sim(3)), plus free-form ``source`` /
                ``format`` entries. Omitted: :data:`ESTIMATE_DEFAULTS`.

        Raises:
            InputError: the folder already holds a run and ``overwrite`` is false.
        """
        path = Path(path)
        if not method or not sequence_name:
            raise ValueError("method and sequence_name must be non-empty")
        if sequence_path is None and groundtruth is None:
            raise ValueError("a run needs a sequence_path or a groundtruth trajectory")
        for key in ("poses", "renders"):
            if estimate is not None and estimate.get(key, "all") not in ESTIMATE_COVERAGE:
                raise ValueError(f"estimate {key} must be one of {ESTIMATE_COVERAGE}")
        if (path / RUN_FILE).exists():
            if not overwrite:
                raise InputError(path, "already holds a run (pass overwrite=True / --overwrite)")
            for stale in (METRICS_FILE, TRAJECTORY_FILE, KEYFRAMES_FILE, TIMING_FILE, LOG_FILE):
                (path / stale).unlink(missing_ok=True)
            for sub in (RENDERS_DIR, PLOTS_DIR):
                if (path / sub).is_dir():
                    for f in (path / sub).iterdir():
                        f.unlink()
        path.mkdir(parents=True, exist_ok=True)
        info: dict[str, Any] = {
            "method": str(method),
            "sequence": {
                "name": str(sequence_name),
                "path": str(Path(sequence_path).resolve()) if sequence_path is not None else None,
            },
            "groundtruth": str(Path(groundtruth).resolve()) if groundtruth is not None else None,
            "egs_bench_version": __version__,
            "created_utc": _now_utc(),
        }
        if estimate is not None:
            info["estimate"] = {**ESTIMATE_DEFAULTS, **dict(estimate)}
        write_text_atomic(path / RUN_FILE, _dump_yaml(info))
        run = cls(path, info)
        run.write_config(config or {})
        run.mark_running()
        return run

    @classmethod
    def open(cls, path: str | Path) -> RunFolder:
        """Open an existing run folder (validates ``run.yaml``).

        Raises:
            InputError: the folder or its ``run.yaml`` is missing or malformed.
        """
        path = Path(path)
        if not path.is_dir():
            raise InputError(path, "run folder not found")
        if not (path / RUN_FILE).is_file():
            raise InputError(path, f"not a run folder (no {RUN_FILE})")
        info = _read_yaml(path / RUN_FILE)
        seq = info.get("sequence")
        if not isinstance(info.get("method"), str) or not info["method"]:
            raise InputError(path / RUN_FILE, "missing 'method'")
        if not isinstance(seq, dict) or not isinstance(seq.get("name"), str) or not seq["name"]:
            raise InputError(path / RUN_FILE, "missing 'sequence: {name, path}'")
        if not seq.get("path") and not info.get("groundtruth"):
            raise InputError(path / RUN_FILE, "needs 'sequence.path' or 'groundtruth'")
        return cls(path, info)

    @staticmethod
    def is_run_folder(path: str | Path) -> bool:
        """Whether ``path`` looks like a run folder (has ``run.yaml``)."""
        return (Path(path) / RUN_FILE).is_file()

    # ---------------------------------------------------------------- identity
    @property
    def method(self) -> str:
        """Method name (leaderboard row)."""
        return str(self._info["method"])

    @property
    def sequence_name(self) -> str:
        """Sequence name (leaderboard column)."""
        return str(self._info["sequence"]["name"])

    @property
    def sequence_path(self) -> Path | None:
        """Folder of the canonical sequence, or ``None`` for trajectory-only imports."""
        p = self._info["sequence"].get("path")
        return Path(p) if p else None

    @property
    def groundtruth_path(self) -> Path | None:
        """Explicit ground-truth TUM file overriding the sequence's, if any."""
        p = self._info.get("groundtruth")
        return Path(p) if p else None

    @property
    def estimate(self) -> dict[str, Any]:
        """What the estimate covers (``run.yaml`` ``estimate``, defaults for own runs)."""
        value = self._info.get("estimate")
        return {**ESTIMATE_DEFAULTS, **(value if isinstance(value, dict) else {})}

    @property
    def info(self) -> dict[str, Any]:
        """The parsed ``run.yaml``."""
        return dict(self._info)

    # ---------------------------------------------------------------- config
    def write_config(self, config: Mapping[str, Any]) -> None:
        """Write the method's resolved configuration to ``config.yaml`` (atomically)."""
        write_text_atomic(self.path / CONFIG_FILE, _dump_yaml(config))

    def read_config(self) -> dict[str, Any]:
        """Read ``config.yaml``."""
        return _read_yaml(self.path / CONFIG_FILE)

    # ---------------------------------------------------------------- status
    def _write_status(self, status: RunStatus) -> None:
        data = {
            "state": status.state,
            "reason": status.reason,
            "tracking_lost": status.tracking_lost,
            "updated_utc": status.updated_utc or _now_utc(),
        }
        write_text_atomic(self.path / STATUS_FILE, json.dumps(data, indent=2) + "\n")

    def mark_running(self) -> None:
        """Set the status to ``running``."""
        self._write_status(RunStatus("running"))

    def mark_done(self) -> None:
        """Set the status to ``done`` (call after every output file is written)."""
        self._write_status(RunStatus("done"))

    def mark_failed(self, reason: str, *, tracking_lost: bool = False) -> None:
        """Set the status to ``failed`` with a one-line ``reason``.

        Args:
            reason: human-readable cause (shown in leaderboard footnotes).
            tracking_lost: the method lost tracking (shown as ``L`` rather than ``--``).
        """
        self._write_status(RunStatus("failed", reason=reason, tracking_lost=tracking_lost))
        self.log(f"FAILED: {reason}")

    def read_status(self) -> RunStatus:
        """Read ``status.json``.

        Raises:
            InputError: missing or malformed file, or an unknown state.
        """
        path = self.path / STATUS_FILE
        data = _read_json(path)
        state = data.get("state")
        if state not in STATES:
            raise InputError(path, f"state must be one of {', '.join(STATES)}, found {state!r}")
        return RunStatus(
            state=state,
            reason=data.get("reason"),
            tracking_lost=bool(data.get("tracking_lost", False)),
            updated_utc=str(data.get("updated_utc", "")),
        )

    @contextlib.contextmanager
    def failure_guard(self) -> Iterator[RunFolder]:
        """Context manager: on an exception, mark the run ``failed`` with it, then re-raise."""
        try:
            yield self
        except BaseException as exc:
            reason = f"{type(exc).__name__}: {exc}".strip()
            self.mark_failed(reason.splitlines()[0] if reason else type(exc).__name__)
            raise

    # ---------------------------------------------------------------- trajectory / keyframes
    @property
    def trajectory_path(self) -> Path:
        return self.path / TRAJECTORY_FILE

    def write_trajectory(self, timestamps_s: np.ndarray, poses: np.ndarray) -> None:
        """Write the estimated trajectory (TUM, atomically).

        Args:
            timestamps_s: exposure-end time of each frame, shape [N], seconds.
            poses: estimated ``T_wc`` per frame, shape [N, 4, 4], float64.
        """
        write_tum(self.trajectory_path, timestamps_s, poses)

    def read_trajectory(self, min_poses: int = 1) -> Trajectory:
        """Read the estimated trajectory; raises :class:`InputError` if missing or malformed."""
        if not self.trajectory_path.is_file():
            raise InputError(self.trajectory_path, "estimated trajectory not found "
                                                   "(the run did not write one)")
        return read_tum(self.trajectory_path, min_poses=min_poses)

    def write_keyframes(self, indices: Sequence[int] | np.ndarray) -> None:
        """Write keyframe frame indices (0-based, sorted, unique) to ``keyframes.txt``."""
        idx = np.unique(np.asarray(indices, dtype=np.int64))
        if len(idx) and idx[0] < 0:
            raise ValueError("keyframe indices must be >= 0")
        write_text_atomic(self.path / KEYFRAMES_FILE, "".join(f"{i}\n" for i in idx))

    def read_keyframes(self) -> np.ndarray | None:
        """Keyframe indices [K] int64, or ``None`` when the run wrote no ``keyframes.txt``."""
        path = self.path / KEYFRAMES_FILE
        if not path.is_file():
            return None
        out = []
        for lineno, line in enumerate(path.read_text().splitlines(), start=1):
            line = line.strip()
            if not line or line.startswith("#"):
                continue
            try:
                value = int(line)
            except ValueError:
                raise InputError(path, f"line {lineno}: not an integer frame index") from None
            if value < 0:
                raise InputError(path, f"line {lineno}: negative frame index")
            out.append(value)
        return np.unique(np.asarray(out, dtype=np.int64))

    # ---------------------------------------------------------------- renders
    @property
    def renders_dir(self) -> Path:
        return self.path / RENDERS_DIR

    def render_path(self, frame_index: int) -> Path:
        """Path of the render of frame ``frame_index`` (``renders/%06d.png``)."""
        return self.renders_dir / f"{int(frame_index):06d}.png"

    def write_render(self, frame_index: int, image: np.ndarray) -> None:
        """Write an LDR render as PNG (atomically).

        Args:
            frame_index: 0-based frame index in the sequence.
            image: sRGB render, uint8 [H, W, 3] (float input is rejected: quantise first).
        """
        import imageio.v3 as iio

        image = np.asarray(image)
        if image.dtype != np.uint8 or image.ndim != 3 or image.shape[2] != 3:
            raise ValueError(f"render must be uint8 [H, W, 3], got {image.dtype} {image.shape}")
        with atomic_path(self.render_path(frame_index)) as tmp:
            iio.imwrite(tmp, image, extension=".png")

    def render_indices(self) -> list[int]:
        """Sorted frame indices that have a render."""
        if not self.renders_dir.is_dir():
            return []
        out = []
        for f in self.renders_dir.iterdir():
            m = _RENDER_NAME.match(f.name)
            if m:
                out.append(int(m.group(1)))
        return sorted(out)

    def read_render(self, frame_index: int) -> np.ndarray:
        """Read a render as uint8 [H, W, 3]; raises :class:`InputError` if missing/unreadable."""
        from egs_bench.eval.image_io import read_ldr_image

        path = self.render_path(frame_index)
        if not path.is_file():
            raise InputError(path, f"render of frame {frame_index} not found")
        return read_ldr_image(path)

    # ---------------------------------------------------------------- timing
    def write_timing(
        self,
        *,
        total_wall_s: float,
        per_frame_s: Sequence[float] | np.ndarray,
        render_fps: float | None = None,
    ) -> None:
        """Write ``timing.json`` (atomically).

        Args:
            total_wall_s: wall time of the SLAM loop, seconds.
            per_frame_s: wall time per processed frame, [N] seconds.
            render_fps: rendering speed of the final map (renders per second), if measured.
        """
        per_frame = np.asarray(per_frame_s, dtype=np.float64)
        data = {
            "total_wall_s": float(total_wall_s),
            "frames": int(len(per_frame)),
            "fps": float(len(per_frame) / total_wall_s) if total_wall_s > 0 else None,
            "render_fps": float(render_fps) if render_fps is not None else None,
            "per_frame_s": [float(v) for v in per_frame],
        }
        write_text_atomic(self.path / TIMING_FILE, json.dumps(data, indent=1) + "\n")

    def read_timing(self) -> RunTiming | None:
        """Read ``timing.json``; ``None`` when the run wrote none (e.g. imported runs)."""
        path = self.path / TIMING_FILE
        if not path.is_file():
            return None
        data = _read_json(path)
        try:
            total = float(data["total_wall_s"])
            per_frame = np.asarray(data.get("per_frame_s", []), dtype=np.float64)
            fps = data.get("render_fps")
            return RunTiming(total, per_frame, float(fps) if fps is not None else None)
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(path, f"malformed timing ({exc})") from None

    # ---------------------------------------------------------------- log / outputs
    @property
    def log_path(self) -> Path:
        return self.path / LOG_FILE

    def log(self, message: str) -> None:
        """Append a time-stamped line to ``log.txt`` (append-only, flushed per line)."""
        with self.log_path.open("a") as f:
            f.write(f"{_now_utc()} {message}\n")

    @property
    def metrics_path(self) -> Path:
        return self.path / METRICS_FILE

    @property
    def plots_dir(self) -> Path:
        return self.path / PLOTS_DIR


def find_runs(root: str | Path) -> list[Path]:
    """All run folders under ``root`` (recursive; a run folder's own subfolders are skipped).

    Returns paths sorted for deterministic output.
    """
    root = Path(root)
    if not root.is_dir():
        raise InputError(root, "runs folder not found")
    found = sorted(p.parent for p in root.rglob(RUN_FILE))
    out: list[Path] = []
    for p in found:
        if not any(parent in out for parent in p.parents):
            out.append(p)
    return out
