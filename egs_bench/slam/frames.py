"""Per-frame observations at the SLAM's internal resolution, and per-frame estimated state."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import torch

from egs_bench.datasets.sequence_view import SequenceView
from egs_bench.geometry import Intrinsics
from egs_bench.slam.config import SlamConfig
from egs_bench.slam.exposure import segment_edges_us, subpose_fractions
from egs_bench.slam.levels import kept_subposes
from egs_bench.slam.losses import depth_valid_mask, edge_mask, rgb_boundary_mask


@dataclass
class FrameObs:
    """What the sensors gave for one frame, ready for the losses (internal resolution).

    Attributes:
        index: frame index in the sequence.
        rgb: observed LDR image [H, W, 3] float32 in [0, 1] (sRGB-encoded values, as stored).
        depth: depth [H, W] metres (0 = invalid).
        rgb_mask, depth_mask: bool [H, W] (MonoGS boundary / valid-depth masks).
        edge_weight: [H, W] float MonoGS tracking edge mask, or None.
        fractions: sub-pose fractions eta_k / tau, float64 numpy [M] (M = K + 1, or [1.0]
            without blur model; host-side, like the poses).
        event_maps: [K, H, W] float32 polarity sums per segment (area-averaged when the internal
            resolution is reduced), or None when events are not used.
        n_events: number of events in the exposure window.
    """

    index: int
    rgb: torch.Tensor
    depth: torch.Tensor
    rgb_mask: torch.Tensor
    depth_mask: torch.Tensor
    edge_weight: torch.Tensor | None
    fractions: np.ndarray
    event_maps: torch.Tensor | None
    n_events: int


def internal_intrinsics(full: Intrinsics, scale: float) -> Intrinsics:
    """Intrinsics of the internal processing resolution (``scale`` x the sequence's)."""
    if scale >= 1.0:
        return full
    w = max(8, int(round(full.width * scale)))
    h = max(8, int(round(full.height * scale)))
    return full.resized(w, h)


def _area_resize(img: np.ndarray, w: int, h: int) -> np.ndarray:
    return cv2.resize(img, (w, h), interpolation=cv2.INTER_AREA)


def _resize_depth(depth: np.ndarray, w: int, h: int) -> np.ndarray:
    """Downsample depth without mixing invalid (0) pixels into valid ones."""
    if depth.shape == (h, w):
        return depth
    valid = (depth > 0).astype(np.float32)
    num = cv2.resize(depth * valid, (w, h), interpolation=cv2.INTER_AREA)
    den = cv2.resize(valid, (w, h), interpolation=cv2.INTER_AREA)
    out = np.where(den > 0.999, num / np.maximum(den, 1e-6), 0.0)
    return out.astype(np.float32)


def load_frame(seq: SequenceView, i: int, cam: Intrinsics, cfg: SlamConfig, want_events: bool,
               device: torch.device) -> FrameObs:
    """Read frame ``i`` of ``seq`` and prepare it at the resolution of ``cam``."""
    w, h = cam.width, cam.height
    rgb = seq.rgb(i).astype(np.float32) / 255.0
    depth = seq.depth(i).astype(np.float32)
    if rgb.shape[:2] != (h, w):
        rgb = _area_resize(rgb, w, h)
        depth = _resize_depth(depth, w, h)
    t0, t1 = (int(v) for v in seq.exposure(i))
    blur = cfg.method.blur_model
    n_events = 0
    event_maps = None
    if blur:
        has_events = seq.has_events
        ev_t = seq.events.window(t0, t1 + 1).t if has_events else np.zeros(0, np.int64)
        n_events = len(ev_t)
        fr = subpose_fractions(ev_t, t0, t1, cfg.n_segments)
        if want_events:
            if has_events and n_events > 0:
                maps = seq.event_maps(i, segment_edges_us(fr, t0, t1)).astype(np.float32)
            else:
                maps = np.zeros((cfg.n_segments, seq.height, seq.width), np.float32)
            if maps.shape[1:] != (h, w):
                # Area mean: the log change of an area-averaged pixel is about the mean of the
                # log changes of its sub-pixels, i.e. theta x the mean polarity sum.
                maps = np.stack([_area_resize(m, w, h) for m in maps])
            event_maps = torch.from_numpy(maps).to(device)
    else:
        fr = np.array([1.0])
    events = _Exposure(np.asarray(fr, dtype=np.float64), event_maps, n_events)
    return _observation(i, rgb, depth, events, cfg, cfg.budget.edge_blocks, device)


@dataclass(frozen=True)
class _Exposure:
    """What a frame's observation holds about its exposure (see :class:`FrameObs`)."""

    fractions: np.ndarray
    event_maps: torch.Tensor | None
    n_events: int


def _observation(i: int, rgb: np.ndarray, depth: np.ndarray, exposure: _Exposure,
                 cfg: SlamConfig, edge_blocks: int | None, device: torch.device) -> FrameObs:
    """A :class:`FrameObs` from host images at their resolution: rgb [H, W, 3] float32,
    depth [H, W] metres; the masks follow from them."""
    rgb_t = torch.from_numpy(np.ascontiguousarray(rgb)).to(device)
    depth_t = torch.from_numpy(np.ascontiguousarray(depth)).to(device)
    edge = None
    if cfg.loss.use_edge_mask:
        edge = torch.from_numpy(edge_mask(rgb, cfg.loss.edge_threshold, edge_blocks)).to(device)
    return FrameObs(
        index=i, rgb=rgb_t, depth=depth_t,
        rgb_mask=rgb_boundary_mask(rgb_t, cfg.loss.rgb_boundary_threshold),
        depth_mask=depth_valid_mask(depth_t), edge_weight=edge,
        fractions=exposure.fractions, event_maps=exposure.event_maps,
        n_events=exposure.n_events,
    )


def coarse_observation(obs: FrameObs, cam: Intrinsics, cfg: SlamConfig,
                       edge_blocks: int | None, segments: int | None = None) -> FrameObs:
    """``obs`` at the lower resolution of ``cam``, made the way the internal resolution is
    made from the sequence's: colour and event maps area-averaged, depth averaged over valid
    pixels only, the masks recomputed (the edge mask on a grid of ``edge_blocks``).

    ``segments``: the exposure segments of the coarse level (None: those of ``obs``); with
    fewer, it keeps the sub-poses :func:`~egs_bench.slam.levels.kept_subposes` picks, and each
    of its event maps is the sum of the maps of the segments it spans."""
    w, h = cam.width, cam.height
    rgb = _area_resize(obs.rgb.cpu().numpy(), w, h)
    depth = _resize_depth(obs.depth.cpu().numpy(), w, h)
    keep = kept_subposes(len(obs.fractions) - 1, segments)
    maps = None
    if obs.event_maps is not None:
        host = obs.event_maps.cpu().numpy()
        merged = [host[a:b].sum(0) for a, b in zip(keep[:-1], keep[1:], strict=True)]
        maps = torch.from_numpy(np.stack([_area_resize(m, w, h) for m in merged])).to(
            obs.event_maps.device)
    return _observation(obs.index, rgb, depth,
                        _Exposure(obs.fractions[keep], maps, obs.n_events),
                        cfg, edge_blocks, obs.rgb.device)


@dataclass
class FrameState:
    """Estimated exposure trajectory and exposure compensation of a frame.

    Poses are world-to-camera float64 numpy [4, 4] on the host (the SLAM's pose algebra runs
    there; see :mod:`egs_bench.slam.tracker`).
    """

    index: int
    pose0_cw: np.ndarray
    pose1_cw: np.ndarray
    exp_a: float = 0.0
    exp_b: float = 0.0
