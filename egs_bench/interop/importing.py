"""Import the outputs of external systems as run folders that ``egs-bench eval`` and
``egs-bench leaderboard`` treat like any other run: a TUM trajectory (:func:`import_tum_run`), or
a system's own output read by the system's reader (:func:`import_external_run`; the systems and
what each writes: :mod:`egs_bench.interop.registry`).

Mapping to the sequence: with the export folder (``egs-bench export``), the external time
stamps / frame uids are mapped through its ``index_map.csv`` back to sequence frames and the
run's trajectory uses the sequence's own exposure-end stamps. Keyframe-only and partial
trajectories are recorded in ``run.yaml`` (``estimate: {poses, renders, scale_free}``) and
reported by evaluation (e.g. "ATE over 9 of 40 frames: the estimate holds keyframes poses
only"). A keyframe file a system writes when it shuts down (MonoGS ``trj_final.json``, ORB-SLAM's
``KeyFrameTrajectory*``) also records ``frames_processed``: the frames the system read, not the
last keyframe's index + 1, so a protocol that scores keyframes sees a complete run. Which
systems write such a file, and which write a Gaussian map that the import can render, is
declared by each system (:class:`~egs_bench.interop.systems.ExternalSystem`).

Validation at import, as ``egs-bench eval`` would: the sequence folder opens, the estimate has
at least 3 poses matching the ground truth within 0.01 s, and every render decodes and has the
sequence's size, all before anything is written. A new run folder is built in a staging folder
(:func:`egs_bench.fileio.atomic_dir`) and appears only when complete, so a failed import leaves
nothing that blocks a retry.
"""

from __future__ import annotations

import contextlib
import json
import re
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from egs_bench.errors import ConfigError, InputError
from egs_bench.fileio import atomic_dir, write_text_atomic
from egs_bench.geometry import Intrinsics, Trajectory, read_tum
from egs_bench.images import read_ldr_image
from egs_bench.interop.export import read_export_index
from egs_bench.interop.registry import importable_system, importable_systems
from egs_bench.interop.systems import ExternalEstimate, ExternalSystem, ImportOptions
from egs_bench.outputs import prepare_output
from egs_bench.runs.folder import RunFolder

if TYPE_CHECKING:
    from egs_bench.datasets.sequence import Sequence

_RENDER = re.compile(r"^(\d+)\.png$")
_MATCH_TOL_S = 5e-4  # external stamps are printed with 6 decimals


def import_tum_run(
    estimate: str | Path,
    out_dir: str | Path,
    *,
    method: str,
    sequence_name: str,
    sequence_path: str | Path | None = None,
    groundtruth: str | Path | None = None,
    renders_dir: str | Path | None = None,
    overwrite: bool = False,
) -> RunFolder:
    """Create a finished run folder from an external TUM trajectory (and optional renders).

    Args:
        estimate: the external system's trajectory, TUM format (seconds, ``T_wc``).
        out_dir: run folder to create.
        method: method name for leaderboards.
        sequence_name: sequence name for leaderboards.
        sequence_path: canonical sequence folder (ground truth and reference images), or
        groundtruth: a TUM ground-truth file (for sequences that exist only as trajectories).
        renders_dir: folder of ``<frame index>.png`` renders to copy (any zero padding).
        overwrite: replace an existing run folder written by egs-bench.

    Raises:
        InputError: unreadable estimate / ground truth, or badly named renders.
        OutputError: ``out_dir`` exists (without ``overwrite``) or is (or contains) an input.
    """
    from egs_bench.datasets.sequence import Sequence

    if sequence_path is None and groundtruth is None:
        raise InputError(out_dir, "an import needs a sequence folder or a ground-truth file")
    trajectory = read_tum(estimate, min_poses=3)
    seq = Sequence.open(sequence_path) if sequence_path is not None else None
    if groundtruth is not None:
        gt, gt_name = read_tum(groundtruth, min_poses=3), Path(groundtruth)
    else:
        assert seq is not None
        gt, gt_name = Trajectory(np.asarray(seq.timestamps_s, dtype=np.float64),
                                 np.asarray(seq.poses, dtype=np.float64)), \
            seq.path / "groundtruth.txt"
    _check_overlap(trajectory, gt, Path(estimate), gt_name)
    renders = _renders_in(renders_dir) if renders_dir is not None else {}
    if seq is not None:
        _check_render_frames(renders, len(seq), Path(renders_dir or "."))
    _check_renders(renders, seq)
    with _new_run(out_dir, overwrite=overwrite, method=method, sequence_name=sequence_name,
                  sequence_path=sequence_path, groundtruth=groundtruth,
                  config={"imported_from": str(Path(estimate).resolve())},
                  inputs=[p for p in (estimate, renders_dir) if p is not None]) as run:
        run.write_trajectory(trajectory.timestamps, trajectory.poses)
        for index, src in renders.items():
            run.write_render(index, read_ldr_image(src))
        run.log(f"imported {len(trajectory)} poses from {estimate}"
                + (f" and {len(renders)} renders from {renders_dir}" if renders else ""))
        run.mark_done()
    return RunFolder.open(out_dir)


