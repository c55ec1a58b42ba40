"""EDI: the Event-based Double Integral (Pan et al., CVPR 2019, "Bringing a blurry frame alive
at high frame-rate with an event camera").

Model (all in **linear** intensity; events are changes of ``log(Y + eps)`` with ``Y`` the BT.601
luma of linear RGB, as the simulator of :mod:`egs_bench.datasets.esim` makes them):

* a blurred frame is the time average of the latent image over its exposure,
  ``B = (1/T) ∫_{t_s}^{t_e} Y(t) dt``;
* between events the latent image is constant; every event of polarity ``±1`` at a pixel
  multiplies ``Y + eps`` there by ``exp(±c±)``, so with ``A(t)`` the sum of ``+c+`` / ``-c-``
  over the pixel's events in ``(t_s, t]``: ``Y(t) + eps = (Y(f) + eps) exp(A(t) - A(f))``;
* hence the latent image at a reference time ``f``:
  ``Y(f) + eps = (B + eps) / Φ`` with ``Φ = (1/T) ∫_{t_s}^{t_e} exp(A(t) - A(f)) dt``.

``Φ`` is evaluated **exactly** (``A`` is piecewise constant between a pixel's events, so the
integral is a sum over the inter-event intervals), vectorised over all events of the exposure
with one sort, cumulative sums and ``np.bincount``; no time discretisation. The reference time
is the exposure end (egs-bench's sharp ground truth, depth and pose are taken there).

Colour: the same ratio is applied to each linear channel, ``C(f) = (C_blur + eps) / Φ - eps``
(exact for grey pixels; the events carry no colour). Pixels saturated in the blurred frame are
not recoverable (their true average is unknown): they go through the same formula, so there
the output is a lower bound.

**Choosing c.** As in Pan et al., the contrast threshold ``c`` (``c+ = c``,
``c- = c · neg/pos`` when the sequence states different thresholds) is chosen per frame by
minimising an energy of the latent image over a range of ``c``: a coarse grid (robust against
local minima) refined by bounded golden-section search (the authors' MATLAB uses Fibonacci
search). The energy is ``(1 - R²(c)) + λ · TV(Y_c) / TV(B)``:

* ``1 - R²``: Pan et al. reward latent edges that coincide with the event edge map; their exact
  cross-correlation is only in obfuscated P-code, so the agreement is made precise here with
  brightness constancy: the signed events of the last moments of the exposure (the last 5 %,
  at least ``0.05 · H · W`` events) are the log-intensity change ``-δ ∇log Y(t_e) · v / c``,
  so in every 16 x 16 block (locally constant flow ``v``) they should be a linear combination
  of the two gradient components of ``log Y_c``. ``R²`` is the fraction of the event map
  that the block-wise least-squares fits explain. Too small a ``c`` leaves blurred edges, too
  large a ``c`` adds ghost edges along the motion path; both explain the events worse.
* ``λ · TV``: Pan et al.'s total-variation regulariser (normalised by the blurred frame's).
  Off by default (``λ = 0``): on egs-bench's synthetic scenes the latent image's total
  variation grows steadily with ``c`` through the true threshold (sharper textures; measured
  on ``demo-fast`` frames), with no kink there, so any ``λ > 0`` only pulled ``c`` low.

Measured on ``demo-fast`` (true ``c`` = 0.25, 40 frames, ``benchmarks/bench_edi.py``): 33
frames pick ``c`` in 0.18-0.25, the other 7 (slow, few events) 0.05-0.18; the mean PSNR
against the sharp ground truth is 0.25 dB below EDI with the true ``c`` (30.52 vs 30.78 dB;
blurred frames 25.83 dB).

References: Pan et al. CVPR 2019 (arXiv 1811.10180); ``ac-freeman/davis-EDI-rs`` (the exact
per-pixel integral, read for the formulas; no code copied).
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from egs_bench.errors import ConfigError

if TYPE_CHECKING:
    from egs_bench.datasets.sequence import Sequence


@dataclass(frozen=True)
class EdiConfig:
    """Settings of the EDI deblurring step.

    Attributes:
        c: fixed contrast threshold (log units) instead of the per-frame search; ``None``
            searches (the paper's method).
        c_min, c_max: search range of ``c`` (log units).
        grid: number of grid points of the coarse search.
        refine: refine the best grid point by golden-section search.
        tv_weight: ``λ``, weight of the total-variation term of the energy (0 = off).
        edge_fraction: the event edge map holds the events of the last ``edge_fraction`` of
            the exposure, ...
        edge_min_events: ... but at least ``edge_min_events · H · W`` events.
        block: block size (pixels) of the brightness-constancy fits.
    """

    c: float | None = None
    c_min: float = 0.05
    c_max: float = 0.6
    grid: int = 12
    refine: bool = True
    tv_weight: float = 0.0
    edge_fraction: float = 0.05
    edge_min_events: float = 0.05
    block: int = 16

    def __post_init__(self) -> None:
        if self.c is not None and not (np.isfinite(self.c) and self.c > 0):
            raise ConfigError(f"EDI threshold c must be a positive number, got {self.c}")
        if not (0 < self.c_min < self.c_max and np.isfinite(self.c_max)):
            raise ConfigError(f"EDI search range needs 0 < c_min < c_max, got "
                              f"[{self.c_min}, {self.c_max}]")
        if self.grid < 2:
            raise ConfigError(f"EDI grid needs at least 2 points, got {self.grid}")
        if not self.tv_weight >= 0:
            raise ConfigError(f"EDI tv_weight must be >= 0, got {self.tv_weight}")
        if not 0 < self.edge_fraction <= 1:
            raise ConfigError(f"EDI edge_fraction must be in (0, 1], got {self.edge_fraction}")
        if not self.edge_min_events >= 0:
            raise ConfigError(f"EDI edge_min_events must be >= 0, got {self.edge_min_events}")
        if self.block < 2:
            raise ConfigError(f"EDI block must be at least 2 pixels, got {self.block}")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class EdiResult:
    """One deblurred frame.

    Attributes:
        latent: latent linear RGB at the exposure end, float64 [H, W, 3] (>= 0).
        c: the threshold used (chosen or fixed), log units; ``None`` when the exposure had no
            events (the frame is returned unchanged).
        energy: the energy at ``c`` (``None`` for a fixed ``c`` or no events).
        n_events: events in the exposure.
        seconds: wall time of the deblurring.
    """

    latent: np.ndarray
    c: float | None
    energy: float | None
    n_events: int
    seconds: float


class ExposureEvents:
    """The events of one exposure, sorted by pixel once, ready to evaluate ``Φ(c)`` for many
    ``c`` (the threshold search) with one ``exp`` and one ``np.bincount`` each.

    Args:
        x, y: event pixel coordinates, [N] (column, row).
        t: event times in microseconds, [N], in time order (events outside
            ``(t_start, t_end]`` are ignored: an event at ``t_start`` changes nothing inside the
            exposure).
        p: polarities, [N], +1 / -1 (or 1 / 0).
        height, width: image size.
        t_start_us, t_end_us: the exposure window (``T = t_end - t_start > 0``).
        t_ref_us: the reference time ``f`` in ``[t_start, t_end]`` (default: ``t_end``).
    """

    def __init__(self, x: np.ndarray, y: np.ndarray, t: np.ndarray, p: np.ndarray, *,
                 height: int, width: int, t_start_us: int, t_end_us: int,
                 t_ref_us: int | None = None) -> None:
        t_ref_us = t_end_us if t_ref_us is None else t_ref_us
        if t_end_us <= t_start_us:
            raise ValueError(f"empty exposure window [{t_start_us}, {t_end_us}]")
        if not t_start_us <= t_ref_us <= t_end_us:
            raise ValueError(f"reference time {t_ref_us} outside the exposure "
                             f"[{t_start_us}, {t_end_us}]")
        self.height, self.width = int(height), int(width)
        self.span = float(t_end_us - t_start_us)
        t = np.asarray(t, dtype=np.int64)
        keep = (t > t_start_us) & (t <= t_end_us)
        self.n_events = int(keep.sum())
        n_pix = self.height * self.width
        pix = np.asarray(y, np.int64)[keep] * self.width + np.asarray(x, np.int64)[keep]
        t = t[keep]
        pos = (np.asarray(p)[keep] > 0).astype(np.int64)
        order = np.argsort(pix, kind="stable")  # events stay in time order within a pixel
        pix, t, pos = pix[order], t[order], pos[order]
        neg = 1 - pos
        first = np.ones(len(pix), dtype=bool)
        first[1:] = pix[1:] != pix[:-1]
        last = np.ones(len(pix), dtype=bool)
        last[:-1] = first[1:]
        # signed counts after each event relative to the reference time: A(t_k) - A(f) is
        # c+ (P_k - P_f) - c- (N_k - N_f) with P, N the pixel's cumulative event counts
        start = np.maximum.accumulate(np.where(first, np.arange(len(pix)), 0))
        cum_p = np.cumsum(pos)
        cum_n = np.cumsum(neg)
        cum_p = cum_p - (cum_p[start] - pos[start])
        cum_n = cum_n - (cum_n[start] - neg[start])
        before = t <= t_ref_us
        ref_p = np.bincount(pix[before], weights=pos[before], minlength=n_pix)
        ref_n = np.bincount(pix[before], weights=neg[before], minlength=n_pix)
        self._dp = cum_p - ref_p[pix]
        self._dn = cum_n - ref_n[pix]
        t_next = np.empty_like(t)
        t_next[:-1] = t[1:]
        t_next[last] = t_end_us
        self._dur = (t_next - t).astype(np.float64)
        self._pix = pix
        self._head_pix = pix[first]
        self._head_p, self._head_n = -ref_p[pix[first]], -ref_n[pix[first]]
        self._head_dur = (t[first] - t_start_us).astype(np.float64)

    def phi(self, c_pos: float, c_neg: float) -> np.ndarray:
        """``Φ = (1/T) ∫_{t_s}^{t_e} exp(A(t) - A(f)) dt`` per pixel, exactly; float64
        [H, W], exactly 1 at pixels without events.

        Args:
            c_pos, c_neg: contrast thresholds of positive / negative events (log units).
        """
        n_pix = self.height * self.width
        out = np.full(n_pix, self.span)
        if self.n_events:
            seg = np.exp(c_pos * self._dp - c_neg * self._dn) * self._dur
            head = np.exp(c_pos * self._head_p - c_neg * self._head_n) * self._head_dur
            acc = np.bincount(self._pix, weights=seg, minlength=n_pix)
            acc[self._head_pix] += head
            out[self._head_pix] = acc[self._head_pix]
        return (out / self.span).reshape(self.height, self.width)


def exposure_integral(
    x: np.ndarray, y: np.ndarray, t: np.ndarray, p: np.ndarray, *, height: int, width: int,
    t_start_us: int, t_end_us: int, t_ref_us: int, c_pos: float, c_neg: float,
) -> np.ndarray:
    """``Φ = (1/T) ∫_{t_s}^{t_e} exp(A(t) - A(f)) dt`` per pixel for one ``c`` (see
    :class:`ExposureEvents` for the arguments); float64 [H, W]."""
    return ExposureEvents(x, y, t, p, height=height, width=width, t_start_us=t_start_us,
                          t_end_us=t_end_us, t_ref_us=t_ref_us).phi(c_pos, c_neg)


def latent_from_blur(blurred_linear: np.ndarray, phi: np.ndarray, eps: float) -> np.ndarray:
    """EDI latent image ``(B + eps) / Φ - eps``, clipped at 0.

    Args:
        blurred_linear: blurred frame in linear intensity, [H, W] or [H, W, C].
        phi: the exposure integral of :func:`exposure_integral`, [H, W].
        eps: the log offset the events were generated with (the sequence's ``eps``).

    Returns:
        Latent linear image, float64, same shape as ``blurred_linear``.
    """
    b = np.asarray(blurred_linear, dtype=np.float64)
    ratio = phi if b.ndim == 2 else phi[..., None]
    return np.maximum((b + eps) / ratio - eps, 0.0)




def total_variation(img: np.ndarray) -> float:
    """Isotropic total variation ``Σ sqrt(dx² + dy²)`` (forward differences) of [H, W]."""
    dx = np.diff(img, axis=1)[:-1, :]
    dy = np.diff(img, axis=0)[:, :-1]
    return float(np.sqrt(dx * dx + dy * dy).sum())


def event_edge_map(x: np.ndarray, y: np.ndarray, p: np.ndarray, *, height: int, width: int,
                   fraction: float, min_events: float) -> np.ndarray:
    """Signed event count of the last events of an exposure, float64 [H, W].

    Args:
        x, y, p: the exposure's events in time order, [N].
        fraction: keep the last ``fraction`` of the events ...
        min_events: ... but at least ``min_events · H · W`` of them.
    """
    n = len(x)
    k = min(n, max(int(fraction * n), int(min_events * height * width), 1))
    pix = np.asarray(y[n - k:], np.int64) * width + np.asarray(x[n - k:], np.int64)
    sign = np.where(np.asarray(p[n - k:]) > 0, 1.0, -1.0)
    return np.bincount(pix, weights=sign, minlength=height * width).reshape(height, width)


def _block_sums(a: np.ndarray, block: int) -> np.ndarray:
    h, w = a.shape
    hb, wb = -(-h // block), -(-w // block)
    padded = np.zeros((hb * block, wb * block))
    padded[:h, :w] = a
    return padded.reshape(hb, block, wb, block).sum(axis=(1, 3))


def edge_consistency(log_latent: np.ndarray, edge_map: np.ndarray, block: int) -> float:
    """``1 - R²`` of block-wise least-squares fits of ``edge_map`` by ``∇ log_latent``.

    In each ``block x block`` block, ``edge_map ≈ a ∂x + b ∂y`` (Sobel derivatives of
    ``log_latent``) with the block's own ``(a, b)`` (closed-form 2x2 normal equations). Returns
    the unexplained fraction of ``Σ edge_map²``, in [0, 1] (1 when the map is empty).
    """
    import cv2

    gx = cv2.Sobel(log_latent, cv2.CV_64F, 1, 0, ksize=3)
    gy = cv2.Sobel(log_latent, cv2.CV_64F, 0, 1, ksize=3)
    m = np.asarray(edge_map, dtype=np.float64)
    sxx, syy, sxy = (_block_sums(v, block) for v in (gx * gx, gy * gy, gx * gy))
    sxm, sym, smm = (_block_sums(v, block) for v in (gx * m, gy * m, m * m))
    total = float(smm.sum())
    if total <= 0:
        return 1.0
    det = sxx * syy - sxy * sxy
    ok = det > 1e-12 * np.maximum(sxx * syy, 1e-300)
    safe = np.where(ok, det, 1.0)
    a = np.where(ok, (syy * sxm - sxy * sym) / safe, 0.0)
    b = np.where(ok, (sxx * sym - sxy * sxm) / safe, 0.0)
    explained = a * sxm + b * sym  # = fitted · m = |fitted|² for least squares
    return float(1.0 - explained.sum() / total)


def deblur_frame(
    blurred_linear: np.ndarray, x: np.ndarray, y: np.ndarray, t: np.ndarray, p: np.ndarray, *,
    t_start_us: int, t_end_us: int, eps: float, neg_to_pos: float = 1.0,
    config: EdiConfig | None = None,
) -> EdiResult:
    """EDI latent image at the exposure end, with ``c`` chosen by the energy (or fixed).

    Args:
        blurred_linear: the blurred frame in linear intensity, [H, W, 3].
        x, y, t, p: the events of the exposure ``(t_start, t_end]`` in time order, [N]
            (microseconds; polarity ±1 or 1/0). Events outside the window are ignored.
        t_start_us, t_end_us: the exposure window.
        eps: the log offset of the event model (the sequence's ``eps``).
        neg_to_pos: ``c- / c+`` (the sequence's threshold ratio).
        config: search settings (default :class:`EdiConfig`).

    Returns:
        The latent image and the chosen threshold.
    """
    from scipy.optimize import minimize_scalar

    cfg = config or EdiConfig()
    t_wall = time.perf_counter()
    blurred = np.asarray(blurred_linear, dtype=np.float64)
    if blurred.ndim != 3 or blurred.shape[2] != 3:
        raise ValueError(f"blurred frame must be [H, W, 3], got {blurred.shape}")
    height, width = blurred.shape[:2]
    t = np.asarray(t, dtype=np.int64)
    inside = (t > t_start_us) & (t <= t_end_us)
    x, y, t, p = (np.asarray(v)[inside] for v in (x, y, t, p))
    if len(t) == 0:
        return EdiResult(blurred.clip(min=0.0), None, None, 0, time.perf_counter() - t_wall)

    events = ExposureEvents(x, y, t, p, height=height, width=width, t_start_us=t_start_us,
                            t_end_us=t_end_us)

    def latent(c: float) -> np.ndarray:
        return latent_from_blur(blurred, events.phi(c, c * neg_to_pos), eps)

    if cfg.c is not None:
        return EdiResult(latent(cfg.c), float(cfg.c), None, len(t), time.perf_counter() - t_wall)

    from egs_bench.color import luma

    edges = event_edge_map(x, y, p, height=height, width=width, fraction=cfg.edge_fraction,
                           min_events=cfg.edge_min_events)
    tv_blur = total_variation(luma(blurred)) if cfg.tv_weight > 0 else 1.0

    def energy(c: float) -> float:
        lum = luma(latent(c))
        e = edge_consistency(np.log(lum + eps), edges, cfg.block)
        if cfg.tv_weight > 0 and tv_blur > 0:
            e += cfg.tv_weight * total_variation(lum) / tv_blur
        return e

    grid = np.linspace(cfg.c_min, cfg.c_max, cfg.grid)
    values = np.array([energy(c) for c in grid])
    k = int(np.argmin(values))
    best_c, best_e = float(grid[k]), float(values[k])
    if cfg.refine:
        lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
        res = minimize_scalar(energy, bounds=(lo, hi), method="bounded",
                              options={"xatol": 1e-3 * (cfg.c_max - cfg.c_min)})
        if res.success and res.fun < best_e:
            best_c, best_e = float(res.x), float(res.fun)
    return EdiResult(latent(best_c), best_c, best_e, len(t), time.perf_counter() - t_wall)


def deblur_sequence_frame(seq: Sequence, index: int, config: EdiConfig | None = None
                          ) -> tuple[np.ndarray, EdiResult]:
    """EDI of frame ``index`` of an opened :class:`~egs_bench.datasets.sequence.Sequence`.

    The stored 8-bit frame is decoded to linear intensity with the sequence's camera response
    (``meta.yaml`` ``crf``; sRGB when absent), deblurred with the events of its exposure, the
    sequence's ``eps`` and threshold ratio, and encoded back with the same response.

    Returns:
        The deblurred frame (uint8 [H, W, 3], sRGB like the input) and the :class:`EdiResult`.
    """
    from egs_bench.color import LdrResponse

    response = LdrResponse.from_dict(seq.meta.get("crf") or {})
    t0, t1 = seq.exposure(index)
    events = seq.events.window(t0 + 1, t1 + 1) if seq.has_events else None
    blurred = response.inverse(seq.rgb(index))
    if events is None or len(events) == 0:
        return seq.rgb(index), EdiResult(blurred.astype(np.float64), None, None, 0, 0.0)
    result = deblur_frame(blurred, events.x, events.y, events.t, events.p, t_start_us=t0,
                          t_end_us=t1, eps=seq.eps,
                          neg_to_pos=seq.neg_threshold / seq.pos_threshold, config=config)
    return response.to_ldr(result.latent), result
