"""The run folder's file contract: what files a run folder has, and reading and writing them.

The contract is between a method run (ours, a baseline, an import) and evaluation.

Every method run writes one folder; ``egs-bench eval`` reads it and adds ``metrics.json``::

    <run>/run.yaml          identity: method name, sequence name + path, egs-bench version,
                            optional ``groundtruth`` (a TUM file, for runs with no sequence folder),
                            optional ``estimate`` (imports: what the external output covers),
                            ``artifacts`` (method-specific files, e.g. ``map.ply``)
    <run>/config.yaml       the method's fully resolved configuration
    <run>/status.json       {"state": "running"|"done"|"failed"|"interrupted", "reason",
                             "tracking_lost", "pid", "host", "heartbeat_utc",
                             optional "progress": {"done": frames processed, "total"}}
    <run>/trajectory.txt    estimated T_wc, TUM format, one pose per frame at its exposure end
    <run>/keyframes.txt     frame indices (0-based) of the keyframes, one per line
    <run>/renders/%06d.png  LDR sRGB renders from the estimated poses, named by frame index
    <run>/timing.json       total wall time, per-frame wall time, rendering FPS
    <run>/log.txt           free-form human-readable log (append-only)
    <run>/metrics.json      written by evaluation (never by the method)
    <run>/plots/            written by ``egs-bench plot``
    <run>/.lock             held (``flock``) by the process writing the run

Every file except the append-only log is written atomically (temp file + rename), so a reader
never sees a half-written file. :class:`RunFiles` reads and writes these files;
who may write a folder, and when a ``running`` status is believed, is the coordination of
:mod:`egs_bench.runs.coordination`, whose :class:`~egs_bench.runs.coordination.RunFolder` (a
:class:`RunFiles` that holds the folder's lock) is what a method run uses.
A typical method run::

    run = RunFolder.create(out_dir, method="egs", sequence_name=seq.name,
                           sequence_path=seq.path, config=resolved_cfg)
    with run.failure_guard():          # failed (or interrupted, on Ctrl-C / SIGTERM) + reason
        for i in range(len(seq)):
            ...
            run.write_render(i, ldr_uint8)
        run.write_trajectory(seq.timestamps_s, est_poses)
        run.write_keyframes(keyframe_ids)
        run.write_timing(total_wall_s=..., per_frame_s=..., render_fps=...)
        save_ply(gmap, run.artifact_path("map.ply"))
        run.mark_done()
"""

from __future__ import annotations

import datetime as _dt
import json
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Self

import numpy as np
import yaml

from egs_bench import installed_version
from egs_bench.errors import InputError
from egs_bench.fileio import (
    is_atomic_temp,
    naming_full_disk,
    read_text,
    read_yaml_mapping,
    to_plain,
    write_text_atomic,
)
from egs_bench.geometry import Trajectory, read_tum, write_tum
from egs_bench.images import read_ldr_image, write_ldr_image
from egs_bench.provenance import code_revision

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
LOCK_FILE = ".lock"
#: the plots ``egs-bench plot`` writes into ``plots/``
PLOT_FILES = ("trajectory_top.png", "ate_over_time.png", "qualitative.png")
_STANDARD_FILES = (RUN_FILE, CONFIG_FILE, STATUS_FILE, TRAJECTORY_FILE, KEYFRAMES_FILE,
                   TIMING_FILE, LOG_FILE, METRICS_FILE)

STATES = ("running", "done", "failed", "interrupted")
#: ``run.yaml`` ``estimate`` keys and their values for a method's own run (every frame has a
#: pose and a render, metric scale). Imports of external outputs record what they really hold.
ESTIMATE_DEFAULTS: dict[str, Any] = {"poses": "all", "renders": "all", "scale_free": False}
ESTIMATE_COVERAGE = ("all", "keyframes", "subset", "none")
_RENDER_NAME = re.compile(r"^(\d{6,})\.png$")



