"""Turn a latent (sharp, linear, time-continuous) RGB-D source into a canonical sequence.

Shared by the procedural scenes and the EventReplica generator. For each frame's exposure
window ``[t_start, t_end]`` it produces

- the observed frame: the time average of linear latent samples over the window (trapezoid rule
  on the sample grid), through the camera response, quantised to 8 bits;
- the sharp ground truth: the latent sample at ``t_end`` through the same response;
- depth and pose at ``t_end``;

and, over the whole span, events from the ESIM model fed with every latent sample.

Temporal sampling rule (adaptive; ESIM assumes log-brightness linear in time between samples):
the exposure boundaries are always samples; between two consecutive boundaries the interval is
split into ``n = ceil(max_flow / max_flow_px)`` equal steps (default 1 px, the rule of vid2e),
``max_flow`` being the largest predicted pixel motion between the interval's end frames (depth
back-projected at one end, re-projected at the other, both ways). Event *counts* do not depend
on the sampling (they follow the end values); the linear-in-time assumption only moves event
*timestamps* within one step, i.e. by less than the time the image needs to move 1 px.
Optionally (``max_log_step``), each step is also bisected (up to ``max_bisections`` times) while
the ``log_percentile``-th percentile over pixels of ``|Δ log(B + eps)|`` exceeds the bound; it
is off by default because on fine textures it multiplies the number of renders several times.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np

import egs_bench
from egs_bench.color import LdrResponse
from egs_bench.datasets.esim import EventSimConfig, EventSimulator, log_luma
from egs_bench.datasets.sequence import SequenceWriter
from egs_bench.errors import ConfigError
from egs_bench.fileio import atomic_dir
from egs_bench.geometry import Intrinsics, invert_pose
from egs_bench.interrupts import raise_if_interrupted
from egs_bench.outputs import prepare_output
from egs_bench.progress import ProgressBar, say_compiling

DEFAULT_DEPTH_SCALE = 5000.0  # uint16 PNG units per metre (TUM convention): 0.2 mm, <= 13.1 m


@dataclass
class LatentFrame:
    """One latent sample of the scene.

    Attributes:
        rgb: linear radiance, float32 [H, W, 3], >= 0 (1.0 = LDR white at gain 1).
        depth: z-depth in metres, float32 [H, W], 0 = invalid.
        pose: camera-to-world ``T_wc``, float64 [4, 4].
    """

    rgb: np.ndarray
    depth: np.ndarray
    pose: np.ndarray


class LatentSource(Protocol):
    """Anything that renders the sharp scene at an arbitrary time."""

    intrinsics: Intrinsics

    def pose(self, t_us: int) -> np.ndarray:
        """Camera-to-world pose [4, 4] at ``t_us``."""
        ...

    def render(self, t_us: int) -> LatentFrame:
        """Latent frame at ``t_us`` (microseconds)."""
        ...


@dataclass(frozen=True)
class SamplingConfig:
    """Temporal sampling of the latent source (see the module docstring for the rule).

    Attributes:
        max_flow_px: largest predicted pixel motion between consecutive samples.
        max_log_step: optional bound on the ``log_percentile``-th percentile of ``|Δ log B|``
            between consecutive samples (None: no log-change refinement).
        log_percentile: percentile over pixels used for the log-change bound.
        max_bisections: how many times a step may be halved for the log-change bound.
        fixed_step_us: if set, no adaptivity: each interval between boundaries is split into
            ``ceil(length / fixed_step_us)`` equal steps.
    """

    max_flow_px: float = 1.0
    max_log_step: float | None = None
    log_percentile: float = 99.0
    max_bisections: int = 3
    fixed_step_us: int | None = None

    def __post_init__(self) -> None:
        if not self.max_flow_px > 0:
            raise ConfigError("max_flow_px must be positive")
        if self.max_log_step is not None and not self.max_log_step > 0:
            raise ConfigError("max_log_step must be positive (or None)")
        if self.fixed_step_us is not None and self.fixed_step_us < 1:
            raise ConfigError("fixed_step_us must be >= 1")


def max_flow_px(a: LatentFrame, b: LatentFrame, intrinsics: Intrinsics, stride: int = 4) -> float:
    """Largest pixel displacement of the scene between two frames (static scene, both ways).

    Back-projects the valid depth of one frame (every ``stride``-th pixel) and re-projects it
    with the other frame's pose.
    """
    worst = 0.0
    for src, dst in ((a, b), (b, a)):
        depth = src.depth[::stride, ::stride]
        points = intrinsics.backproject(src.depth)[::stride, ::stride]
        valid = depth > 0
        if not valid.any():
            continue
        pts = points[valid]
        rel = invert_pose(dst.pose) @ src.pose
        moved = pts @ rel[:3, :3].T + rel[:3, 3]
        in_front = moved[:, 2] > 1e-6
        if not in_front.any():
            return math.inf
        uv0 = intrinsics.project(pts[in_front])
        uv1 = intrinsics.project(moved[in_front])
        worst = max(worst, float(np.abs(uv1 - uv0).max()))
    return worst


class _Sampler:
    """Yields latent samples in time order between fixed boundary times."""

    def __init__(self, source: LatentSource, config: SamplingConfig, eps: float) -> None:
        self.source = source
        self.config = config
        self.eps = eps
        self.num_samples = 0
        self.max_flow_seen = 0.0

    def render(self, t_us: int) -> tuple[int, LatentFrame, np.ndarray]:
        frame = self.source.render(int(t_us))
        self.num_samples += 1
        return int(t_us), frame, log_luma(frame.rgb, self.eps)

    def between(self, a: tuple[int, LatentFrame, np.ndarray], t_b: int
                ) -> Iterator[tuple[int, LatentFrame, np.ndarray]]:
        """Samples in ``(t_a, t_b]`` (``a`` already emitted)."""
        b = self.render(t_b)
        if self.config.fixed_step_us is not None:
            steps = math.ceil((t_b - a[0]) / self.config.fixed_step_us)
        else:
            flow = max_flow_px(a[1], b[1], self.source.intrinsics)
            self.max_flow_seen = max(self.max_flow_seen, flow)
            steps = max(1, math.ceil(flow / self.config.max_flow_px)) if math.isfinite(flow) \
                else 2 ** self.config.max_bisections
        steps = min(steps, max(1, t_b - a[0]))  # at most one sample per microsecond
        times = np.round(np.linspace(a[0], t_b, steps + 1)).astype(np.int64)[1:]
        prev = a
        for t in times:
            cur = b if t == t_b else self.render(int(t))
            if self.config.fixed_step_us is None and self.config.max_log_step is not None:
                yield from self._refine(prev, cur, self.config.max_bisections)
            else:
                yield cur
            prev = cur

    def _refine(self, a: tuple[int, LatentFrame, np.ndarray],
                b: tuple[int, LatentFrame, np.ndarray], depth: int
                ) -> Iterator[tuple[int, LatentFrame, np.ndarray]]:
        if depth > 0 and b[0] - a[0] >= 2:
            change = np.percentile(np.abs(b[2] - a[2]), self.config.log_percentile)
            if change > self.config.max_log_step:
                mid = self.render((a[0] + b[0]) // 2)
                yield from self._refine(a, mid, depth - 1)
                yield from self._refine(mid, b, depth - 1)
                return
        yield b


def _blur_step(acc: np.ndarray, prev_rgb: np.ndarray, rgb: np.ndarray, dt_us: int) -> None:
    """Trapezoid-rule accumulation of linear radiance over one sample step (in place)."""
    acc += (0.5 * dt_us) * (prev_rgb.astype(np.float64) + rgb)


def generate_sequence(
    source: LatentSource,
    t_start_us: np.ndarray,
    t_end_us: np.ndarray,
    out: str | Path,
    *,
    meta_extra: dict[str, Any] | None = None,
    sim: EventSimConfig | None = None,
    response: LdrResponse | None = None,
    sampling: SamplingConfig | None = None,
    depth_scale: float = DEFAULT_DEPTH_SCALE,
    progress: bool = True,
    overwrite: bool = False,
    inputs: Sequence[str | Path | None] = (),
) -> Path:
    """Render, simulate and write a canonical sequence folder at ``out`` (atomically).

    Args:
        source: the latent scene.
        t_start_us: exposure starts, [N] int64 microseconds.
        t_end_us: exposure ends, [N] int64 microseconds; each window non-empty, none
            overlapping the next.
        out: destination folder; written under a temporary name, then renamed.
        meta_extra: extra ``meta.yaml`` entries (name, source, scene description...).
        sim: event simulator settings (thresholds, eps, noise...).
        response: camera response to LDR (default: sRGB, gain 1).
        sampling: temporal sampling rule.
        depth_scale: depth PNG units per metre.
        progress: show a progress bar.
        overwrite: replace an existing ``out`` (only a sequence folder that egs-bench wrote
            and that holds nothing else, see :func:`egs_bench.outputs.prepare_output`).
        inputs: files or folders the generator reads; ``out`` may not be or contain one.

    Returns:
        The sequence folder.

    Raises:
        OutputError: ``out`` exists and may not be replaced.
    """
    out = Path(out)
    sim = sim or EventSimConfig()
    response = response or LdrResponse()
    sampling = sampling or SamplingConfig()
    t_start = np.asarray(t_start_us, dtype=np.int64)
    t_end = np.asarray(t_end_us, dtype=np.int64)
    if len(t_start) == 0 or len(t_start) != len(t_end):
        raise ValueError("need the same non-zero number of exposure starts and ends")
    if (t_end <= t_start).any() or (t_start[1:] < t_end[:-1]).any():
        raise ValueError("exposure windows must be non-empty and must not overlap")
    prepare_output(out, "sequence", overwrite=overwrite, inputs=inputs)
    cam = source.intrinsics
    boundaries = np.unique(np.concatenate([t_start, t_end]))
    meta = _base_meta(cam, sim, response, sampling, t_start, t_end, depth_scale)
    meta.update(meta_extra or {})
    meta["name"] = meta.get("name") or out.name

    # the writer and the bar are closed on an error too: the bar before the error's line, the
    # event file before its staging folder goes
    with (atomic_dir(out, replace=overwrite) as tmp,
          SequenceWriter(tmp, meta, t_offset_us=int(boundaries[0])) as writer,
          contextlib.ExitStack() as closing):
        events = writer.events
        assert events is not None  # t_offset_us given: the writer has an event file
        sampler = _Sampler(source, sampling, sim.eps)
        simulator = EventSimulator(sim, cam.height, cam.width)
        if progress and _compiles(source):  # else a cold cache is a silent minute
            say_compiling(f"generating {out.name}")
        prev = sampler.render(int(boundaries[0]))
        simulator.reset(prev[2], prev[0])
        dense_t, dense_pose = [prev[0]], [prev[1].pose]
        frame = 0
        acc = np.zeros((cam.height, cam.width, 3))
        bar = closing.enter_context(ProgressBar(len(t_start), f"generating {out.name}",
                                                unit="frame", enabled=progress))
        for t_b in boundaries[1:]:
            raise_if_interrupted()  # one whose exception was swallowed: stop within a frame
            for cur in sampler.between(prev, int(t_b)):
                events.append(simulator.step(cur[2], cur[0]))
                if frame < len(t_start) and t_start[frame] <= prev[0] and cur[0] <= t_end[frame]:
                    _blur_step(acc, prev[1].rgb, cur[1].rgb, cur[0] - prev[0])
                dense_t.append(cur[0])
                dense_pose.append(cur[1].pose)
                prev = cur
                if frame < len(t_end) and cur[0] == t_end[frame]:
                    observed = acc / float(t_end[frame] - t_start[frame])
                    writer.add_frame(int(t_start[frame]), int(t_end[frame]),
                                     response.to_ldr(observed), cur[1].depth, cur[1].pose,
                                     sharp=response.to_ldr(cur[1].rgb))
                    acc[:] = 0.0
                    frame += 1
                    bar.set_postfix(samples=sampler.num_samples)
                    bar.update(1)
        bar.close()
        meta_stats = {"num_samples": sampler.num_samples,
                      "max_flow_px_between_boundaries": round(sampler.max_flow_seen, 3)}
        writer.meta["sampling"].update(meta_stats)
        writer.finish(np.asarray(dense_t), np.stack(dense_pose))
    return out


def _compiles(source: LatentSource) -> bool:
    """Whether the first frame will compile numba kernels: the event simulator's, or those of
    the source's own package (``egs_bench.datasets.synthetic``, ``...eventreplica``), are not
    in numba's cache."""
    from egs_bench.kernel_cache import uncached_kernels

    package = type(source).__module__.rsplit(".", 1)[0]
    return bool(uncached_kernels("egs_bench.datasets.esim_kernels")
                or (package != "egs_bench.datasets" and uncached_kernels(package)))


