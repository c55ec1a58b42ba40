"""Tile kernels of the CPU backend (numba): binning, forward compositing, hand-written backward.

Why hand-written: no maintained library composites Gaussians on a CPU (gsplat's rasteriser is
CUDA-only, taichi-splatting's kernels are GPU-only, warp's autodiff gets the compositing loop
wrong; see ``research/rasterizer.md``). The kernels implement the rule of
:mod:`egs_bench.render.constants`:

* ``bin_tiles``: per camera, append each Gaussian to the 16x16 tiles its ``alpha >= 1/255``
  box touches, then sort each tile's list by depth (stable, so ties keep the id order), as
  integer keys of :func:`depth_order_keys`: a radix sort, linear in the list's length (a
  merge sort of the float depths took 80 % of the binning on a 488k-Gaussian map).
* ``raster_fwd``: parallel over (camera, tile); every Gaussian is evaluated only on the pixels
  of each row where its ``alpha >= 1/255`` ellipse lies (exact span from the conic, then the
  alpha test as usual), clipped to the tile.
* ``raster_bwd``: replays each pixel back to front from its last contributor, recovering the
  transmittance by division (``alpha <= 0.99``). Each (tile, Gaussian) pair writes its own
  gradient row, so there are no atomics and results are deterministic; ``reduce_rows`` then sums
  rows per Gaussian in a fixed order.

Inputs may be float32 or float64; the arithmetic inside the kernels is float64.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

TILE = 16  # must equal constants.TILE_SIZE (kept literal so numba sees a compile-time constant)
NGRAD = 10  # gradient row: mx, my, a, b, c, r, g, b, opacity, depth
SPAN_PAD = 1e-3  # px: widens the exact row span so rounding never drops a boundary pixel


@njit(inline="always")
def _box(mx, my, rx, ry, W, H):
    """Pixel index box whose centres lie within ``(mx +- rx, my +- ry)``, clipped to the
    image; ok=False when empty or culled (rx < 0)."""
    if not (rx > 0.0):
        return False, 0, 0, 0, 0
    fu0 = min(max(math.ceil(mx - rx - 0.5), -1.0), W)
    fu1 = min(max(math.floor(mx + rx - 0.5), -1.0), W)
    fv0 = min(max(math.ceil(my - ry - 0.5), -1.0), H)
    fv1 = min(max(math.floor(my + ry - 0.5), -1.0), H)
    if fu0 > fu1 or fv0 > fv1 or fu0 > W - 1 or fu1 < 0 or fv0 > H - 1 or fv1 < 0:
        return False, 0, 0, 0, 0
    return (True, int(max(fu0, 0.0)), int(min(fu1, W - 1.0)), int(max(fv0, 0.0)),
            int(min(fv1, H - 1.0)))


@njit(inline="always")
def _row_span(dy, ca, cb, cc, m2, mx, u0, u1):
    """Pixels ``[ua, ub]`` of one row (offset ``dy`` from the centre) inside the ellipse
    ``a dx^2 + 2 b dx dy + c dy^2 <= m2``, intersected with ``[u0, u1]``; empty if ua > ub."""
    bdy = cb * dy
    disc = bdy * bdy - ca * (cc * dy * dy - m2)
    if disc < 0.0:
        return 1, 0
    s = math.sqrt(disc)
    lo = mx + (-bdy - s) / ca - 0.5 - SPAN_PAD
    hi = mx + (-bdy + s) / ca - 0.5 + SPAN_PAD
    ua = u0 if lo < u0 else int(math.ceil(lo))
    ub = u1 if hi > u1 else int(math.floor(hi))
    return ua, ub


# A Gaussian whose clipped box holds no pixel it could still change composites nothing, so the
# two checks below skip it before its row spans and exponentials and leave every output bit as
# it was. On a 488k-Gaussian map they save a tenth of the compositing at a quarter of 448x256
# (a tile's list there holds thousands of Gaussians behind pixels that are already opaque).

@njit(inline="always")
def _box_open(done, u0, u1, v0, v1, px0, py0):
    """Forward: whether a pixel of box ``[u0, u1] x [v0, v1]`` of the tile at ``(px0, py0)``
    is not yet done (``done``: the tile's flags, row-major 16 x 16)."""
    for v in range(v0, v1 + 1):
        row = (v - py0) * TILE - px0
        for u in range(u0, u1 + 1):
            if not done[row + u]:
                return True
    return False


@njit(inline="always")
def _box_reached(last, j, u0, u1, v0, v1, px0, py0):
    """Backward: whether intersection ``j`` lies at or before the last contributor of a pixel
    of the box (``last``: the tile's last-contributor indices, row-major 16 x 16)."""
    for v in range(v0, v1 + 1):
        row = (v - py0) * TILE - px0
        for u in range(u0, u1 + 1):
            if j <= last[row + u]:
                return True
    return False


RADIX_BITS = 11  # bits per pass of the tile sort: 3 passes for 32-bit keys, 6 for 64-bit
SMALL_TILE = 32  # lists up to this length are insertion-sorted (a radix pass clears 2^11 bins)


def depth_order_keys(depth: np.ndarray) -> np.ndarray:
    """Unsigned integers that order as the depths do: float32 -> uint32, float64 -> uint64.

    The IEEE bit pattern read as an unsigned integer orders the non-negative floats; negative
    ones get all bits flipped and the others the sign bit set, so every non-NaN value keeps its
    place. ``-0.0`` is folded onto ``+0.0`` first, so the two tie as a float comparison says.
    """
    folded = depth + depth.dtype.type(0.0)  # -0.0 + 0.0 = +0.0
    bits = folded.view(np.uint32 if depth.dtype == np.float32 else np.uint64)
    sign = bits.dtype.type(1) << bits.dtype.type(8 * bits.dtype.itemsize - 1)
    return np.where(bits & sign, ~bits, bits | sign)


@njit(inline="always")
def _sort_by_keys(ids, keys, nbits):
    """``ids`` [n] ordered by ``keys`` [n] (unsigned), stably; returns the sorted ids (the
    input arrays are reused as scratch). Insertion sort for short lists, else a least
    significant digit radix sort (stable by construction)."""
    n = ids.shape[0]
    if n <= SMALL_TILE:
        for i in range(1, n):
            key = keys[i]
            gid = ids[i]
            j = i - 1
            while j >= 0 and keys[j] > key:
                keys[j + 1] = keys[j]
                ids[j + 1] = ids[j]
                j -= 1
            keys[j + 1] = key
            ids[j + 1] = gid
        return ids
    nbins = 1 << RADIX_BITS
    mask = nbins - 1
    ids_out = np.empty_like(ids)
    keys_out = np.empty_like(keys)
    start = np.empty(nbins + 1, np.int64)
    for shift in range(0, nbits, RADIX_BITS):
        start[:] = 0
        for i in range(n):
            start[((keys[i] >> shift) & mask) + 1] += 1
        for b in range(nbins):
            start[b + 1] += start[b]
        for i in range(n):
            digit = (keys[i] >> shift) & mask
            pos = start[digit]
            start[digit] = pos + 1
            keys_out[pos] = keys[i]
            ids_out[pos] = ids[i]
        keys, keys_out = keys_out, keys
        ids, ids_out = ids_out, ids
    return ids


@njit(cache=True, parallel=True)
def bin_tiles(mean2d, ext, depth_keys, W, H):
    """Depth-sorted tile lists for C cameras.

    Args: mean2d [C,N,2], ext [C,N,2] (negative = culled), depth_keys [C,N] the camera z's
    :func:`depth_order_keys` (uint32 or uint64).
    Returns: isect [M] int32 Gaussian ids and offsets [C*T+1] int64; tile ``kt = k*T + t``
    owns ``isect[offsets[kt]:offsets[kt+1]]``, sorted by depth, ties by Gaussian id: the order
    of a stable sort of all N depths, restricted to the tile. Sorting each tile's list (a
    counting sort into tiles in id order, then a stable sort per tile) instead of all N
    Gaussians per camera skips the culled ones and runs in parallel over tiles.
    """
    nbits = 8 * depth_keys.itemsize
    C, N = depth_keys.shape
    TX = (W + TILE - 1) // TILE
    TY = (H + TILE - 1) // TILE
    T = TX * TY
    counts = np.zeros(C * T, np.int64)
    for k in prange(C):
        for g in range(N):
            ok, u0, u1, v0, v1 = _box(mean2d[k, g, 0], mean2d[k, g, 1], ext[k, g, 0],
                                      ext[k, g, 1], W, H)
            if ok:
                for ty in range(v0 // TILE, v1 // TILE + 1):
                    for tx in range(u0 // TILE, u1 // TILE + 1):
                        counts[k * T + ty * TX + tx] += 1
    offsets = np.zeros(C * T + 1, np.int64)
    offsets[1:] = np.cumsum(counts)
    isect = np.empty(offsets[-1], np.int32)
    fill = offsets[:-1].copy()
    for k in prange(C):
        for g in range(N):
            ok, u0, u1, v0, v1 = _box(mean2d[k, g, 0], mean2d[k, g, 1], ext[k, g, 0],
                                      ext[k, g, 1], W, H)
            if ok:
                for ty in range(v0 // TILE, v1 // TILE + 1):
                    for tx in range(u0 // TILE, u1 // TILE + 1):
                        kt = k * T + ty * TX + tx
                        isect[fill[kt]] = g
                        fill[kt] += 1
    for kt in prange(C * T):
        start = offsets[kt]
        n = offsets[kt + 1] - start
        if n > 1:
            k = kt // T
            ids = isect[start:start + n].copy()
            keys = np.empty(n, depth_keys.dtype)
            for i in range(n):
                keys[i] = depth_keys[k, ids[i]]
            isect[start:start + n] = _sort_by_keys(ids, keys, nbits)  # ties keep id order
    return isect, offsets


@njit(cache=True, parallel=True, fastmath=True)
def raster_fwd(mean2d, conic, depth, opac, m2s, colors, ext, isect, offsets, W, H,
               out_rgb, out_depth, out_T, out_last, touch, blends, consts, centre):
    """Forward compositing. Writes rgb [C,H,W,3], depth [C,H,W] (data dtype), final
    transmittance [C,H,W] (float64, for the backward), index into ``isect`` of each pixel's
    last contributor [C,H,W] (-1: none), per intersection the number of pixels it touched
    with the transmittance after it above TOUCH_T, and per camera tile [C * tiles] the number
    of Gaussian-pixel blends it composited (the work accounting's unit,
    :mod:`egs_bench.render.work`).

    Arithmetic is float64 whatever the data dtype. ``exp(power)`` along a row comes from the
    recurrence ``G(u+1) = G(u) E(u)``, ``E(u+1) = E(u) exp(-a)`` (power is quadratic in u):
    two exps per row instead of one per pixel (exp was 60 % of the kernel's time; the
    recurrence error is < 16^2 ulp of float64). ``raster_bwd`` repeats it bit for bit.
    """
    HALF, AMAX, AMIN, TMIN, ONE, TOUCH = (consts[0], consts[1], consts[2], consts[3],
                                          consts[4], consts[5])
    C = mean2d.shape[0]
    TX = (W + TILE - 1) // TILE
    TY = (H + TILE - 1) // TILE
    T = TX * TY
    for kt in prange(C * T):
        k = kt // T
        t = kt - k * T
        ty = t // TX
        tx = t - ty * TX
        px0 = tx * TILE
        py0 = ty * TILE
        px1 = min(px0 + TILE, W)
        py1 = min(py0 + TILE, H)
        npix = (px1 - px0) * (py1 - py0)
        P = TILE * TILE
        Tr = np.ones(P, np.float64)
        acc = np.zeros((P, 4), np.float64)
        last = np.full(P, -1, np.int64)
        done = np.zeros(P, np.bool_)
        ndone = 0
        nblend = 0
        for j in range(offsets[kt], offsets[kt + 1]):
            g = isect[j]
            mx = np.float64(mean2d[k, g, 0])
            my = np.float64(mean2d[k, g, 1])
            ok, u0, u1, v0, v1 = _box(mx, my, ext[k, g, 0], ext[k, g, 1], W, H)
            u0 = max(u0, px0)
            u1 = min(u1, px1 - 1)
            v0 = max(v0, py0)
            v1 = min(v1, py1 - 1)
            if not ok or u0 > u1 or v0 > v1 or not _box_open(done, u0, u1, v0, v1, px0, py0):
                continue
            ca = np.float64(conic[k, g, 0])
            cb = np.float64(conic[k, g, 1])
            cc = np.float64(conic[k, g, 2])
            o = np.float64(opac[g])
            m2 = np.float64(m2s[g])
            cr = np.float64(colors[g, 0])
            cg = np.float64(colors[g, 1])
            cbl = np.float64(colors[g, 2])
            z = np.float64(depth[k, g])
            ratio = math.exp(-ca)
            ntouch = 0
            for v in range(v0, v1 + 1):
                dy = centre[v] - my
                ua, ub = _row_span(dy, ca, cb, cc, m2, mx, u0, u1)
                if ua > ub:
                    continue
                dx0 = centre[ua] - mx
                Gn = math.exp(-HALF * (ca * dx0 * dx0 + cc * dy * dy) - cb * dx0 * dy)
                En = math.exp(-HALF * ca * (dx0 + dx0 + ONE) - cb * dy)
                row = (v - py0) * TILE - px0
                for u in range(ua, ub + 1):
                    G = Gn
                    Gn = Gn * En
                    En = En * ratio
                    p = row + u
                    if done[p] or G > ONE:  # G > 1 <=> power > 0 (the rule's guard)
                        continue
                    alpha = min(o * G, AMAX)
                    if alpha < AMIN:
                        continue
                    Tp = Tr[p]
                    tT = Tp * (ONE - alpha)
                    if tT < TMIN:
                        done[p] = True
                        ndone += 1
                        continue
                    w = alpha * Tp
                    nblend += 1
                    acc[p, 0] += w * cr
                    acc[p, 1] += w * cg
                    acc[p, 2] += w * cbl
                    acc[p, 3] += w * z
                    Tr[p] = tT
                    last[p] = j
                    if tT > TOUCH:
                        ntouch += 1
            touch[j] = ntouch
            if ndone == npix:
                break
        blends[kt] = nblend
        for v in range(py0, py1):
            for u in range(px0, px1):
                p = (v - py0) * TILE + (u - px0)
                out_rgb[k, v, u, 0] = acc[p, 0]
                out_rgb[k, v, u, 1] = acc[p, 1]
                out_rgb[k, v, u, 2] = acc[p, 2]
                out_depth[k, v, u] = acc[p, 3]
                out_T[k, v, u] = Tr[p]
                out_last[k, v, u] = last[p]


@njit(cache=True, parallel=True, fastmath=True)
def raster_bwd(mean2d, conic, depth, opac, m2s, colors, ext, isect, offsets, W, H,
               out_T, out_last, g_rgb, g_depth, g_alpha, rows, blends, consts, centre):
    """Backward of :func:`raster_fwd`: fills ``rows[j]`` (one per intersection) with
    dL/d(mx, my, a, b, c, r, g, b, opacity, z) of that Gaussian restricted to that tile, and
    ``blends[kt]`` with the number of blends it differentiated (equal to the forward's)."""
    HALF, AMAX, AMIN, ONE = consts[0], consts[1], consts[2], consts[4]
    C = mean2d.shape[0]
    TX = (W + TILE - 1) // TILE
    TY = (H + TILE - 1) // TILE
    T = TX * TY
    for kt in prange(C * T):
        k = kt // T
        t = kt - k * T
        ty = t // TX
        tx = t - ty * TX
        px0 = tx * TILE
        py0 = ty * TILE
        px1 = min(px0 + TILE, W)
        py1 = min(py0 + TILE, H)
        P = TILE * TILE
        Tr = np.ones(P, np.float64)
        last = np.full(P, -1, np.int64)
        dC = np.zeros((P, 4), np.float64)  # dL/d(r, g, b, depth) of the pixel
        dAT = np.zeros(P, np.float64)  # dL/dalpha_img * T_final
        # sum over the Gaussians behind the current one of w (c . dC), divided by T: one
        # scalar instead of four channels, since the "behind" colour only enters dL/dalpha
        # through its dot product with dC.
        behind = np.zeros(P, np.float64)
        nblend = 0
        jmax = -1
        for v in range(py0, py1):
            for u in range(px0, px1):
                p = (v - py0) * TILE + (u - px0)
                Tr[p] = out_T[k, v, u]
                last[p] = out_last[k, v, u]
                jmax = max(jmax, last[p])
                dC[p, 0] = g_rgb[k, v, u, 0]
                dC[p, 1] = g_rgb[k, v, u, 1]
                dC[p, 2] = g_rgb[k, v, u, 2]
                dC[p, 3] = g_depth[k, v, u]
                dAT[p] = g_alpha[k, v, u] * out_T[k, v, u]
        for j in range(jmax, offsets[kt] - 1, -1):
            g = isect[j]
            mx = np.float64(mean2d[k, g, 0])
            my = np.float64(mean2d[k, g, 1])
            ok, u0, u1, v0, v1 = _box(mx, my, ext[k, g, 0], ext[k, g, 1], W, H)
            u0 = max(u0, px0)
            u1 = min(u1, px1 - 1)
            v0 = max(v0, py0)
            v1 = min(v1, py1 - 1)
            if (not ok or u0 > u1 or v0 > v1
                    or not _box_reached(last, j, u0, u1, v0, v1, px0, py0)):
                continue  # rows[j] stays 0
            ca = np.float64(conic[k, g, 0])
            cb = np.float64(conic[k, g, 1])
            cc = np.float64(conic[k, g, 2])
            o = np.float64(opac[g])
            m2 = np.float64(m2s[g])
            cr = np.float64(colors[g, 0])
            cg = np.float64(colors[g, 1])
            cbl = np.float64(colors[g, 2])
            z = np.float64(depth[k, g])
            ratio = math.exp(-ca)
            s_mx = 0.0
            s_my = 0.0
            s_a = 0.0
            s_b = 0.0
            s_c = 0.0
            s_r = 0.0
            s_g = 0.0
            s_bl = 0.0
            s_o = 0.0
            s_z = 0.0
            for v in range(v0, v1 + 1):
                dy = centre[v] - my
                ua, ub = _row_span(dy, ca, cb, cc, m2, mx, u0, u1)
                if ua > ub:
                    continue
                dx0 = centre[ua] - mx
                Gn = math.exp(-HALF * (ca * dx0 * dx0 + cc * dy * dy) - cb * dx0 * dy)
                En = math.exp(-HALF * ca * (dx0 + dx0 + ONE) - cb * dy)
                row = (v - py0) * TILE - px0
                for u in range(ua, ub + 1):
                    G = Gn
                    Gn = Gn * En
                    En = En * ratio
                    p = row + u
                    if j > last[p] or G > ONE:
                        continue
                    og = o * G
                    alpha = min(og, AMAX)
                    if alpha < AMIN:
                        continue
                    nblend += 1
                    one_m = ONE - alpha
                    inv = ONE / one_m
                    Ti = Tr[p] * inv  # transmittance in front of this Gaussian
                    w = alpha * Ti
                    d0 = dC[p, 0]
                    d1 = dC[p, 1]
                    d2 = dC[p, 2]
                    d3 = dC[p, 3]
                    s_r += w * d0
                    s_g += w * d1
                    s_bl += w * d2
                    s_z += w * d3
                    cdot = cr * d0 + cg * d1 + cbl * d2 + z * d3
                    # dL/dalpha: this Gaussian's colour/depth minus what lies behind it, plus
                    # the final-alpha term (alpha_img = 1 - prod(1 - alpha_i)).
                    dal = Ti * (cdot - behind[p]) + dAT[p] * inv
                    behind[p] = alpha * cdot + one_m * behind[p]
                    Tr[p] = Ti
                    if og <= AMAX:  # a clamped alpha has no gradient
                        s_o += G * dal
                        dp = og * dal  # dL/dpower
                        dx = centre[u] - mx
                        s_mx += dp * (ca * dx + cb * dy)
                        s_my += dp * (cb * dx + cc * dy)
                        s_a -= HALF * dp * dx * dx
                        s_b -= dp * dx * dy
                        s_c -= HALF * dp * dy * dy
            rows[j, 0] = s_mx
            rows[j, 1] = s_my
            rows[j, 2] = s_a
            rows[j, 3] = s_b
            rows[j, 4] = s_c
            rows[j, 5] = s_r
            rows[j, 6] = s_g
            rows[j, 7] = s_bl
            rows[j, 8] = s_o
            rows[j, 9] = s_z
        blends[kt] = nblend


@njit(cache=True, parallel=True)
def reduce_rows(isect, offsets, rows, T, out):
    """``out[k, g] += rows[j]`` for every intersection j of camera k (parallel over cameras,
    sequential and therefore deterministic within one)."""
    C = out.shape[0]
    ncol = rows.shape[1]
    for k in prange(C):
        for j in range(offsets[k * T], offsets[(k + 1) * T]):
            g = isect[j]
            for c in range(ncol):
                out[k, g, c] += rows[j, c]


@njit(cache=True, parallel=True)
def reduce_touch(isect, offsets, touch, T, out):
    """``out[k, g] = True`` where any intersection of Gaussian g in camera k touched a pixel."""
    C = out.shape[0]
    for k in prange(C):
        for j in range(offsets[k * T], offsets[(k + 1) * T]):
            if touch[j] > 0:
                out[k, isect[j]] = True


def tables(alpha_max: float, alpha_min: float, t_min: float, touch_t: float,
           size: int) -> tuple[np.ndarray, np.ndarray]:
    """Constants table and pixel-centre coordinates (``i + 0.5``), float64 (kernel arithmetic)."""
    consts = np.array([0.5, alpha_max, alpha_min, t_min, 1.0, touch_t], np.float64)
    centre = np.arange(size, dtype=np.float64) + 0.5
    return consts, centre
