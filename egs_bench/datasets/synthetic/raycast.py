"""Analytic ray caster for the synthetic scenes (numba, CPU, primary rays only).

Hand-written because no installed library ray-casts analytic primitives with textures on the
CPU at the speed the generator needs (thousands of frames per sequence); the model is kept
deliberately simple and independent of Gaussian splatting:

* Geometry: the room is an axis-aligned box seen from inside (one slab test gives the wall a
  ray leaves through); furniture are yaw-rotated boxes, spheres and vertical capped cylinders.
  Objects are culled per 16x16 screen tile against the tile's frustum planes with bounding
  spheres, so a ray tests only the few objects that can cover its tile.
* Camera: pinhole with gsplat's pixel convention. The ray through continuous image point
  ``(x, y)`` has camera direction ``((x - cx) / fx, (y - cy) / fy, 1)``; pixel ``(u, v)``
  covers ``[u, u + 1) x [v, v + 1)``. Because the direction's camera ``z`` is 1, the ray
  parameter of a hit *is* its z-depth.
* Anti-aliasing: ``ss x ss`` stratified samples per pixel with a fixed per-pixel jitter (the
  same at every time, so static content never flickers), box-averaged. Textures are sampled
  trilinearly from a mip pyramid at the level of the sample's footprint. Adaptive: pixels
  whose 3x3 neighbourhood of centre rays all see the same surface (primitive and decal) are
  shaded once at the centre with the whole pixel's texture footprint; only the others (edges)
  are supersampled. A feature thinner than the pixel spacing can slip between centre rays and
  be missed; the scenes avoid such features at the default resolution.
* Depth: from the ray through the pixel centre (exact analytic z-depth there).
* Shading (linear HDR radiance): ``albedo * (ambient * (0.8 + 0.2 n_z) + sum_l I_l max(0,
  n.l) / (d_l^2 + r_l^2)) + emission``. No shadows or inter-reflections.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from egs_bench.datasets.synthetic.scene import OBJ_BOX, OBJ_SPHERE, PackedScene
from egs_bench.geometry import Intrinsics

TILE = 16
_EPS_T = 1e-9
KIND_FACE, KIND_SPHERE, KIND_CYL_SIDE, KIND_CYL_CAP = 0, 1, 2, 3
_MIN_COS = 0.15  # caps the footprint growth at grazing angles (limits over-blur)
# The per-ray helpers are inlined and allocate nothing; they are compiled with ``_nrt=False``
# because otherwise numba emits atomic reference-count updates for the ~20 scene arrays at every
# inlined call, which cost ~100 ns per ray (measured: tracing 10x slower, rendering 1.6x).


@njit(cache=True)
def bin_objects(
    rot_cw: np.ndarray,
    t_cw: np.ndarray,
    bounds: np.ndarray,
    fx: float,
    fy: float,
    cx: float,
    cy: float,
    width: int,
    height: int,
    out_list: np.ndarray,
    out_count: np.ndarray,
) -> None:
    """List, per ``TILE x TILE`` screen tile, the objects whose bounding sphere can touch it.

    Conservative: a sphere is dropped only if it lies entirely outside one of the tile's four
    frustum planes (all through the camera centre) or entirely behind the camera.

    Args:
        rot_cw, t_cw: world-to-camera rotation [3, 3] and translation [3].
        bounds: bounding spheres [O, 4] (world centre, radius).
        out_list: int64 [n_tiles_y, n_tiles_x, O], filled with object indices.
        out_count: int64 [n_tiles_y, n_tiles_x], number of valid entries per tile.
    """
    nty, ntx = out_count.shape
    out_count[:, :] = 0
    for o in range(bounds.shape[0]):
        wx, wy, wz, rad = bounds[o, 0], bounds[o, 1], bounds[o, 2], bounds[o, 3]
        px = rot_cw[0, 0] * wx + rot_cw[0, 1] * wy + rot_cw[0, 2] * wz + t_cw[0]
        py = rot_cw[1, 0] * wx + rot_cw[1, 1] * wy + rot_cw[1, 2] * wz + t_cw[1]
        pz = rot_cw[2, 0] * wx + rot_cw[2, 1] * wy + rot_cw[2, 2] * wz + t_cw[2]
        if pz < -rad:
            continue
        for ty in range(nty):
            b0 = (ty * TILE - cy) / fy
            b1 = (min((ty + 1) * TILE, height) - cy) / fy
            if (py - b0 * pz) / math.sqrt(1.0 + b0 * b0) < -rad:
                continue
            if (b1 * pz - py) / math.sqrt(1.0 + b1 * b1) < -rad:
                continue
            for tx in range(ntx):
                a0 = (tx * TILE - cx) / fx
                a1 = (min((tx + 1) * TILE, width) - cx) / fx
                if (px - a0 * pz) / math.sqrt(1.0 + a0 * a0) < -rad:
                    continue
                if (a1 * pz - px) / math.sqrt(1.0 + a1 * a1) < -rad:
                    continue
                out_list[ty, tx, out_count[ty, tx]] = o
                out_count[ty, tx] += 1


@njit(cache=True, inline="always", fastmath=True, _nrt=False)
def _slab(lo, ld, h, tnear, tfar, face, face_pos):
    """One axis of the ray/box slab test: ray origin ``lo`` and direction ``ld`` along the axis,
    half-extent ``h``. Returns the updated ``(tnear, tfar, face, miss)``; the entering face is
    ``face_pos`` (+1 when the ray travels towards -axis)."""
    if ld != 0.0:
        t1, t2 = (-h - lo) / ld, (h - lo) / ld
        if t1 > t2:
            t1, t2 = t2, t1
        if t1 > tnear:
            tnear, face = t1, face_pos + 1 if ld < 0.0 else face_pos
        return tnear, min(tfar, t2), face, False
    return tnear, tfar, face, abs(lo) > h


@njit(cache=True, inline="always", fastmath=True, _nrt=False)
def _trace(ox, oy, oz, dx, dy, dz, room, boxes, spheres, cylinders, objects, tlist, ty, tx, tcount):
    """Nearest hit of ray ``o + t d`` (t > 0): returns ``(t, kind, index)``.

    Objects tested: ``tlist[ty, tx, :tcount]`` (the screen tile's list).

    ``kind`` is one of the ``KIND_*`` constants; for faces, ``index`` is the face row (room
    faces 0-5, then six per box); for spheres and cylinders the primitive index.
    """
    # Room, seen from inside: the exit wall.
    best_t = 1e30
    kind = KIND_FACE
    index = -1
    if dx != 0.0:
        t = ((room[3] if dx > 0.0 else room[0]) - ox) / dx
        best_t, index = t, 1 if dx > 0.0 else 0
    if dy != 0.0:
        t = ((room[4] if dy > 0.0 else room[1]) - oy) / dy
        if t < best_t:
            best_t, index = t, 3 if dy > 0.0 else 2
    if dz != 0.0:
        t = ((room[5] if dz > 0.0 else room[2]) - oz) / dz
        if t < best_t:
            best_t, index = t, 5 if dz > 0.0 else 4
    for k in range(tcount):
        obj = tlist[ty, tx, k]
        okind = objects[obj, 0]
        i = objects[obj, 1]
        if okind == OBJ_BOX:
            rx, ry, rz = ox - boxes[i, 0], oy - boxes[i, 1], oz - boxes[i, 2]
            c, s = boxes[i, 3], boxes[i, 4]
            # Slab test in the box frame, one axis per call (scalars in, scalars out).
            tnear, tfar, face, miss = _slab(c * rx + s * ry, c * dx + s * dy, boxes[i, 5],
                                            -1e30, 1e30, -1, 0)
            if miss:
                continue
            tnear, tfar, face, miss = _slab(-s * rx + c * ry, -s * dx + c * dy, boxes[i, 6],
                                            tnear, tfar, face, 2)
            if miss:
                continue
            tnear, tfar, face, miss = _slab(rz, dz, boxes[i, 7], tnear, tfar, face, 4)
            if miss:
                continue
            if face >= 0 and tnear <= tfar and _EPS_T < tnear < best_t:
                best_t, kind, index = tnear, KIND_FACE, 6 + 6 * i + face
        elif okind == OBJ_SPHERE:
            rx, ry, rz = ox - spheres[i, 0], oy - spheres[i, 1], oz - spheres[i, 2]
            qa = dx * dx + dy * dy + dz * dz
            qb = rx * dx + ry * dy + rz * dz
            qc = rx * rx + ry * ry + rz * rz - spheres[i, 3] ** 2
            disc = qb * qb - qa * qc
            if disc >= 0.0:
                t = (-qb - math.sqrt(disc)) / qa
                if _EPS_T < t < best_t:
                    best_t, kind, index = t, KIND_SPHERE, i
        else:  # OBJ_CYLINDER
            rx, ry = ox - cylinders[i, 0], oy - cylinders[i, 1]
            z0, z1, r = cylinders[i, 2], cylinders[i, 3], cylinders[i, 4]
            qa = dx * dx + dy * dy
            if qa > 1e-15:
                qb = rx * dx + ry * dy
                qc = rx * rx + ry * ry - r * r
                disc = qb * qb - qa * qc
                if disc >= 0.0:
                    t = (-qb - math.sqrt(disc)) / qa
                    z = oz + t * dz
                    if _EPS_T < t < best_t and z0 <= z <= z1:
                        best_t, kind, index = t, KIND_CYL_SIDE, i
            if dz != 0.0:
                # Only the cap facing the ray can be its first hit.
                t = ((z1 if dz < 0.0 else z0) - oz) / dz
                if _EPS_T < t < best_t:
                    hx, hy = rx + t * dx, ry + t * dy
                    if hx * hx + hy * hy <= r * r:
                        best_t, kind, index = t, KIND_CYL_CAP, i
    return best_t, kind, index


@njit(cache=True, fastmath=True, _nrt=False)
def _bilinear(texels, base, size, u, v, wrap_u, wrap_v):
    x = u * size - 0.5
    y = v * size - 0.5
    fx0 = math.floor(x)
    fy0 = math.floor(y)
    ax = x - fx0
    ay = y - fy0
    ix0 = int(fx0)
    iy0 = int(fy0)
    ix1 = ix0 + 1
    iy1 = iy0 + 1
    mask = size - 1  # size is a power of two
    if wrap_u:
        ix0 &= mask
        ix1 &= mask
    else:
        ix0 = min(max(ix0, 0), mask)
        ix1 = min(max(ix1, 0), mask)
    if wrap_v:
        iy0 &= mask
        iy1 &= mask
    else:
        iy0 = min(max(iy0, 0), mask)
        iy1 = min(max(iy1, 0), mask)
    i00 = base + iy0 * size + ix0
    i01 = base + iy0 * size + ix1
    i10 = base + iy1 * size + ix0
    i11 = base + iy1 * size + ix1
    w00 = (1 - ax) * (1 - ay)
    w01 = ax * (1 - ay)
    w10 = (1 - ax) * ay
    w11 = ax * ay
    r = w00 * texels[i00, 0] + w01 * texels[i01, 0] + w10 * texels[i10, 0] + w11 * texels[i11, 0]
    g = w00 * texels[i00, 1] + w01 * texels[i01, 1] + w10 * texels[i10, 1] + w11 * texels[i11, 1]
    b = w00 * texels[i00, 2] + w01 * texels[i01, 2] + w10 * texels[i10, 2] + w11 * texels[i11, 2]
    return r, g, b


@njit(cache=True, inline="always", fastmath=True, _nrt=False)
def sample_texture(texels, tex_off, tex_size, tex, u, v, lod, wrap_u, wrap_v):
    """Trilinear (mip-mapped) lookup of texture ``tex`` at ``(u, v)`` (1 = one texture width),
    level of detail ``lod`` (0 = full resolution). Returns linear ``(r, g, b)``."""
    n_levels = tex_off.shape[1]
    if lod < 0.0:
        lod = 0.0
    if lod > n_levels - 1:
        lod = float(n_levels - 1)
    l0 = int(lod)
    frac = lod - l0
    r, g, b = _bilinear(texels, tex_off[tex, l0], tex_size >> l0, u, v, wrap_u, wrap_v)
    if frac > 1e-6 and l0 + 1 < n_levels:
        r1, g1, b1 = _bilinear(
            texels, tex_off[tex, l0 + 1], tex_size >> (l0 + 1), u, v, wrap_u, wrap_v
        )
        r += frac * (r1 - r)
        g += frac * (g1 - g)
        b += frac * (b1 - b)
    return r, g, b


@njit(cache=True, inline="always", fastmath=True, _nrt=False)
def _face_coords(px, py, pz, f, faces):
    """Face coordinates ``(s, r)`` (metres) of point ``p`` on face row ``f``."""
    qx, qy, qz = px - faces[f, 0], py - faces[f, 1], pz - faces[f, 2]
    s = qx * faces[f, 9] + qy * faces[f, 10] + qz * faces[f, 11] + faces[f, 12]
    r = qx * faces[f, 6] + qy * faces[f, 7] + qz * faces[f, 8] + faces[f, 13]
    return s, r


@njit(cache=True, inline="always", fastmath=True, _nrt=False)
def _decal_at(ox, oy, oz, dx, dy, dz, t, kind, index, faces, decal_rect, fd_start, fd_count):
    """Index of the decal seen at hit ``(t, kind, index)`` of ray ``o + t d``, or -1.

    The last decal containing the point wins (later decals cover earlier ones).
    """
    if kind != KIND_FACE:
        return -1
    s, r = _face_coords(ox + t * dx, oy + t * dy, oz + t * dz, index, faces)
    top = -1
    for k in range(fd_start[index], fd_start[index] + fd_count[index]):
        if decal_rect[k, 0] <= s <= decal_rect[k, 2]:
            if decal_rect[k, 1] <= r <= decal_rect[k, 3]:
                top = k
    return top


@njit(cache=True, inline="always", fastmath=True, _nrt=False)
def _shade(
    ox, oy, oz, dx, dy, dz, t, kind, index, decal, pix_ang, lod_bias,
    faces, face_mat, decal_rect, decal_mat, spheres, sphere_mat,
    cylinders, cyl_mat, mat_f, mat_tex, texels, tex_off, tex_size, lights, ambient,
):  # fmt: skip
    """Linear radiance ``(r, g, b)`` of the hit ``(t, kind, index)`` of ray ``o + t d``.

    ``decal`` is the decal at the hit (from :func:`_decal_at`); ``pix_ang`` the angular size
    (radians) of the area the sample stands for, which sets the texture mip level.
    """
    px, py, pz = ox + t * dx, oy + t * dy, oz + t * dz
    wrap_u = True
    wrap_v = True
    if kind == KIND_FACE:
        f = index
        nx, ny, nz = faces[f, 3], faces[f, 4], faces[f, 5]
        s, r = _face_coords(px, py, pz, f, faces)
        m = face_mat[f]
        ext_s, ext_r = 2.0 * faces[f, 12], 2.0 * faces[f, 13]
        if decal >= 0:
            m = decal_mat[decal]
            s -= decal_rect[decal, 0]
            r -= decal_rect[decal, 1]
            ext_s = decal_rect[decal, 2] - decal_rect[decal, 0]
            ext_r = decal_rect[decal, 3] - decal_rect[decal, 1]
        tile = mat_f[m, 6]
        if tile > 0.0:
            u, v = s / tile, -r / tile
            texel = tile
        else:
            u, v = s / ext_s, 1.0 - r / ext_r
            texel = min(ext_s, ext_r)
            wrap_u = False
            wrap_v = False
    elif kind == KIND_SPHERE:
        rad = spheres[index, 3]
        nx = (px - spheres[index, 0]) / rad
        ny = (py - spheres[index, 1]) / rad
        nz = (pz - spheres[index, 2]) / rad
        m = sphere_mat[index]
        u = math.atan2(ny, nx) / (2.0 * math.pi) + 0.5
        v = math.acos(min(max(nz, -1.0), 1.0)) / math.pi
        tile = mat_f[m, 6]
        if tile > 0.0:
            u *= 2.0 * math.pi * rad / tile
            v *= math.pi * rad / tile
            texel = tile
        else:
            texel = math.pi * rad
            wrap_v = False
    elif kind == KIND_CYL_SIDE:
        rad = cylinders[index, 4]
        z0, z1 = cylinders[index, 2], cylinders[index, 3]
        nx = (px - cylinders[index, 0]) / rad
        ny = (py - cylinders[index, 1]) / rad
        nz = 0.0
        m = cyl_mat[index, 0]
        u = math.atan2(ny, nx) / (2.0 * math.pi) + 0.5
        tile = mat_f[m, 6]
        if tile > 0.0:
            u *= 2.0 * math.pi * rad / tile
            v = (z1 - pz) / tile
            texel = tile
        else:
            v = (z1 - pz) / (z1 - z0)
            texel = min(2.0 * math.pi * rad, z1 - z0)
            wrap_v = False
    else:  # KIND_CYL_CAP
        rad = cylinders[index, 4]
        nx, ny = 0.0, 0.0
        nz = 1.0 if dz < 0.0 else -1.0
        m = cyl_mat[index, 1]
        tile = mat_f[m, 6]
        lx, ly = px - cylinders[index, 0], py - cylinders[index, 1]
        if tile > 0.0:
            u, v = lx / tile, ly / tile
            texel = tile
        else:
            u, v = (lx + rad) / (2 * rad), (ly + rad) / (2 * rad)
            texel = 2 * rad
            wrap_u = False
            wrap_v = False
    dnorm = math.sqrt(dx * dx + dy * dy + dz * dz)
    cos_view = (nx * dx + ny * dy + nz * dz) / dnorm
    if cos_view > 0.0:  # make the normal face the viewer
        nx, ny, nz = -nx, -ny, -nz
    else:
        cos_view = -cos_view

    cr, cg, cb = mat_f[m, 0], mat_f[m, 1], mat_f[m, 2]
    er, eg, eb = mat_f[m, 3], mat_f[m, 4], mat_f[m, 5]
    tex = mat_tex[m]
    if tex >= 0:
        footprint = t * dnorm * pix_ang / max(cos_view, _MIN_COS)
        lod = math.log2(max(footprint * tex_size / texel, 1e-12)) + lod_bias
        tr, tg, tb = sample_texture(texels, tex_off, tex_size, tex, u, v, lod, wrap_u, wrap_v)
        mix = mat_f[m, 7]
        cr *= 1.0 - mix + mix * tr
        cg *= 1.0 - mix + mix * tg
        cb *= 1.0 - mix + mix * tb
        er *= tr
        eg *= tg
        eb *= tb
    hemi = 0.8 + 0.2 * nz
    ir, ig, ib = ambient[0] * hemi, ambient[1] * hemi, ambient[2] * hemi
    for li in range(lights.shape[0]):
        lx, ly, lz = lights[li, 0] - px, lights[li, 1] - py, lights[li, 2] - pz
        d2 = lx * lx + ly * ly + lz * lz
        cos_l = (nx * lx + ny * ly + nz * lz) / math.sqrt(d2)
        if cos_l > 0.0:
            w = cos_l / (d2 + lights[li, 6] ** 2)
            ir += w * lights[li, 3]
            ig += w * lights[li, 4]
            ib += w * lights[li, 5]
    return cr * ir + er, cg * ig + eg, cb * ib + eb


@njit(cache=True, fastmath=True, _nrt=False)
def _primary_row(
    v, rot_wc, origin, fx, fy, cx, cy, tlist, tcount, room, faces, decal_rect, fd_start,
    fd_count, boxes, spheres, cylinders, objects, out_depth, out_code,
):  # fmt: skip
    """Trace the pixel-centre rays of row ``v``: z-depth and a surface code per pixel.

    The code identifies (primitive kind, index, decal), so equal codes mean the same surface.
    """
    ox, oy, oz = origin[0], origin[1], origin[2]
    ty = v // TILE
    for u in range(out_depth.shape[1]):
        tx = u // TILE
        cxd = (u + 0.5 - cx) / fx
        cyd = (v + 0.5 - cy) / fy
        dx = rot_wc[0, 0] * cxd + rot_wc[0, 1] * cyd + rot_wc[0, 2]
        dy = rot_wc[1, 0] * cxd + rot_wc[1, 1] * cyd + rot_wc[1, 2]
        dz = rot_wc[2, 0] * cxd + rot_wc[2, 1] * cyd + rot_wc[2, 2]
        t, kind, index = _trace(
            ox, oy, oz, dx, dy, dz, room, boxes, spheres, cylinders, objects, tlist, ty, tx,
            tcount[ty, tx],
        )  # fmt: skip
        decal = _decal_at(
            ox, oy, oz, dx, dy, dz, t, kind, index, faces, decal_rect, fd_start, fd_count
        )
        out_depth[v, u] = t
        out_code[v, u] = (kind << 40) | (index << 20) | (decal + 1)


@njit(cache=True, fastmath=True, _nrt=False)
def _shade_row(
    v, rot_wc, origin, fx, fy, cx, cy, offsets, tlist, tcount, lod_bias,
    room, faces, face_mat, decal_rect, decal_mat, fd_start, fd_count, boxes, spheres, sphere_mat,
    cylinders, cyl_mat, objects, mat_f, mat_tex, texels, tex_off, tex_size, lights, ambient,
    depth, code, out_rgb,
):  # fmt: skip
    """Shade row ``v`` (see :func:`render_kernel`), given the centre-ray ``depth`` and ``code``.

    Adaptive supersampling: a pixel whose 3x3 neighbourhood of centre rays all see the same
    surface is shaded once, at its centre, with the texture footprint of the whole pixel;
    other pixels (edges, silhouettes, decal borders) trace and shade all ``S`` sub-pixel rays
    and average them. Both estimate the pixel's box filter.
    """
    height, width = depth.shape
    n_samples = offsets.shape[2]
    sub_ang = 1.0 / (0.5 * (fx + fy) * math.sqrt(n_samples))
    pix_ang = 1.0 / (0.5 * (fx + fy))
    ox, oy, oz = origin[0], origin[1], origin[2]
    ty = v // TILE
    v0, v1 = max(v - 1, 0), min(v + 1, height - 1)
    for u in range(width):
        tx = u // TILE
        tc = tcount[ty, tx]
        c0 = code[v, u]
        uniform = n_samples == 1
        if not uniform:
            uniform = True
            for vv in range(v0, v1 + 1):
                for uu in range(max(u - 1, 0), min(u + 1, width - 1) + 1):
                    if code[vv, uu] != c0:
                        uniform = False
        if uniform:
            cxd = (u + 0.5 - cx) / fx
            cyd = (v + 0.5 - cy) / fy
            dx = rot_wc[0, 0] * cxd + rot_wc[0, 1] * cyd + rot_wc[0, 2]
            dy = rot_wc[1, 0] * cxd + rot_wc[1, 1] * cyd + rot_wc[1, 2]
            dz = rot_wc[2, 0] * cxd + rot_wc[2, 1] * cyd + rot_wc[2, 2]
            kind = c0 >> 40
            index = (c0 >> 20) & 0xFFFFF
            decal = (c0 & 0xFFFFF) - 1
            r, g, b = _shade(
                ox, oy, oz, dx, dy, dz, depth[v, u], kind, index, decal, pix_ang, lod_bias,
                faces, face_mat, decal_rect, decal_mat, spheres, sphere_mat, cylinders,
                cyl_mat, mat_f, mat_tex, texels, tex_off, tex_size, lights, ambient,
            )  # fmt: skip
            out_rgb[v, u, 0] = r
            out_rgb[v, u, 1] = g
            out_rgb[v, u, 2] = b
            continue
        ar, ag, ab = 0.0, 0.0, 0.0
        for k in range(n_samples):
            sxd = (u + offsets[v, u, k, 0] - cx) / fx
            syd = (v + offsets[v, u, k, 1] - cy) / fy
            dx = rot_wc[0, 0] * sxd + rot_wc[0, 1] * syd + rot_wc[0, 2]
            dy = rot_wc[1, 0] * sxd + rot_wc[1, 1] * syd + rot_wc[1, 2]
            dz = rot_wc[2, 0] * sxd + rot_wc[2, 1] * syd + rot_wc[2, 2]
            t, kind, index = _trace(
                ox, oy, oz, dx, dy, dz, room, boxes, spheres, cylinders, objects, tlist, ty, tx, tc
            )
            decal = _decal_at(
                ox, oy, oz, dx, dy, dz, t, kind, index, faces, decal_rect, fd_start, fd_count
            )
            r, g, b = _shade(
                ox, oy, oz, dx, dy, dz, t, kind, index, decal, sub_ang, lod_bias,
                faces, face_mat, decal_rect, decal_mat, spheres, sphere_mat, cylinders,
                cyl_mat, mat_f, mat_tex, texels, tex_off, tex_size, lights, ambient,
            )  # fmt: skip
            ar += r
            ag += g
            ab += b
        out_rgb[v, u, 0] = ar / n_samples
        out_rgb[v, u, 1] = ag / n_samples
        out_rgb[v, u, 2] = ab / n_samples


@njit(parallel=True, cache=True)
def render_kernel(
    rot_wc, origin, fx, fy, cx, cy, offsets, tlist, tcount, lod_bias,
    room, faces, face_mat, decal_rect, decal_mat, fd_start, fd_count, boxes, spheres, sphere_mat,
    cylinders, cyl_mat, objects, mat_f, mat_tex, texels, tex_off, tex_size, lights, ambient,
    out_rgb, out_depth, code,
):  # fmt: skip
    """Render radiance ``out_rgb`` [H, W, 3] (float32) and z-depth ``out_depth`` [H, W].

    ``offsets`` [H, W, S, 2] are the sub-pixel sample positions in ``[0, 1)`` of each pixel;
    ``code`` int64 [H, W] is scratch space for the centre rays' surface codes. Rows are
    distributed over threads; the per-row work lives in small helpers (a small parallel body
    keeps numba's compile time short).
    """
    height = out_depth.shape[0]
    for v in prange(height):
        _primary_row(
            v, rot_wc, origin, fx, fy, cx, cy, tlist, tcount, room, faces, decal_rect, fd_start,
            fd_count, boxes, spheres, cylinders, objects, out_depth, code,
        )  # fmt: skip
    for v in prange(height):
        _shade_row(
            v, rot_wc, origin, fx, fy, cx, cy, offsets, tlist, tcount, lod_bias,
            room, faces, face_mat, decal_rect, decal_mat, fd_start, fd_count, boxes, spheres,
            sphere_mat, cylinders, cyl_mat, objects, mat_f, mat_tex, texels, tex_off, tex_size,
            lights, ambient, out_depth, code, out_rgb,
        )  # fmt: skip


def stratified_offsets(
    height: int, width: int, supersample: int, jitter: bool = True, seed: int = 0
) -> np.ndarray:
    """Sub-pixel sample positions float64 [H, W, ss*ss, 2] in ``[0, 1)``.

    Cell ``(i, j)`` of the ``ss x ss`` grid holds one sample at ``((j + a) / ss, (i + b) / ss)``
    with ``a, b`` uniform in ``[0.05, 0.95)`` per pixel and sample when ``jitter`` (else 0.5).
    The pattern is fixed for a renderer: static content renders identically at every time.
    """
    if supersample < 1:
        raise ValueError(f"supersample must be >= 1, got {supersample}")
    ss = supersample
    jj, ii = np.meshgrid(np.arange(ss), np.arange(ss))
    grid = np.stack([jj.ravel(), ii.ravel()], axis=-1).astype(np.float64)  # [S, 2] (x, y)
    if jitter and ss > 1:
        rng = np.random.default_rng(seed)
        frac = rng.uniform(0.05, 0.95, size=(height, width, ss * ss, 2))
    else:
        frac = np.full((height, width, ss * ss, 2), 0.5)
    return np.ascontiguousarray((grid[None, None] + frac) / ss)


class Renderer:
    """Renders a packed scene through one camera (intrinsics + fixed sample pattern).

    Args:
        scene: packed scene.
        intrinsics: camera (gsplat pixel convention).
        supersample: samples per pixel along each axis (``ss x ss`` per pixel).
        jitter: jitter samples inside their strata (fixed pattern).
        lod_bias: added to the mip level (negative = sharper, positive = blurrier).
        cull: cull objects per screen tile (off = test every object for every ray; same
            image, slower; for checking the culling).
    """

    def __init__(
        self,
        scene: PackedScene,
        intrinsics: Intrinsics,
        supersample: int = 2,
        jitter: bool = True,
        lod_bias: float = 0.0,
        cull: bool = True,
    ) -> None:
        self.scene = scene
        self.cull = cull
        self.intrinsics = intrinsics
        self.supersample = supersample
        self.lod_bias = float(lod_bias)
        h, w = intrinsics.height, intrinsics.width
        self.offsets = stratified_offsets(h, w, supersample, jitter)
        self._nty = (h + TILE - 1) // TILE
        self._ntx = (w + TILE - 1) // TILE
        n_obj = max(1, len(scene.objects))
        self._tlist = np.zeros((self._nty, self._ntx, n_obj), np.int64)
        self._tcount = np.zeros((self._nty, self._ntx), np.int64)

    def render(self, pose_wc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Render from camera-to-world pose [4, 4].

        Returns:
            ``rgb`` float32 [H, W, 3] linear radiance (>= 0) and ``depth`` float32 [H, W]
            z-depth in metres along the optical axis (every ray hits the closed room, so > 0).
        """
        sc, k = self.scene, self.intrinsics
        pose = np.asarray(pose_wc, dtype=np.float64)
        rot_wc = np.ascontiguousarray(pose[:3, :3])
        origin = np.ascontiguousarray(pose[:3, 3])
        rot_cw = np.ascontiguousarray(rot_wc.T)
        t_cw = -rot_cw @ origin
        if self.cull:
            bin_objects(
                rot_cw, t_cw, sc.object_bounds, k.fx, k.fy, k.cx, k.cy, k.width, k.height,
                self._tlist, self._tcount,
            )  # fmt: skip
        else:
            n_obj = len(sc.objects)
            self._tlist[:, :, :n_obj] = np.arange(n_obj)[None, None, :]
            self._tcount[:] = n_obj
        rgb = np.empty((k.height, k.width, 3), np.float32)
        depth = np.empty((k.height, k.width), np.float32)
        code = np.empty((k.height, k.width), np.int64)
        tex = sc.textures
        render_kernel(
            rot_wc, origin, k.fx, k.fy, k.cx, k.cy, self.offsets, self._tlist, self._tcount,
            self.lod_bias, sc.room, sc.faces, sc.face_mat, sc.decal_rect, sc.decal_mat,
            sc.face_decal_start, sc.face_decal_count, sc.boxes, sc.spheres, sc.sphere_mat,
            sc.cylinders, sc.cylinder_mat, sc.objects, sc.mat_f, sc.mat_tex, tex.texels,
            tex.offsets, tex.size, sc.lights, sc.ambient, rgb, depth, code,
        )  # fmt: skip
        return rgb, depth