@dataclass(frozen=True)
class RunStatus:
    """Content of ``status.json``, with stale runs detected.

    Attributes:
        state: ``"running"``, ``"done"``, ``"failed"`` or ``"interrupted"`` (stopped by a
            signal, or a ``running`` run whose writing process is gone).
        reason: why the run failed or stopped (``None`` when running or done).
        tracking_lost: the failure was a tracking loss (leaderboards show ``L``, not ``--``).
        updated_utc: ISO-8601 UTC time of the last status change.
        pid, host: the process that wrote the run.
        heartbeat_utc: last sign of life of that process while running.
        progress: ``(done, total)`` frames the method had processed at the last status write
            (a heartbeat while running, the final state when it stopped), or None when the
            method does not report progress.
    """

    state: str
    reason: str | None = None
    tracking_lost: bool = False
    updated_utc: str = ""
    pid: int | None = None
    host: str | None = None
    heartbeat_utc: str | None = None
    progress: tuple[int, int] | None = None

    def progress_text(self) -> str:
        """``"frame 123/300"``, or ``""`` without progress."""
        return f"frame {self.progress[0]}/{self.progress[1]}" if self.progress else ""


@dataclass(frozen=True)
class RunTiming:
    """Content of ``timing.json``.

    Attributes:
        total_wall_s: wall time of the whole SLAM loop (tracking + mapping), seconds.
        per_frame_s: wall time per processed frame, shape [N], seconds.
        render_fps: rendering speed of the final map (frames per second), if measured.
        compile_s: kernel compilation (or cache loading) before the loop, seconds; None in
            runs that did not record it.
    """

    total_wall_s: float
    per_frame_s: np.ndarray
    render_fps: float | None
    compile_s: float | None = None

    @property
    def init_s(self) -> float | None:
        """Frame 0's wall time: the map's initialisation (None without frames)."""
        return float(self.per_frame_s[0]) if len(self.per_frame_s) else None

    @property
    def fps_after_init(self) -> float | None:
        """Frames per second over frames 1.. (tracking and mapping, the steady state);
        None with fewer than two frames."""
        rest = float(np.sum(self.per_frame_s[1:]))
        return (len(self.per_frame_s) - 1) / rest if len(self.per_frame_s) > 1 and rest > 0 \
            else None

    @property
    def fps(self) -> float:
        """Processed frames per second of wall time of the SLAM loop."""
        return len(self.per_frame_s) / self.total_wall_s if self.total_wall_s > 0 else float("nan")


def _now_utc() -> str:
    return _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


def _parse_utc(text: str | None) -> _dt.datetime | None:
    if not text:
        return None
    try:
        return _dt.datetime.strptime(text, "%Y-%m-%dT%H:%M:%SZ").replace(tzinfo=_dt.UTC)
    except ValueError:
        return None


def _read_progress(path: Path, value: Any) -> tuple[int, int] | None:
    """``status.json``'s optional ``progress`` as ``(done, total)``."""
    if value is None:
        return None
    ok = isinstance(value, dict) and all(
        isinstance(value.get(k), int) and not isinstance(value.get(k), bool) and value[k] >= 0
        for k in ("done", "total"))
    if not ok or value["done"] > value["total"]:
        raise InputError(path, "'progress' must be {\"done\": n, \"total\": m} with "
                               f"0 <= n <= m, found {value!r}")
    return int(value["done"]), int(value["total"])


def read_json_object(path: Path) -> dict[str, Any]:
    """A JSON file whose top level is an object; anything else is an :class:`InputError`
    naming the file."""
    text = read_text(path)
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(path, f"not valid JSON ({exc})") from None
    if not isinstance(data, dict):
        raise InputError(path, "expected a JSON object")
    return data


def _read_yaml(path: Path) -> dict[str, Any]:
    return read_yaml_mapping(path, empty_is_mapping=True)


def _dump_yaml(data: Mapping[str, Any]) -> str:
    return yaml.safe_dump(to_plain(data), sort_keys=False, default_flow_style=False)