def _check_overlap(trajectory: Trajectory, gt: Trajectory, est_name: Path,
                   gt_name: Path) -> None:
    """Refuse an estimate that evaluation could not score: fewer than 3 of its poses match a
    ground-truth pose within evaluation's 0.01 s (e.g. a clock 100 s off), with evaluation's
    own association and message.

    Raises:
        InputError: naming ``est_name``.
    """
    from egs_bench.eval.ate import DEFAULT_MAX_DIFF_S, associate

    associate(trajectory, gt, max_diff_s=DEFAULT_MAX_DIFF_S, est_name=est_name,
              gt_name=gt_name)


def _check_render_frames(renders: Mapping[int, Any], num_frames: int, where: Path) -> None:
    """Refuse renders of frames the sequence does not have."""
    beyond = [f for f in renders if not 0 <= f < num_frames]
    if beyond:
        raise InputError(where, f"holds a render of frame {min(beyond)}, beyond the sequence's "
                                f"{num_frames} frames")


def _check_renders(renders: Mapping[int, Path | np.ndarray], seq: Sequence | None) -> None:
    """Decode every render file and compare its size with the sequence's, before anything is
    written (a header-only check passes a truncated file).

    Raises:
        InputError: naming the render that does not decode or has another size.
    """
    for image in renders.values():
        img = read_ldr_image(image) if isinstance(image, Path) else image
        if seq is not None and img.shape[:2] != (seq.height, seq.width):
            where = image if isinstance(image, Path) else Path(seq.path)
            raise InputError(where, f"render is {img.shape[1]}x{img.shape[0]}, the sequence is "
                                    f"{seq.width}x{seq.height}")


@contextlib.contextmanager
def _new_run(out_dir: str | Path, *, overwrite: bool, inputs: list[str | Path],
             **create: Any) -> Iterator[RunFolder]:
    """The run folder an import fills (``create`` are :meth:`RunFolder.create`'s arguments).

    A new (or empty) ``out_dir`` is built in a staging folder and renamed into place when the
    block ends after :meth:`RunFolder.mark_done`; on an error or a signal the staging folder is
    removed, so nothing is left that a retry would have to ``--overwrite``. An existing run
    folder replaced with ``overwrite`` is rewritten in place, by :meth:`RunFolder.create`'s
    rules (files a run does not write are kept, which a folder swap would delete).
    """
    out_dir = Path(out_dir)
    protected = [p for p in (create.get("sequence_path"), create.get("groundtruth"), *inputs)
                 if p is not None]
    prepare_output(out_dir, "run", overwrite=overwrite, inputs=protected)
    fresh = not out_dir.exists() or (out_dir.is_dir() and not out_dir.is_symlink()
                                     and not any(out_dir.iterdir()))
    if not fresh:
        run = RunFolder.create(out_dir, overwrite=overwrite, inputs=inputs, **create)
        with run.failure_guard():
            yield run
        return
    with atomic_dir(out_dir) as staging:
        run = RunFolder.create(staging, inputs=inputs, **create)
        with run.failure_guard():
            yield run


