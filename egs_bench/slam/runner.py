"""Run a configured SLAM method on a sequence and write its run folder."""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from egs_bench.datasets.sequence_view import SequenceView
from egs_bench.errors import ConfigError, InputError
from egs_bench.fileio import write_text_atomic
from egs_bench.geometry import invert_pose
from egs_bench.progress import ProgressBar
from egs_bench.render import cpu_kernels
from egs_bench.render.cpu_kernels import kernels_ready
from egs_bench.render.ply import save_ply
from egs_bench.render.rasterize import resolve_backend
from egs_bench.runs.folder import RunFolder
from egs_bench.slam.appearance import APPEARANCE_FILE, MAP_FILE, Appearance, ldr8, write_appearance
from egs_bench.slam.components import SlamComponents
from egs_bench.slam.config import SlamConfig, resolve_device
from egs_bench.slam.progress import COMPILING, PhaseProgress
from egs_bench.slam.render_model import render_views
from egs_bench.slam.system import FrameReport, SlamResult, SlamSystem


def check_inputs(seq: SequenceView, config: SlamConfig, max_frames: int | None) -> int:
    """The number of frames to process; rejects runs that cannot give a meaningful result.

    Raises:
        ConfigError: ``max_frames`` below 1.
        InputError: the method uses events (event tracking or mapping) but the sequence has
            none (``has_events: false`` in its ``meta.yaml``): event losses would see empty
            event maps and the no-event loss would pull every frame towards "no motion".
    """
    if max_frames is not None and int(max_frames) < 1:
        raise ConfigError(f"--max-frames must be at least 1, got {max_frames}")
    if (config.method.event_tracking or config.method.event_mapping) and not seq.has_events:
        used = [n for n in ("event_tracking", "event_mapping") if getattr(config.method, n)]
        raise InputError(seq.path / "meta.yaml",
                         f"has_events is false, but the method uses events ({', '.join(used)}); "
                         "run a method without events (egs-no-events, monogs) or set "
                         + " and ".join(f"{n}=false" for n in used))
    return len(seq) if max_frames is None else min(len(seq), int(max_frames))


@dataclass(frozen=True)
class RunSettings:
    """How one run is carried out, besides the configuration.

    Attributes:
        preset: the budget's name, recorded in the run folder.
        device: torch device (``auto``: CUDA when present).
        seed: seeds every random choice.
        max_frames: process only the first frames (None: all).
        progress: show a progress bar.
        overwrite: replace an existing run folder at the output path.
    """

    preset: str = "paper"
    device: str = "cpu"
    seed: int = 0
    max_frames: int | None = None
    progress: bool = True
    overwrite: bool = False


