"""Numba kernels for the per-pixel ESIM crossing loop (used by :mod:`egs_bench.datasets.esim`).

Hand-written because no maintained library offers an event simulator on the CPU with the
semantics we need (esim_py needs a C++ build and has no threshold map; esim_torch needs CUDA;
v2e places events on a global time grid instead of at each pixel's crossing time).

All arrays are flat over pixels (index ``y * width + x``). Log-brightness is float64.
The two passes (:func:`crossing_offsets`, :func:`emit_crossings`) share one formula for the
number of crossings, so they always agree:

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
def crossing_offsets(
    log_new: np.ndarray, ref: np.ndarray, pos_thr: np.ndarray, neg_thr: np.ndarray
) -> np.ndarray:
    """Where each pixel's crossings start in the output, from the number of crossings.

    Args:
        log_new: [P] float64, log-brightness at the new sample.
        ref: [P] float64, per-pixel reference level (last crossing).
        pos_thr, neg_thr: [P] float64, per-pixel thresholds (> 0).

    Returns:
        [P + 1] int64: pixel i has ``offsets[i + 1] - offsets[i]`` crossings; ``offsets[P]`` is
        the total.
    """
    n_pix = log_new.shape[0]
    offsets = np.empty(n_pix + 1, dtype=np.int64)
    total = np.int64(0)
    for i in range(n_pix):
        offsets[i] = total
        diff = log_new[i] - ref[i]
        if diff > 0.0:
            total += np.int64(np.floor((diff + CROSSING_TOLERANCE) / pos_thr[i]))
        elif diff < 0.0:
            total += np.int64(np.floor((-diff + CROSSING_TOLERANCE) / neg_thr[i]))
    offsets[n_pix] = total
    return offsets


@njit(cache=True)
def emit_crossings(
    log_old: np.ndarray,
    log_new: np.ndarray,
    ref: np.ndarray,
    pos_thr: np.ndarray,
    neg_thr: np.ndarray,
    last_event_us: np.ndarray,
    offsets: np.ndarray,
    t_old_us: np.int64,
    dt_us: np.int64,
    refractory_us: np.int64,
    width: np.int64,
    out_x: np.ndarray,
    out_y: np.ndarray,
    out_dt: np.ndarray,
    out_pol: np.ndarray,
    out_keep: np.ndarray,
) -> None:
    """Write every crossing of the interval and move the references (in place).

    The k-th crossing (k = 1..n) of pixel i lies at level ``ref + k * s * C`` (s = ±1); its time
    is found by linear interpolation of log-brightness between the two samples and rounded to
    the nearest microsecond, then clamped into ``(t_old, t_old + dt]``. An event is kept unless
    it follows the pixel's previous *kept* event by less than ``refractory_us``; the reference
    moves past every crossing, kept or not (ESIM semantics). Output is pixel by pixel, each
    pixel's crossings in time order.

    Args:
        log_old, log_new: [P] float64 log-brightness at the previous / new sample.
        ref: [P] float64 references, updated in place.
        pos_thr, neg_thr: [P] float64 thresholds.
        last_event_us: [P] int64 time of each pixel's last kept event, updated in place.
        offsets: [P + 1] int64 from :func:`crossing_offsets`.
        t_old_us, dt_us: interval start (µs) and length (µs, > 0).
        refractory_us: refractory period (µs, >= 0).
        width: image width (pixel i is at x = i % width, y = i // width).
        out_x, out_y, out_dt, out_pol, out_keep: [offsets[P]] outputs: column and row (uint16),
            time after ``t_old_us`` in µs (int64, in [1, dt_us]), polarity (int8), kept (bool).
    """
    n_pix = log_new.shape[0]
    dt_f = np.float64(dt_us)
    for i in range(n_pix):
        j = offsets[i]
        n = offsets[i + 1] - j
        if n == 0:
            continue
        row = i // width
        col = i - row * width
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
            out_x[j] = col
            out_y[j] = row
            out_dt[j] = dt_event
            out_pol[j] = pol
            out_keep[j] = keep
            j += 1
        ref[i] = base + n * step
        last_event_us[i] = last


@njit(cache=True)
def counting_sort_by_time(
    sig_x: np.ndarray,
    sig_y: np.ndarray,
    sig_dt: np.ndarray,
    sig_pol: np.ndarray,
    sig_keep: np.ndarray,
    noise_x: np.ndarray,
    noise_y: np.ndarray,
    noise_dt: np.ndarray,
    noise_pol: np.ndarray,
    dt_us: np.int64,
    t_old_us: np.int64,
    out_x: np.ndarray,
    out_y: np.ndarray,
    out_t: np.ndarray,
    out_p: np.ndarray,
) -> None:
    """Merge kept crossings and noise events into (t, y, x) order with a stable counting sort.

    O(N + dt_us). Both inputs must be in pixel (y, x) order, as :func:`emit_crossings` writes
    the crossings; the two are merged by pixel on the fly (crossing first on equal pixels) and
    then bucketed by time, which keeps pixel order within each microsecond.

    Args:
        sig_x, sig_y, sig_dt, sig_pol, sig_keep: [N] crossings from :func:`emit_crossings`.
        noise_x, noise_y, noise_dt, noise_pol: [M] noise events (uint16, uint16, int64, int8).
        dt_us: interval length (µs); every time offset lies in [1, dt_us].
        t_old_us: interval start (µs), added to the offsets.
        out_x, out_y, out_t, out_p: [kept N + M] outputs (uint16, uint16, int64, int8).
    """
    start = np.zeros(dt_us + 2, dtype=np.int64)
    for j in range(sig_dt.shape[0]):
        if sig_keep[j]:
            start[sig_dt[j] + 1] += 1
    for j in range(noise_dt.shape[0]):
        start[noise_dt[j] + 1] += 1
    for d in range(1, dt_us + 2):
        start[d] += start[d - 1]
    n_sig = sig_dt.shape[0]
    n_noise = noise_dt.shape[0]
    a = 0
    b = 0
    while a < n_sig or b < n_noise:
        take_signal = b >= n_noise or (
            a < n_sig
            and (sig_y[a] < noise_y[b] or (sig_y[a] == noise_y[b] and sig_x[a] <= noise_x[b]))
        )
        if take_signal:
            if sig_keep[a]:
                d = sig_dt[a]
                k = start[d]
                start[d] = k + 1
                out_x[k] = sig_x[a]
                out_y[k] = sig_y[a]
                out_t[k] = t_old_us + d
                out_p[k] = sig_pol[a]
            a += 1
        else:
            d = noise_dt[b]
            k = start[d]
            start[d] = k + 1
            out_x[k] = noise_x[b]
            out_y[k] = noise_y[b]
            out_t[k] = t_old_us + d
            out_p[k] = noise_pol[b]
            b += 1
