"""ESIM-style event simulation from a stream of log-brightness samples (docs/design.md §4).

Model (per pixel, following ESIM, Rebecq et al. 2018):

* The pixel keeps a reference log-brightness ``ref``, set to the first sample by
  :meth:`EventSimulator.reset`.
* Between two consecutive samples ``L0`` (at ``t0``) and ``L1`` (at ``t1``) the log-brightness
  is assumed linear in time. Each time it crosses ``ref + C+`` (``ref - C-``) the pixel emits a
  positive (negative) event at the interpolated crossing time and ``ref`` moves by exactly one
  threshold; any number of events per interval is possible, and sub-threshold change stays in
  ``ref`` for the next interval.
* Time stamps are the crossing time rounded to the nearest integer microsecond, clamped into
  ``(t0, t1]``. Output is sorted by ``(t, y * width + x)`` (stable; deterministic).

Options, all off by default (the no-event loss of EGS-SLAM assumes clean silent pixels):

* ``sigma``: fixed per-pixel threshold mismatch. Two maps ``C+ ~ N(pos_threshold, sigma)`` and
  ``C- ~ N(neg_threshold, sigma)`` are drawn once per simulator from ``seed`` and clamped at
  ``>= 0.01``.
* ``refractory_us``: an event that follows the pixel's previous *emitted* event by less than
  this is dropped, but the reference still moves past its level (ESIM semantics), so the
  dropped change is lost for good and not emitted later.
* ``noise_rate_hz``: shot-noise (background activity) events, an independent Poisson process
  per pixel with this total rate, polarity ±1 with probability 1/2 each, time uniform in the
  interval (integer µs). Noise events do not touch the reference or the refractory state.

Memory does not grow with sequence length: the simulator holds O(H·W) state and each
:meth:`EventSimulator.step` returns only the events of the interval since the previous sample.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from egs_bench.color import luma
from egs_bench.datasets.esim_kernels import (
    NEVER_FIRED_US,
    counting_sort_by_time,
    crossing_offsets,
    emit_crossings,
)
from egs_bench.datasets.events import Events
from egs_bench.errors import ConfigError

MIN_THRESHOLD = 0.01  # lower clamp of the mismatch map (as v2e / rpg_esim)
_MAX_SIZE = 2**16  # x, y are stored as uint16


@dataclass(frozen=True)
class EventSimConfig:
    """Event camera model parameters.

    Attributes:
        pos_threshold: nominal ON contrast threshold C+ in log units (> 0).
        neg_threshold: nominal OFF contrast threshold C- in log units (> 0).
        sigma: std of the fixed per-pixel threshold mismatch (log units, >= 0; 0 = off).
        refractory_us: refractory period in microseconds (>= 0; 0 = off).
        noise_rate_hz: shot-noise event rate per pixel, both polarities together (>= 0; 0 = off).
        eps: offset in ``log(luma + eps)`` (> 0); must match the sequence metadata.
        seed: seed for the threshold map and the noise events.
    """

    pos_threshold: float = 0.25
    neg_threshold: float = 0.25
    sigma: float = 0.0
    refractory_us: int = 0
    noise_rate_hz: float = 0.0
    eps: float = 1e-3
    seed: int = 0

    def __post_init__(self) -> None:
        checks = [
            (self.pos_threshold > 0, f"pos_threshold must be > 0, got {self.pos_threshold}"),
            (self.neg_threshold > 0, f"neg_threshold must be > 0, got {self.neg_threshold}"),
            (self.sigma >= 0, f"sigma must be >= 0, got {self.sigma}"),
            (self.refractory_us >= 0, f"refractory_us must be >= 0, got {self.refractory_us}"),
            (self.noise_rate_hz >= 0, f"noise_rate_hz must be >= 0, got {self.noise_rate_hz}"),
            (self.eps > 0, f"eps must be > 0, got {self.eps}"),
        ]
        for ok, message in checks:
            # ``not ok`` also rejects NaN, for which every comparison is False.
            if not ok:
                raise ConfigError(message)
        for name in ("pos_threshold", "neg_threshold", "sigma", "noise_rate_hz", "eps"):
            if not np.isfinite(getattr(self, name)):
                raise ConfigError(f"{name} must be finite, got {getattr(self, name)}")
        if int(self.refractory_us) != self.refractory_us:
            raise ConfigError(f"refractory_us must be an integer, got {self.refractory_us}")


def linear_luma(rgb_linear: np.ndarray) -> np.ndarray:
    """BT.601 luma of a linear RGB image.

    Args:
        rgb_linear: [H, W, 3] linear intensities (any float or integer dtype).

    Returns:
        [H, W] float64 ``0.299 R + 0.587 G + 0.114 B``.
    """
    rgb = np.asarray(rgb_linear)
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"expected an [H, W, 3] image, got shape {rgb.shape}")
    return luma(rgb.astype(np.float64, copy=False))


def log_luma(rgb_linear: np.ndarray, eps: float) -> np.ndarray:
    """Log-brightness ``log(luma + eps)`` of a linear RGB image, [H, W, 3] -> [H, W] float64."""
    if not eps > 0:
        raise ValueError(f"eps must be > 0, got {eps}")
    luma = linear_luma(rgb_linear)
    if not np.all(luma + eps > 0):
        raise ValueError("luma + eps must be > 0 everywhere (negative linear intensities?)")
    return np.log(luma + eps)


class EventSimulator:
    """Stateful ESIM simulator: feed one log-brightness sample at a time.

    Usage::

        sim = EventSimulator(EventSimConfig(), height, width)
        sim.reset(log_luma(frame0, eps), t0_us)
        for frame, t_us in rest:
            events = sim.step(log_luma(frame, eps), t_us)   # events in (t_prev, t_us]
    """

    def __init__(self, config: EventSimConfig, height: int, width: int) -> None:
        if not (0 < height <= _MAX_SIZE and 0 < width <= _MAX_SIZE):
            raise ValueError(f"image size must be in 1..{_MAX_SIZE}, got {height}x{width}")
        self.config = config
        self.height = int(height)
        self.width = int(width)
        n_pix = self.height * self.width
        threshold_seed, self._noise_seed = np.random.SeedSequence(config.seed).spawn(2)
        rng = np.random.default_rng(threshold_seed)
        if config.sigma > 0:
            pos = rng.normal(config.pos_threshold, config.sigma, n_pix)
            neg = rng.normal(config.neg_threshold, config.sigma, n_pix)
            pos = np.maximum(pos, MIN_THRESHOLD)
            neg = np.maximum(neg, MIN_THRESHOLD)
        else:
            pos = np.full(n_pix, float(config.pos_threshold))
            neg = np.full(n_pix, float(config.neg_threshold))
        self._pos = pos
        self._neg = neg
        self._pos.flags.writeable = False
        self._neg.flags.writeable = False
        self._ref: np.ndarray | None = None
        self._last_log: np.ndarray | None = None
        self._last_event_us = np.full(n_pix, NEVER_FIRED_US, dtype=np.int64)
        self._t_us: int | None = None
        self._noise_rng = np.random.default_rng(self._noise_seed)

    @property
    def thresholds(self) -> tuple[np.ndarray, np.ndarray]:
        """Per-pixel (C+, C-) maps, each [H, W] float64 (read-only views)."""
        shape = (self.height, self.width)
        return self._pos.reshape(shape), self._neg.reshape(shape)

    @property
    def time_us(self) -> int | None:
        """Time of the last sample fed (µs), or None before :meth:`reset`."""
        return self._t_us

    def _flat_log(self, log_image: np.ndarray) -> np.ndarray:
        arr = np.asarray(log_image)
        if arr.shape != (self.height, self.width):
            raise ValueError(
                f"log image must have shape ({self.height}, {self.width}), got {arr.shape}"
            )
        flat = np.array(arr, dtype=np.float64, order="C", copy=True).reshape(-1)
        if not np.all(np.isfinite(flat)):
            raise ValueError("log image contains NaN or infinite values")
        return flat

    @staticmethod
    def _as_time(t_us: int) -> int:
        if isinstance(t_us, bool) or int(t_us) != t_us:
            raise ValueError(f"sample time must be an integer number of microseconds, got {t_us}")
        return int(t_us)

    def reset(self, log_image: np.ndarray, t_us: int) -> None:
        """Start a new stream at the first sample (no events).

        Sets every reference to ``log_image`` [H, W] (log units) at time ``t_us`` (µs), clears
        the refractory state and restarts the noise generator from the seed, so a reset
        simulator reproduces a fresh one exactly. The threshold maps are kept.
        """
        self._last_log = self._flat_log(log_image)
        self._ref = self._last_log.copy()
        self._last_event_us.fill(NEVER_FIRED_US)
        self._t_us = self._as_time(t_us)
        self._noise_rng = np.random.default_rng(self._noise_seed)

    def step(self, log_image: np.ndarray, t_us: int) -> Events:
        """Feed the next sample and return the events in ``(t_prev, t_us]``.

        Args:
            log_image: [H, W] log-brightness (log units) at ``t_us``.
            t_us: sample time in microseconds, strictly after the previous sample.

        Returns:
            Events sorted by (t, y * width + x).
        """
        if self._t_us is None or self._ref is None or self._last_log is None:
            raise RuntimeError("EventSimulator.step called before reset")
        t_new = self._as_time(t_us)
        if t_new <= self._t_us:
            raise ValueError(f"sample times must increase: got {t_new} us after {self._t_us} us")
        log_new = self._flat_log(log_image)
        t_old = self._t_us
        dt = t_new - t_old

        offsets = crossing_offsets(log_new, self._ref, self._pos, self._neg)
        total = int(offsets[-1])
        x = np.empty(total, np.uint16)
        y = np.empty(total, np.uint16)
        dt_ev = np.empty(total, np.int64)
        pol = np.empty(total, np.int8)
        keep = np.empty(total, np.bool_)
        emit_crossings(
            self._last_log, log_new, self._ref, self._pos, self._neg, self._last_event_us,
            offsets, np.int64(t_old), np.int64(dt), np.int64(self.config.refractory_us),
            np.int64(self.width), x, y, dt_ev, pol, keep,
        )
        noise = self._noise_events(dt)
        events = self._sorted_events((x, y, dt_ev, pol, keep), noise, t_old, dt)
        self._last_log = log_new
        self._t_us = t_new
        return events

    @staticmethod
    def _sorted_events(
        signal: tuple[np.ndarray, ...], noise: tuple[np.ndarray, ...], t_old: int, dt: int
    ) -> Events:
        """Kept crossings and noise events in (t, y, x) order (crossing first on ties).

        ``signal`` = (x, y, dt, pol, keep) as written by :func:`emit_crossings` (pixel order);
        ``noise`` = (x, y, dt, pol) in pixel order. Times are offsets from ``t_old`` in µs.
        """
        sig_x, sig_y, sig_dt, sig_pol, sig_keep = signal
        n_out = int(np.count_nonzero(sig_keep)) + len(noise[0])
        if dt <= 4 * n_out + 2**16:
            # Counting sort over the interval's microseconds: O(N + dt), no comparisons.
            out = Events(np.empty(n_out, np.uint16), np.empty(n_out, np.uint16),
                         np.empty(n_out, np.int64), np.empty(n_out, np.int8))
            counting_sort_by_time(*signal, *noise, np.int64(dt), np.int64(t_old),
                                  out.x, out.y, out.t, out.p)
            return out
        # Long interval with few events: a comparison sort is cheaper.
        x = np.concatenate([sig_x[sig_keep], noise[0]])
        y = np.concatenate([sig_y[sig_keep], noise[1]])
        dts = np.concatenate([sig_dt[sig_keep], noise[2]])
        pol = np.concatenate([sig_pol[sig_keep], noise[3]])
        # lexsort is stable and crossings come first: they precede noise on equal (t, y, x).
        order = np.lexsort((x, y, dts))  # last key is the primary one
        return Events(x[order], y[order], dts[order] + t_old, pol[order])

    def _noise_events(self, dt_us: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Shot-noise events of one interval, in pixel order (empty when the rate is 0).

        One Poisson count for the whole sensor with uniform pixel choice is the same process as
        independent per-pixel Poisson processes of rate ``noise_rate_hz`` (Poisson thinning).

        Returns:
            x, y (uint16), time after the interval start in µs (int64, in [1, dt_us]),
            polarity (int8), each [M].
        """
        n_pix = self.height * self.width
        n = 0
        if self.config.noise_rate_hz > 0:
            rng = self._noise_rng
            n = int(rng.poisson(self.config.noise_rate_hz * n_pix * dt_us * 1e-6))
        if n == 0:
            return (np.zeros(0, np.uint16), np.zeros(0, np.uint16), np.zeros(0, np.int64),
                    np.zeros(0, np.int8))
        pix = rng.integers(0, n_pix, size=n, dtype=np.int64)
        dt_ev = rng.integers(1, dt_us + 1, size=n, dtype=np.int64)
        pol = np.where(rng.random(n) < 0.5, 1, -1).astype(np.int8)
        order = np.argsort(pix, kind="stable")
        pix = pix[order]
        return ((pix % self.width).astype(np.uint16), (pix // self.width).astype(np.uint16),
                dt_ev[order], pol[order])


def simulate(
    log_images: Iterable[np.ndarray],
    times_us: Iterable[int],
    config: EventSimConfig,
    height: int,
    width: int,
) -> Events:
    """Simulate a whole stream: the first sample resets, every later one steps.

    Args:
        log_images: iterable of [H, W] log-brightness samples (consumed lazily).
        times_us: matching sample times in µs, strictly increasing.
        config, height, width: as for :class:`EventSimulator`.

    Returns:
        All events, sorted by (t, pixel). Raises ValueError if the two iterables differ in
        length or are empty.
    """
    sim = EventSimulator(config, height, width)
    batches: list[Events] = []
    first = True
    images = iter(log_images)
    times = iter(times_us)
    sentinel: Any = object()
    while True:
        image = next(images, sentinel)
        t_us = next(times, sentinel)
        if image is sentinel and t_us is sentinel:
            break
        if image is sentinel or t_us is sentinel:
            raise ValueError("log_images and times_us have different lengths")
        if first:
            sim.reset(image, t_us)
            first = False
        else:
            batches.append(sim.step(image, t_us))
    if first:
        raise ValueError("simulate needs at least one sample")
    return Events.concatenate(batches)