def _renders_in(renders_dir: str | Path) -> dict[int, Path]:
    """``<frame index>.png`` files of a folder, by frame index."""
    renders_dir = Path(renders_dir)
    if not renders_dir.is_dir():
        raise InputError(renders_dir, "renders folder not found")
    renders: dict[int, Path] = {}
    for f in sorted(renders_dir.iterdir()):
        m = _RENDER.match(f.name)
        if f.suffix.lower() == ".png" and not m:
            raise InputError(f, "render names must be the frame index, e.g. 000005.png")
        if m:
            renders[int(m.group(1))] = f
    return renders


# --------------------------------------------------------------------------------------------
# mapping onto the sequence


def _nearest(reference: np.ndarray, stamps: np.ndarray, source: str | Path,
             what: str) -> np.ndarray:
    """Index into ``reference`` of the nearest stamp for each of ``stamps`` (within 0.5 ms).

    Raises:
        InputError: naming ``source``, for a stamp with no reference stamp that close.
    """
    ref = np.asarray(reference, dtype=np.float64)
    stamps = np.asarray(stamps, dtype=np.float64)
    order = np.argsort(ref, kind="stable")
    ts = ref[order]
    right = np.searchsorted(ts, stamps).clip(0, len(ts) - 1)
    left = (right - 1).clip(0, len(ts) - 1)
    k = np.where(np.abs(stamps - ts[left]) <= np.abs(stamps - ts[right]), left, right)
    bad = np.abs(ts[k] - stamps) > _MATCH_TOL_S
    if bad.any():
        j = int(np.argmax(bad))
        raise InputError(source, f"time stamp {stamps[j]:.6f} s matches no frame of {what} "
                                 f"(nearest {ts[k[j]]:.6f} s)")
    return order[k]


def _unit_scale(stamps: np.ndarray, reference: np.ndarray) -> float:
    """The factor (1, 1e9, 1e-6, 1e-3, 1e6, 1e3) that brings ``stamps`` onto ``reference``
    (RampVO writes seconds x 1e-9), or 1 if none does."""
    for factor in (1.0, 1e9, 1e-6, 1e-3, 1e6, 1e3):
        scaled = stamps * factor
        k = np.searchsorted(reference, scaled).clip(1, len(reference) - 1)
        near = np.minimum(np.abs(scaled - reference[k - 1]), np.abs(scaled - reference[k]))
        if (near <= _MATCH_TOL_S).all():
            return factor
    return 1.0


@dataclass(frozen=True)
class _Frames:
    """Where an import's frames come from: sequence frame of each export frame, the time stamps
    written in the export, and the sequence's own stamps."""

    frame: np.ndarray
    t_external: np.ndarray
    t_sequence: np.ndarray
    rgb: tuple[str, ...]
    export_format: str | None
    what: str


def _frames(export_dir: str | Path | None, seq: Sequence) -> _Frames:
    if export_dir is not None:
        idx = read_export_index(export_dir)
        return _Frames(idx.frame, idx.t_export_s, idx.t_sequence_s, idx.rgb, idx.format,
                       f"the export {idx.path}")
    n = len(seq)
    stamps = np.asarray(seq.timestamps_s, dtype=np.float64)
    rgb = tuple(str(seq.frame_path(i, "rgb").relative_to(seq.path)) for i in range(n))
    return _Frames(np.arange(n), stamps, stamps, rgb, None, f"sequence {seq.path}")


def _loaded(system: ExternalSystem, frames: _Frames) -> np.ndarray:
    """Export-frame indices of the frames ``system`` loads (a system's frame uids index
    them): every frame, unless the system says otherwise (``loaded_frames``)."""
    if system.loaded_frames is None:
        return np.arange(len(frames.frame))
    return system.loaded_frames(frames.export_format, frames.t_external)


def _frames_processed(est: ExternalEstimate, frames: _Frames, system: ExternalSystem
                      ) -> int | None:
    """Leading sequence frames an external system read, when its keyframe file says it ran to
    the end (the estimate's ``written_at_end``, which a system's reader sets for a file it
    writes at shutdown); None otherwise (evaluation then counts up to the last pose)."""
    if est.poses_kind != "keyframes" or not est.written_at_end:
        return None
    loaded = _loaded(system, frames) if est.uids is not None else np.arange(len(frames.frame))
    return int(frames.frame[loaded].max()) + 1