def run_slam(seq: SequenceView, out: str | Path, *, method_name: str, config: SlamConfig,
             settings: RunSettings = RunSettings(),
             components: SlamComponents | None = None) -> RunFolder:
    """Run the SLAM system configured by ``config`` on ``seq``; write a complete run folder.

    Writes the estimated ``T_tau`` of every processed frame (TUM, exposure-end stamps), the
    keyframes, LDR renders of the sharp latent image at ``T_tau`` for every processed frame at
    the sequence's resolution, the map (``map.ply``) with what reproduces the renders from it
    (``appearance.json``: CRF, camera, per-frame exposure; :mod:`egs_bench.slam.appearance`),
    timing, ``slam_stats.json`` (divergences, map size) and the log. On an exception the folder
    is marked failed (interrupted on Ctrl-C or SIGTERM) with the reason.

    Args:
        settings: device, seed, frames, progress; ``settings.overwrite`` replaces an existing
            run folder at ``out`` (see :meth:`RunFolder.create`).
        components: the SLAM system's tracker, mapper and keyframe policy (None: built-in).

    Raises:
        ConfigError, InputError: see :func:`check_inputs`; OutputError: ``out`` may not be
        written (see :func:`egs_bench.outputs.prepare_output`).
    """
    device = resolve_device(settings.device)
    preset, seed, progress = settings.preset, settings.seed, settings.progress
    n = check_inputs(seq, config, settings.max_frames)
    resolved = {"method": method_name, "preset": preset, "seed": seed, "device": device,
                "frames": n, "slam": config.to_dict(),
                "components": (components or SlamComponents()).record()}
    run = RunFolder.create(out, method=method_name, sequence_name=seq.name,
                           sequence_path=seq.path, config=resolved,
                           overwrite=settings.overwrite)
    with run.failure_guard():
        if device == "cpu":
            torch.use_deterministic_algorithms(True, warn_only=True)
        run.log(f"{method_name} on {seq.name}: {n} frames, preset {preset}, seed {seed}")
        system = SlamSystem(seq, config, device=device, seed=seed, log=run.log,
                            components=components)
        bar = ProgressBar(n, f"{method_name} {seq.name}", unit="frame", enabled=progress)
        # The CPU kernels compile (cold cache) or load before the clock starts: timing.json
        # gives compile_s apart, so a cold cache does not lower the run's frame rate.
        t_compile = time.perf_counter()
        if resolve_backend(config.runtime.backend, system.device) == "numba":
            from egs_bench.kernel_cache import uncached_kernels

            if not kernels_ready() and uncached_kernels("egs_bench.render"):
                bar.set_postfix_str(COMPILING)  # only when numba's cache lacks them
            cpu_kernels.prepare_kernels()
        compile_s = time.perf_counter() - t_compile
        t_start = time.perf_counter()
        run.set_progress(0, n)
        gaussians_per_frame: list[int] = []  # the map's size after each frame (its mapping)

        def on_frame(rep: FrameReport) -> None:
            elapsed = time.perf_counter() - t_start
            gaussians_per_frame.append(len(system.gmap))
            run.set_progress(rep.index + 1, n)
            bar.set_postfix(loss=rep.loss, fps=round((rep.index + 1) / max(elapsed, 1e-9), 2),
                            gaussians=len(system.gmap))
            bar.update(1)

        # Frame 0's map initialisation alone takes minutes on a CPU with the paper budget:
        # show how far it is and when it ends (or that kernels compile) rather than a frozen bar.
        phase_progress = PhaseProgress(kernels_ready if device == "cpu" else None)

        def on_phase(name: str, done: int, total: int) -> None:
            bar.set_postfix_str(phase_progress.text(name, done, total))

        try:
            result = system.run(n, on_frame=on_frame, on_phase=on_phase if progress else None)
        except BaseException:
            _write_partial_trajectory(run, system, seq)
            raise
        total_wall = time.perf_counter() - t_start
        bar.close()
        poses_wc = np.stack([invert_pose(s.pose1_cw) for s in result.states])
        run.write_trajectory(np.asarray(seq.timestamps_s[:n]), poses_wc)
        run.write_keyframes(result.keyframes)
        render_fps = _write_renders(run, system, result, seq)
        run.write_timing(total_wall_s=total_wall,
                         per_frame_s=[r.wall_s for r in result.reports], render_fps=render_fps,
                         compile_s=compile_s)
        save_ply(result.gmap, run.artifact_path(MAP_FILE))
        write_appearance(run.artifact_path(APPEARANCE_FILE), Appearance(
            system.crf, seq.intrinsics, config.mapping.near_plane,
            np.array([s.index for s in result.states]),
            np.asarray(seq.timestamps_s[:n], dtype=np.float64),
            np.array([s.exp_a for s in result.states]),
            np.array([s.exp_b for s in result.states])))
        stats = {"frames": n, "keyframes": len(result.keyframes),
                 "gaussians": len(result.gmap), "gaussians_per_frame": gaussians_per_frame,
                 "divergences": result.divergences,
                 "tracking_iterations": [r.iterations for r in result.reports],
                 "fps": n / total_wall if total_wall > 0 else None,
                 "work": system.ctx.work.summary()}
        write_text_atomic(run.artifact_path("slam_stats.json"),
                          json.dumps(stats, indent=1) + "\n")
        run.log(f"done: {n} frames in {total_wall:.1f} s ({stats['fps']:.3f} fps), "
                f"{len(result.keyframes)} keyframes, {len(result.gmap)} Gaussians, "
                f"{len(result.divergences)} divergence(s)")
        run.mark_done()
    return run


def _write_partial_trajectory(run: RunFolder, system: SlamSystem, seq: SequenceView) -> None:
    """The trajectory of the frames processed before an interruption or a failure, so the
    run can still be scored over them (the run stays marked interrupted / failed)."""
    states = getattr(system, "states", None) or []
    if not states:
        return
    try:
        poses_wc = np.stack([invert_pose(s.pose1_cw) for s in states])
        run.write_trajectory(np.asarray(seq.timestamps_s[:len(states)]), poses_wc)
        run.log(f"wrote the trajectory of the {len(states)} frame(s) processed before the run "
                "stopped")
    except Exception as exc:  # never hide the original error
        run.log(f"could not write the partial trajectory: {exc}")


@torch.no_grad()
def _write_renders(run: RunFolder, system: SlamSystem, result: SlamResult, seq: SequenceView
                   ) -> float:
    """Render the sharp latent image at every frame's ``T_tau`` at full resolution; returns the
    rendering speed (renders per second)."""
    full = seq.intrinsics
    K = torch.tensor(full.K, dtype=torch.float32, device=system.device)
    elapsed = 0.0
    for s in result.states:
        t = time.perf_counter()
        res = render_views(result.gmap, s.pose1_cw[None], K, full.width, full.height,
                           system.cfg)
        img = ldr8(system.crf, res.rgb[0])
        elapsed += time.perf_counter() - t
        run.write_render(s.index, img)
    return len(result.states) / elapsed if elapsed > 0 else float("nan")