def _base_meta(cam: Intrinsics, sim: EventSimConfig, response: LdrResponse,
               sampling: SamplingConfig, t_start: np.ndarray, t_end: np.ndarray,
               depth_scale: float) -> dict[str, Any]:
    period = float(np.median(np.diff(t_end))) if len(t_end) > 1 else float(t_end[0] - t_start[0])
    return {
        "name": None,
        "source": None,
        "generator": {"name": "egs-bench", "version": egs_bench.__version__},
        "width": cam.width, "height": cam.height,
        "fx": cam.fx, "fy": cam.fy, "cx": cam.cx, "cy": cam.cy,
        "pixel_convention": "pixel (u, v) has its centre at (u + 0.5, v + 0.5)",
        "distortion": [0.0, 0.0, 0.0, 0.0, 0.0],
        "depth_scale": depth_scale,
        "eps": sim.eps,
        "event_thresholds": {"pos": sim.pos_threshold, "neg": sim.neg_threshold},
        "sigma": sim.sigma,
        "refractory_us": sim.refractory_us,
        "noise": {"shot_noise_rate_hz": sim.noise_rate_hz},
        "event_seed": sim.seed,
        "exposure_us": int(np.median(t_end - t_start)),
        "frame_rate": 1e6 / period if period > 0 else None,
        "crf": response.to_dict(),
        "sampling": asdict(sampling),
    }
