"""Numba kernels for the per-pixel ESIM crossing loop (used by :mod:`egs_bench.datasets.esim`).

Hand-written because no maintained library offers an event simulator on the CPU with the
semantics we need (esim_py needs a C++ build and has no threshold map; esim_torch needs CUDA;
v2e places events on a global time grid instead of at each pixel's crossing time).

All arrays are flat over pixels (index ``y * width + x``). Log-brightness is float64.
The two passes share one formula for the number of crossings, so they always agree:

    n = floor((|L1 - ref| + CROSSING_TOLERANCE) / C),   C = pos or neg threshold of the pixel

``CROSSING_TOLERANCE`` makes a change of exactly ``n * C`` (up to float rounding) yield ``n``
events instead of ``n - 1`` depending on the last bit.
"""

from __future__ import annotations

import numpy as np
from numba import njit

# Absolute tolerance in log units; far below any physical threshold (>= 0.01).
CROSSING_TOLERANCE = 1e-9

# "Has never fired" marker for the refractory check; far enough from any real time stamp that
# ``t - NEVER_FIRED_US`` cannot overflow int64 for realistic times.
NEVER_FIRED_US = np.int64(-(2**62))


@njit(cache=True)
def count_crossings(
    log_new: np.ndarray, ref: np.ndarray, pos_thr: np.ndarray, neg_thr: np.ndarray
) -> np.ndarray:
    """Number of threshold crossings per pixel between ``ref`` and ``log_new``.

    Args:
        log_new: [P] float64, log-brightness at the new sample.
        ref: [P] float64, per-pixel reference level (last crossing).
        pos_thr, neg_thr: [P] float64, per-pixel thresholds (> 0).

    Returns:
        [P] int64 counts.
    """
    n_pix = log_new.shape[0]
    counts = np.zeros(n_pix, dtype=np.int64)
    for i in range(n_pix):
        diff = log_new[i] - ref[i]
        if diff > 0.0:
            counts[i] = np.int64(np.floor((diff + CROSSING_TOLERANCE) / pos_thr[i]))
        elif diff < 0.0:
            counts[i] = np.int64(np.floor((-diff + CROSSING_TOLERANCE) / neg_thr[i]))
    return counts


@njit(cache=True)
def emit_crossings(
    log_old: np.ndarray,
    log_new: np.ndarray,
    ref: np.ndarray,
    pos_thr: np.ndarray,
    neg_thr: np.ndarray,
    last_event_us: np.ndarray,
    counts: np.ndarray,
    offsets: np.ndarray,
    t_old_us: np.int64,
    dt_us: np.int64,
    refractory_us: np.int64,
    out_pix: np.ndarray,
    out_dt: np.ndarray,
    out_pol: np.ndarray,
    out_keep: np.ndarray,
) -> None:
    """Write every crossing of the interval and move the references (in place).

    The k-th crossing (k = 1..n) of pixel i lies at level ``ref + k * s * C`` (s = ±1); its time
    is found by linear interpolation of log-brightness between the two samples and rounded to
    the nearest microsecond, then clamped into ``(t_old, t_old + dt]``. An event is kept unless
    it follows the pixel's previous *kept* event by less than ``refractory_us``; the reference
    moves past every crossing, kept or not (ESIM semantics).

    Args:
        log_old, log_new: [P] float64 log-brightness at the previous / new sample.
        ref: [P] float64 references, updated in place.
        pos_thr, neg_thr: [P] float64 thresholds.
        last_event_us: [P] int64 time of each pixel's last kept event, updated in place.
        counts: [P] int64 from :func:`count_crossings`; offsets: [P] int64 exclusive prefix sum.
        t_old_us, dt_us: interval start (µs) and length (µs, > 0).
        refractory_us: refractory period (µs, >= 0).
        out_pix, out_dt, out_pol, out_keep: [sum(counts)] outputs: pixel index (int64), time
            after ``t_old_us`` in µs (int64, in [1, dt_us]), polarity (int8), kept flag (bool).
    """
    n_pix = log_new.shape[0]
    dt_f = np.float64(dt_us)
    for i in range(n_pix):
        n = counts[i]
        if n == 0:
            continue
        l0 = log_old[i]
        span = log_new[i] - l0
        if log_new[i] > ref[i]:
            step = pos_thr[i]
            pol = np.int8(1)
        else:
            step = -neg_thr[i]
            pol = np.int8(-1)
        base = ref[i]
        last = last_event_us[i]
        j = offsets[i]
        for k in range(1, n + 1):
            level = base + k * step
            if span != 0.0:
                frac = (level - l0) / span
            else:
                frac = 1.0
            frac = min(max(frac, 0.0), 1.0)
            dt_event = np.int64(np.floor(frac * dt_f + 0.5))
            dt_event = min(max(dt_event, np.int64(1)), dt_us)
            t_event = t_old_us + dt_event
            keep = t_event - last >= refractory_us
            if keep:
                last = t_event
            out_pix[j] = i
            out_dt[j] = dt_event
            out_pol[j] = pol
            out_keep[j] = keep
            j += 1
        ref[i] = base + n * step
        last_event_us[i] = last