def _to_export_frames(est: ExternalEstimate, frames: _Frames, source: Path,
                      system: ExternalSystem) -> tuple[np.ndarray, np.ndarray | None]:
    """Export-frame index of every pose and of every keyframe."""
    if est.uids is not None:
        kept = _loaded(system, frames)
        if est.uids.max() >= len(kept):
            raise InputError(source, f"frame uid {int(est.uids.max())} beyond the "
                                     f"{len(kept)} frames {system.title} loads from {frames.what}")
        kf = kept[est.keyframe_uids] if est.keyframe_uids is not None else None
        return kept[est.uids], kf
    stamps = np.asarray(est.stamps_s, dtype=np.float64)
    ref = np.sort(frames.t_external)
    scale = _unit_scale(stamps, ref) if est.stamps_unit_unknown else 1.0
    idx = _nearest(frames.t_external, stamps * scale, source, frames.what)
    kf = None
    if est.keyframe_stamps_s is not None:
        kf = _nearest(frames.t_external, np.asarray(est.keyframe_stamps_s) * scale, source,
                      frames.what)
    return idx, kf


def _render_ply(ply: Path, poses_wc: np.ndarray, intrinsics: Intrinsics) -> list[np.ndarray]:
    """Render a 3DGS map at each pose ([N, 4, 4] camera-to-world) into [H, W, 3] uint8
    images; colours are taken as display (sRGB-encoded) values, as a system trains them on the
    8-bit frames it reads (no transfer curve applied), clipped to [0, 1]."""
    import torch

    from egs_bench.render.ply import load_ply
    from egs_bench.render.rasterize import rasterize

    gmap = load_ply(ply)
    K = torch.tensor(intrinsics.K[None], dtype=gmap.dtype)
    out = []
    with torch.no_grad():
        for pose in poses_wc:
            view = torch.tensor(np.linalg.inv(pose)[None], dtype=gmap.dtype)
            res = rasterize(gmap.means, gmap.quats, gmap.scales, gmap.opacities, gmap.colors,
                            view, K, intrinsics.width, intrinsics.height)
            rgb = res.rgb[0].clamp(0, 1).cpu().numpy()
            out.append((rgb * 255.0 + 0.5).astype(np.uint8))
    return out


