"""``make_eventreplica``: a blurred E-RGB-D sequence from one Replica-layout scene.

Timeline. Strided frame ``j`` sits at ``t_j = j / fps``. Output frame ``j`` is exposed over
``[t_j - exposure, t_j]``, so its sharp ground truth is the original frame ``j`` (exposure end)
and its depth is that frame's depth. Frame 0 has no content before it, so the sequence starts at
the first strided frame whose exposure lies inside the interpolated span (``j = 1`` whenever the
exposure is at most one frame period, which is required: exposures must not overlap). Events
cover ``[t_start of the first output frame, t_end of the last]`` -- the span the pipeline
samples; nothing before the first exposure is simulated.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any, Literal

import numpy as np

from egs_bench.color import LdrResponse
from egs_bench.datasets.esim import EventSimConfig
from egs_bench.datasets.eventreplica.interpolate import InterpolatorName, make_interpolator
from egs_bench.datasets.eventreplica.resize import ResizeCrop
from egs_bench.datasets.eventreplica.source import ReplicaSource
from egs_bench.datasets.pipeline import SamplingConfig, generate_sequence
from egs_bench.datasets.replica import read_replica
from egs_bench.datasets.rgbd_layouts import RGBDInput
from egs_bench.errors import ConfigError, InputError
from egs_bench.outputs import prepare_output, shareable_path


def exposure_windows(
    key_times_us: np.ndarray, exposure_us: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exposure windows ending at the key frames whose exposure fits after the first key time.

    Returns:
        ``(frame_ids [N], t_start_us [N], t_end_us [N])``, ``frame_ids`` indexing the strided
        frames.
    """
    key_times_us = np.asarray(key_times_us, dtype=np.int64)
    t_end = key_times_us
    t_start = t_end - int(exposure_us)
    ids = np.nonzero(t_start >= key_times_us[0])[0]
    return ids, t_start[ids], t_end[ids]