def run_identity(method: str, sequence_name: str, sequence_path: str | Path | None,
                 groundtruth: str | Path | None = None,
                 estimate: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """A new run's ``run.yaml`` content: who made it (method, egs-bench version, code
    revision, time), on what (sequence name and absolute path, or a ground-truth file), what the
    estimate covers (``estimate``, imports only) and no artifacts yet."""
    info: dict[str, Any] = {
        "method": str(method),
        "sequence": {
            "name": str(sequence_name),
            "path": str(Path(sequence_path).resolve()) if sequence_path is not None else None,
        },
        "groundtruth": str(Path(groundtruth).resolve()) if groundtruth is not None else None,
        "egs_bench_version": installed_version(),
        "code": code_revision(),
        "created_utc": _now_utc(),
        "artifacts": [],
    }
    if estimate is not None:
        info["estimate"] = {**ESTIMATE_DEFAULTS, **dict(estimate)}
    return info


class RunFiles:
    """The files of one run folder (see the module docstring for the layout): ``run.yaml``'s
    identity, and reading and writing the outputs of a run.

    Use :meth:`open` to read an existing run; a method run writes through
    :meth:`egs_bench.runs.coordination.RunFolder.create`, a :class:`RunFiles` that holds the
    folder's lock.
    """

    def __init__(self, path: Path, info: dict[str, Any]) -> None:
        self.path = path
        self._info = info

    # ---------------------------------------------------------------- files a run owns
    @staticmethod
    def remove_run_files(path: Path) -> list[str]:
        """Delete what a run wrote into ``path`` (its standard files, recorded artifacts,
        ``renders/NNNNNN.png``, the plots, and the temporary files of atomic writes a killed
        process left); returns the names of other entries, which are kept. Symbolic links are
        never followed: a linked ``renders/`` is kept whole."""
        try:
            artifacts = _read_yaml(path / RUN_FILE).get("artifacts") or []
        except InputError:
            artifacts = []
        names = set(_STANDARD_FILES) | {str(a) for a in artifacts if isinstance(a, str)}

        def ours_to_delete(entry: Path, ours: bool) -> bool:
            return (ours or is_atomic_temp(entry.name)) and entry.is_file() \
                and not entry.is_symlink()

        for entry in list(path.iterdir()):
            if "/" not in entry.name and ours_to_delete(entry, entry.name in names):
                entry.unlink()
        for sub, allowed in ((RENDERS_DIR, None), (PLOTS_DIR, set(PLOT_FILES))):
            folder = path / sub
            if not folder.is_dir() or folder.is_symlink():
                continue
            for f in list(folder.iterdir()):
                ours = _RENDER_NAME.match(f.name) if allowed is None else f.name in allowed
                if ours_to_delete(f, bool(ours)):
                    f.unlink()
            if not any(folder.iterdir()):
                folder.rmdir()
        kept = []
        for entry in sorted(path.iterdir()):
            if entry.name == LOCK_FILE:
                continue
            if entry.name in (RENDERS_DIR, PLOTS_DIR) and entry.is_dir() \
                    and not entry.is_symlink():
                kept += [f"{entry.name}/{f.name}" for f in sorted(entry.iterdir())]
                continue
            kept.append(entry.name)
        return kept

    @classmethod
    def open(cls, path: str | Path) -> Self:
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
        if seq.get("path") is not None and not isinstance(seq.get("path"), str):
            raise InputError(path / RUN_FILE, "'sequence.path' must be a path")
        if info.get("groundtruth") is not None and not isinstance(info["groundtruth"], str):
            raise InputError(path / RUN_FILE, "'groundtruth' must be a path")
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
    def code_revision(self) -> dict[str, Any] | None:
        """``{"commit", "modified"}`` of the egs_bench checkout that wrote the run
        (:func:`egs_bench.provenance.code_revision`); None for runs written from an installed
        package, without git, or before run folders recorded it."""
        value = self._info.get("code")
        return dict(value) if isinstance(value, dict) and isinstance(value.get("commit"), str) \
            else None

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

    # ---------------------------------------------------------------- status (as written)
    def read_status_file(self) -> RunStatus:
        """Read ``status.json`` as written: a ``running`` state is not checked against its
        writer (:meth:`egs_bench.runs.coordination.RunFolder.read_status` does that).

        Raises:
            InputError: missing or malformed file, or an unknown state.
        """
        path = self.path / STATUS_FILE
        data = read_json_object(path)
        state = data.get("state")
        if state not in STATES:
            raise InputError(path, f"state must be one of {', '.join(STATES)}, found {state!r}")
        reason, pid, host = data.get("reason"), data.get("pid"), data.get("host")
        if reason is not None and not isinstance(reason, str):
            raise InputError(path, f"'reason' must be text or null, found {reason!r}")
        if not isinstance(data.get("tracking_lost", False), bool):
            raise InputError(path, "'tracking_lost' must be true or false")
        if pid is not None and (isinstance(pid, bool) or not isinstance(pid, int)):
            raise InputError(path, f"'pid' must be an integer, found {pid!r}")
        if host is not None and not isinstance(host, str):
            raise InputError(path, f"'host' must be text, found {host!r}")
        progress = _read_progress(path, data.get("progress"))
        return RunStatus(
            state=state,
            reason=reason,
            tracking_lost=bool(data.get("tracking_lost", False)),
            updated_utc=str(data.get("updated_utc", "")),
            pid=pid,
            host=host,
            heartbeat_utc=str(data["heartbeat_utc"]) if data.get("heartbeat_utc") else None,
            progress=progress,
        )

    # ---------------------------------------------------------------- artifacts
    def artifact_path(self, name: str) -> Path:
        """Path for a method-specific output file (e.g. ``map.ply``), recorded in ``run.yaml``
        so that ``--overwrite`` removes it with the rest of the run."""
        if "/" in name or name in _STANDARD_FILES or name.startswith("."):
            raise ValueError(f"artifact name must be a plain new file name, not {name!r}")
        artifacts = list(self._info.get("artifacts") or [])
        if name not in artifacts:
            artifacts.append(name)
            self._info["artifacts"] = artifacts
            write_text_atomic(self.path / RUN_FILE, _dump_yaml(self._info))
        return self.path / name

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
        for lineno, line in enumerate(read_text(path).splitlines(), start=1):
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
        write_ldr_image(self.render_path(frame_index), image)

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
        compile_s: float | None = None,
    ) -> None:
        """Write ``timing.json`` (atomically).

        Args:
            total_wall_s: wall time of the SLAM loop, seconds (kernel compilation excluded).
            per_frame_s: wall time per processed frame, [N] seconds (frame 0: the map's
                initialisation).
            render_fps: rendering speed of the final map (renders per second), if measured.
            compile_s: seconds spent compiling or loading kernels before the loop.
        """
        per_frame = np.asarray(per_frame_s, dtype=np.float64)
        timing = RunTiming(float(total_wall_s), per_frame, render_fps, compile_s)
        data = {
            "total_wall_s": float(total_wall_s),
            "frames": int(len(per_frame)),
            "fps": float(len(per_frame) / total_wall_s) if total_wall_s > 0 else None,
            "render_fps": float(render_fps) if render_fps is not None else None,
            "compile_s": float(compile_s) if compile_s is not None else None,
            "init_s": timing.init_s,
            "fps_after_init": timing.fps_after_init,
            "per_frame_s": [float(v) for v in per_frame],
        }
        write_text_atomic(self.path / TIMING_FILE, json.dumps(data, indent=1) + "\n")

    def read_timing(self) -> RunTiming | None:
        """Read ``timing.json``; ``None`` when the run wrote none (e.g. imported runs)."""
        path = self.path / TIMING_FILE
        if not path.is_file():
            return None
        data = read_json_object(path)
        try:
            total = float(data["total_wall_s"])
            per_frame = np.asarray(data.get("per_frame_s", []), dtype=np.float64)
            fps = data.get("render_fps")
            compile_s = data.get("compile_s")
            return RunTiming(total, per_frame, float(fps) if fps is not None else None,
                             float(compile_s) if compile_s is not None else None)
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(path, f"malformed timing ({exc})") from None

    # ---------------------------------------------------------------- log / outputs
    @property
    def log_path(self) -> Path:
        return self.path / LOG_FILE

    def log(self, message: str) -> None:
        """Append a time-stamped line to ``log.txt`` (append-only, flushed per line)."""
        with naming_full_disk(self.log_path), self.log_path.open("a") as f:
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