def import_external_run(
    source: str | Path,
    out_dir: str | Path,
    *,
    fmt: str,
    export_dir: str | Path | None = None,
    method: str | None = None,
    sequence_name: str | None = None,
    sequence_path: str | Path | None = None,
    renders_dir: str | Path | None = None,
    render_ply: bool = False,
    quaternion: str = "rampvo",
    overwrite: bool = False,
) -> RunFolder:
    """Import an external system's output (see the module docstring) as a finished run folder.

    Args:
        source: the system's output file or folder.
        out_dir: run folder to create.
        fmt: the system's key, one of
            :func:`egs_bench.interop.registry.import_formats` but ``tum`` (which
            :func:`import_tum_run` reads).
        export_dir: the ``egs-bench export`` folder the system ran on (maps its stamps / frame
            uids back to sequence frames; names the sequence).
        method: leaderboard name (default: the system's name).
        sequence_name: leaderboard column (default: the exported sequence's name).
        sequence_path: the sequence folder (default: the one the export came from).
        renders_dir: extra renders ``<frame index>.png`` (e.g. from a patched system).
        render_ply: render the system's Gaussian map
            (:attr:`~egs_bench.interop.systems.ExternalSystem.gaussian_map`) at the imported
            poses.
        quaternion: RampVO's quaternion columns: ``rampvo`` (as its code writes them) or
            ``wxyz``.
        overwrite: replace an existing run folder.

    Raises:
        ConfigError: unknown format or option. InputError: unreadable or inconsistent files
            (the message names the file), time stamps that match no frame.
    """
    from egs_bench.datasets.sequence import Sequence

    system = importable_system(fmt)
    assert system.read is not None  # importable_system returns a system with a reader
    if render_ply and system.gaussian_map is None:
        drawn = [s.key for s in importable_systems() if s.gaussian_map is not None]
        raise ConfigError(f"--render-ply: {system.title} writes no Gaussian map (systems that "
                          f"do: {', '.join(drawn) or 'none'})")
    source = Path(source)
    est = system.read(source, ImportOptions(quaternion=quaternion))
    if sequence_path is None:
        if export_dir is None:
            raise InputError(out_dir, "an import needs the export folder (--export) or the "
                                      "sequence folder (--sequence-path)")
        sequence_path = read_export_index(export_dir).sequence_path
    seq = Sequence.open(sequence_path)
    frames = _frames(export_dir, seq)
    if len(frames.frame) and frames.frame.max() >= len(seq):
        raise InputError(Path(export_dir or sequence_path), f"maps to frame "
                         f"{int(frames.frame.max())}, beyond the sequence's {len(seq)} frames")
    idx, kf_idx = _to_export_frames(est, frames, source, system)
    seq_frames = frames.frame[idx]
    order = np.argsort(seq_frames, kind="stable")
    seq_frames, poses = seq_frames[order], est.poses[order]
    if len(np.unique(seq_frames)) != len(seq_frames):
        raise InputError(source, "two poses map to the same frame")
    if est.poses_kind == "subset" and len(seq_frames) == len(frames.frame):
        est.poses_kind = "all"
    renders: dict[int, Path | np.ndarray] = {}
    rgb_to_export = {name: j for j, name in enumerate(frames.rgb)}
    for key, path in est.renders.items():
        j = rgb_to_export.get(str(key))
        if j is None:
            raise InputError(path, f"its image {key!r} is not a frame of {frames.what}")
        renders[int(frames.frame[j])] = path
    if renders_dir is not None:
        renders.update(_renders_in(renders_dir))
    if render_ply:
        if est.ply is None:
            raise InputError(source, f"no {system.gaussian_map} to render (--render-ply "
                                     f"needs a {system.title} output folder that holds it)")
        for f, rendered in zip(seq_frames, _render_ply(est.ply, poses, seq.intrinsics),
                               strict=True):
            renders[int(f)] = rendered
    _check_render_frames(renders, len(seq), Path(renders_dir or source))
    _check_renders(renders, seq)
    _check_overlap(Trajectory(seq.timestamps_s[seq_frames], poses),
                   Trajectory(np.asarray(seq.timestamps_s, dtype=np.float64),
                              np.asarray(seq.poses, dtype=np.float64)),
                   source, seq.path / "groundtruth.txt")
    renders_kind = "none" if not renders else (
        "all" if len(renders) >= len(seq) else
        "keyframes" if est.poses_kind == "keyframes" or est.renders else "subset")
    name = method or system.title
    config = {"imported_from": [str(Path(s).resolve()) for s in est.sources],
              "format": fmt, "export": str(Path(export_dir).resolve()) if export_dir else None,
              "render_ply": bool(render_ply), **est.settings}
    estimate: dict[str, Any] = {"poses": est.poses_kind, "renders": renders_kind,
                                "scale_free": est.scale_free, "format": fmt}
    processed = _frames_processed(est, frames, system)
    if processed is not None:
        estimate["frames_processed"] = processed
    with _new_run(out_dir, overwrite=overwrite, method=name,
                  sequence_name=sequence_name or seq.name, sequence_path=seq.path,
                  config=config, estimate=estimate,
                  inputs=[p for p in (source, export_dir, renders_dir) if p is not None]) as run:
        run.write_trajectory(seq.timestamps_s[seq_frames], poses)
        if kf_idx is not None:
            run.write_keyframes(frames.frame[kf_idx])
        elif est.poses_kind == "keyframes":
            run.write_keyframes(seq_frames)
        for f, image in sorted(renders.items()):  # checked by _check_renders
            run.write_render(f, image if isinstance(image, np.ndarray) else read_ldr_image(image))
        if est.reported:
            write_text_atomic(run.path / "reported_metrics.json",
                              json.dumps(est.reported, indent=1) + "\n")
        run.log(f"imported {len(poses)} {est.poses_kind} poses ({fmt}) of {len(seq)} frames "
                f"from {', '.join(est.sources)}; {len(renders)} renders ({renders_kind})")
        run.mark_done()
    return RunFolder.open(out_dir)