def make_eventreplica(
    input: str | Path | RGBDInput,
    out: str | Path,
    *,
    stride: int = 1,
    fps: float = 30.0,
    exposure_ms: float = 20.0,
    upsample: str | int = "auto",
    interpolator: InterpolatorName = "depth",
    width: int = 448,
    height: int = 256,
    resize: tuple[int, int] | Literal["auto"] | None = "auto",
    first: int = 0,
    max_frames: int | None = None,
    cam_params: str | Path | None = None,
    sim: EventSimConfig | None = None,
    response: LdrResponse | None = None,
    sampling: SamplingConfig | None = None,
    progress: bool = True,
    overwrite: bool = False,
) -> Path:
    """Generate an EventReplica-style sequence (canonical format) from a Replica-layout scene.

    Args:
        input: scene folder in NICE-SLAM Replica layout (see :mod:`egs_bench.datasets.replica`),
            or an :class:`~egs_bench.datasets.rgbd_layouts.RGBDInput` naming a TUM RGB-D
            folder or a generic image / depth / trajectory layout. Frames of every layout are
            placed at ``j / fps``; a layout's own time stamps are recorded in ``meta.yaml``.
        out: output sequence folder (written atomically).
        stride: use every ``stride``-th original frame (larger = faster motion = more blur).
        fps: frame rate of the strided frames, Hz.
        exposure_ms: exposure per output frame, at most one frame period.
        upsample: ``"auto"`` = the pipeline's adaptive rule (pixel-motion and log-change
            bounds); an int ``N`` = latent samples every ``period / N`` (about ``N`` per strided
            interval; exposure boundaries are always samples, so a few more).
        interpolator: ``"depth"`` (pose-aware view synthesis) or ``"flow"`` (DIS optical flow).
        width, height: output size after the centre crop.
        resize: size ``(w, h)`` to resize to before cropping; ``"auto"`` = the paper's 459x260
            for Replica's 1200x680 frames, the input's aspect ratio otherwise (see
            :func:`~egs_bench.datasets.eventreplica.resize.auto_resize`); None = crop only.
        first: first original frame used.
        max_frames: cap on the number of strided frames read (output frames are one fewer).
        cam_params: explicit ``cam_params.json`` (else auto-detected, else Replica defaults);
            Replica layout given as a folder only (an ``RGBDInput`` carries its own camera).
        sim: event simulator settings (default: thresholds 0.25, eps 1e-3, no noise).
        response: camera response (default: sRGB, gain 1, which reproduces the original frames).
        sampling: full sampling settings; overrides ``upsample``.
        progress: show a progress bar.
        overwrite: replace ``out`` if it exists.

    Returns:
        The sequence folder.
    """
    if isinstance(input, RGBDInput):
        if cam_params is not None:
            raise ConfigError("give the camera file in the RGBDInput, not as cam_params")
        spec = input
    else:
        spec = RGBDInput(layout="replica", path=Path(input),
                         camera=None if cam_params is None else Path(cam_params))
    inputs = spec.inputs()
    prepare_output(out, "sequence", overwrite=overwrite, inputs=inputs)
    scene = spec.open()
    if not (math.isfinite(fps) and fps > 0):
        raise ConfigError(f"fps must be positive, got {fps}")
    period_us = 1e6 / fps
    exposure_us = int(round(exposure_ms * 1000.0))
    if exposure_us <= 0:
        raise ConfigError(f"exposure must be positive, got {exposure_ms} ms")
    if exposure_us > math.floor(period_us):
        raise ConfigError(
            f"exposure {exposure_ms} ms exceeds the frame period {period_us / 1000:.3f} ms "
            f"at {fps} fps (exposures must not overlap)"
        )
    if sampling is None:
        sampling = _sampling_for(upsample, period_us)
    source = ReplicaSource(
        scene, fps=fps, stride=stride, first=first, num_frames=max_frames,
        geometry=ResizeCrop(width=width, height=height, resize=resize),
        interpolator=make_interpolator(interpolator),
    )
    ids, t_start, t_end = exposure_windows(source.key_times_us, exposure_us)
    if len(ids) == 0:
        raise InputError(scene.path, "no frame has a full exposure inside the sequence (too "
                                     "few frames for --stride / --first / --max-frames?)")
    sim = sim or EventSimConfig()
    meta_extra: dict[str, Any] = {
        "name": Path(out).name,
        # meta.yaml goes along with the sequence: the inputs relative to it, no local paths
        "source": f"EventReplica generator from {shareable_path(scene.path, out)}",
        "eventreplica": {
            "input": shareable_path(scene.path, out),
            "paths_relative_to": "this sequence folder (a path outside its parent: name only)",
            "layout": scene.layout,
            "cam_params": None if scene.cam_params_path is None
            else shareable_path(scene.cam_params_path, out),
            "input_intrinsics": scene.intrinsics.to_dict(),
            "input_intrinsics_note": "egs-bench convention: Replica cx, cy + 0.5",
            "stride": stride,
            "first": first,
            "fps_strided": fps,
            "original_frames": [int(source.frame_indices[i]) for i in ids],
            **({} if scene.timestamps_s is None else {"original_timestamps_s": [
                round(float(scene.timestamps_s[source.frame_indices[i]]), 6) for i in ids]}),
            **({"distortion": list(scene.distortion)} if scene.distortion else {}),
            **({"layout_record": {k: shareable_path(v, out) if isinstance(v, Path) else v
                                  for k, v in scene.record.items()}} if scene.record else {}),
            "resize": list(source.geometry.resized_size(scene.intrinsics)),
            "resize_rule": resize if isinstance(resize, str) or resize is None else "explicit",
            "crop": [width, height],
            "interpolator": source.interpolator.name,
            "interpolator_settings": asdict(source.interpolator),  # type: ignore[call-overload]
            "upsample": upsample if isinstance(upsample, str) else int(upsample),
            "linearisation": "sRGB EOTF (IEC 61966-2-1) on the 8-bit input frames",
            "timeline": "output frame j exposed over [t_j - exposure, t_j]; sharp = original "
                        "frame j; the first strided frame only starts the interpolation",
        },
    }
    return generate_sequence(
        source, t_start, t_end, out, meta_extra=meta_extra, sim=sim,
        response=response or LdrResponse(), sampling=sampling, progress=progress,
        overwrite=overwrite, inputs=inputs,
    )


def make_eventreplica_scenes(
    replica_root: str | Path, scenes: Sequence[str], out: str | Path, **kwargs: Any
) -> list[Path]:
    """Run :func:`make_eventreplica` for ``replica_root/<scene>`` into ``out/<scene>`` each.

    A ``cam_params.json`` in ``replica_root`` is picked up automatically (parent-folder lookup).
    """
    root = Path(replica_root)
    if not root.is_dir():
        raise InputError(root, "Replica root folder does not exist")
    if not scenes:
        raise ConfigError("name at least one scene")
    missing = [s for s in scenes if not (root / s).is_dir()]
    if missing:
        raise InputError(root / missing[0], "scene folder does not exist")
    # every scene's input and output are checked before the first is generated, so a bad
    # scene or output path does not stop the batch half-way
    for s in scenes:
        prepare_output(Path(out) / s, "sequence", overwrite=bool(kwargs.get("overwrite")),
                       inputs=[root / s, kwargs.get("cam_params")])
        read_replica(root / s, cam_params=kwargs.get("cam_params"))
    return [make_eventreplica(root / s, Path(out) / s, **kwargs) for s in scenes]


def _sampling_for(upsample: str | int, period_us: float) -> SamplingConfig:
    if isinstance(upsample, str):
        if upsample == "auto":
            return SamplingConfig()
        try:
            upsample = int(upsample)
        except ValueError:
            raise ConfigError(f"upsample must be 'auto' or a positive integer, "
                              f"not {upsample!r}") from None
    if upsample < 1:
        raise ConfigError(f"upsample must be >= 1, got {upsample}")
    return SamplingConfig(fixed_step_us=max(1, math.floor(period_us / int(upsample))))
