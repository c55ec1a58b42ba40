"""EWA projection of the CPU backend: one fused numba pass forward, a hand-written backward.

:func:`egs_bench.render.projection.project_gaussians` states the math in PyTorch and stays the
reference (the ``reference`` backend and the tests use it). On the CPU its ~60 elementwise
operations over [C, N] tensors, and autograd's replay of them, took about 40 % of a
``rasterize`` forward + backward (224x128, 5 cameras, 110k Gaussians, one thread: 0.95 of
2.3 s); the numba backend therefore projects with the kernels below: one loop over the
Gaussians that keeps every intermediate in registers, and its derivative written out.

Conventions and results are those of ``project_gaussians`` (same outputs, same culling, same
gradients including the ``torch.where`` / clamp branches). The camera-space point is computed,
and compared with the near and far planes, in the input dtype in the same order as the
reference, so both cull the same Gaussians (a float32 point at z = 0.2 is on a 0.2 m near plane
in both, not in front of it); from the perspective division on the arithmetic is float64.
Gradients of the world-to-camera matrices are summed over
fixed chunks of Gaussians and then over chunks in order, so they are deterministic and do not
depend on the thread count.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import torch
from numba import njit, prange

from egs_bench.render import constants as RC
from egs_bench.render.projection import Projected

CHUNK = 2048  # Gaussians per partial sum of the camera gradients (fixed: deterministic sums)


@njit(inline="always")
def _rotation(qw, qx, qy, qz):
    """Unit quaternion (after normalising, as ``F.normalize``) and its rotation matrix."""
    norm = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
    inv = 1.0 / max(norm, 1e-12)
    w, x, y, z = qw * inv, qx * inv, qy * inv, qz * inv
    return (norm, w, x, y, z,
            1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y),
            2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x),
            2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y))


@njit(inline="always")
def _clamp_pass(q, lo, hi):
    """``min(max(q, lo), hi)`` and the share of the gradient that passes (torch's rule:
    1 inside, 1/2 at a tie, 0 outside)."""
    if q > lo:
        v, g = q, 1.0
    elif q == lo:
        v, g = q, 0.5
    else:
        v, g = lo, 0.0
    if v < hi:
        return v, g
    if v == hi:
        return v, 0.5 * g
    return hi, 0.0


@njit(cache=True, parallel=True)
def project_fwd(means, quats, scales, opacities, viewmats, Ks, width, height, near, far,
                eps2d, fov_clamp, alpha_min, means2d, conics, depths, valid, extents, radii):
    """Fill ``means2d`` [C,N,2], ``conics`` [C,N,3], ``depths`` [C,N], ``valid`` [C,N],
    ``extents`` [C,N,2] and ``radii`` [C,N] (see :class:`Projected`)."""
    C = viewmats.shape[0]
    N = means.shape[0]
    for n in prange(N):
        (_, _, _, _, _, r00, r01, r02, r10, r11, r12, r20, r21, r22) = _rotation(
            quats[n, 0], quats[n, 1], quats[n, 2], quats[n, 3])
        s0, s1, s2 = scales[n, 0], scales[n, 1], scales[n, 2]
        # M = R_q diag(s)
        m00, m01, m02 = r00 * s0, r01 * s1, r02 * s2
        m10, m11, m12 = r10 * s0, r11 * s1, r12 * s2
        m20, m21, m22 = r20 * s0, r21 * s1, r22 * s2
        px, py, pz = means[n, 0], means[n, 1], means[n, 2]
        ratio = opacities[n] / alpha_min
        m2 = 2.0 * math.log(ratio) if ratio > 1.0 else 0.0
        for c in range(C):
            fx, fy, cx, cy = Ks[c, 0, 0], Ks[c, 1, 1], Ks[c, 0, 2], Ks[c, 1, 2]
            x = viewmats[c, 0, 0] * px + viewmats[c, 0, 1] * py + viewmats[c, 0, 2] * pz \
                + viewmats[c, 0, 3]
            y = viewmats[c, 1, 0] * px + viewmats[c, 1, 1] * py + viewmats[c, 1, 2] * pz \
                + viewmats[c, 1, 3]
            z = viewmats[c, 2, 0] * px + viewmats[c, 2, 1] * py + viewmats[c, 2, 2] * pz \
                + viewmats[c, 2, 3]
            in_range = z > near and z < far
            zs = z if in_range else 1.0
            tan_x, tan_y = 0.5 * width / fx, 0.5 * height / fy
            tx = _clamp_pass(x / zs, -(cx / fx + fov_clamp * tan_x),
                             (width - cx) / fx + fov_clamp * tan_x)[0]
            ty = _clamp_pass(y / zs, -(cy / fy + fov_clamp * tan_y),
                             (height - cy) / fy + fov_clamp * tan_y)[0]
            j00, j02 = fx / zs, -fx * tx / zs
            j11, j12 = fy / zs, -fy * ty / zs
            # rows of J R
            a0 = j00 * viewmats[c, 0, 0] + j02 * viewmats[c, 2, 0]
            a1 = j00 * viewmats[c, 0, 1] + j02 * viewmats[c, 2, 1]
            a2_ = j00 * viewmats[c, 0, 2] + j02 * viewmats[c, 2, 2]
            b0 = j11 * viewmats[c, 1, 0] + j12 * viewmats[c, 2, 0]
            b1 = j11 * viewmats[c, 1, 1] + j12 * viewmats[c, 2, 1]
            b2_ = j11 * viewmats[c, 1, 2] + j12 * viewmats[c, 2, 2]
            # V = (J R) M
            v00 = a0 * m00 + a1 * m10 + a2_ * m20
            v01 = a0 * m01 + a1 * m11 + a2_ * m21
            v02 = a0 * m02 + a1 * m12 + a2_ * m22
            v10 = b0 * m00 + b1 * m10 + b2_ * m20
            v11 = b0 * m01 + b1 * m11 + b2_ * m21
            v12 = b0 * m02 + b1 * m12 + b2_ * m22
            ca = v00 * v00 + v01 * v01 + v02 * v02 + eps2d
            cb = v00 * v10 + v01 * v11 + v02 * v12
            cc = v10 * v10 + v11 * v11 + v12 * v12 + eps2d
            det = ca * cc - cb * cb
            ok = in_range and det > 0.0 and math.isfinite(det)
            det_s = det if ok else 1.0
            u = fx * x / zs + cx
            v = fy * y / zs + cy
            means2d[c, n, 0] = u
            means2d[c, n, 1] = v
            conics[c, n, 0] = cc / det_s
            conics[c, n, 1] = -cb / det_s
            conics[c, n, 2] = ca / det_s
            depths[c, n] = z
            valid[c, n] = ok
            # culling box (no gradient): see projection._extents
            e0 = math.sqrt(m2 * ca) * (1.0 + 1e-3) + 1e-3
            e1 = math.sqrt(m2 * cc) * (1.0 + 1e-3) + 1e-3
            if not ok or m2 <= 0.0 or not (math.isfinite(e0) and math.isfinite(e1)):
                extents[c, n, 0] = -1.0
                extents[c, n, 1] = -1.0
                radii[c, n] = 0
                continue
            extents[c, n, 0] = e0
            extents[c, n, 1] = e1
            # the box test uses the stored (input-dtype) values, as the PyTorch form does
            mu, mv, f0, f1 = means2d[c, n, 0], means2d[c, n, 1], extents[c, n, 0], \
                extents[c, n, 1]
            if mu + f0 > 0.0 and mu - f0 < width and mv + f1 > 0.0 and mv - f1 < height:
                radii[c, n] = min(math.ceil(max(f0, f1)), 2147483647.0)
            else:
                radii[c, n] = 0


@njit(inline="always")
def _no_cotangent(g_means2d, g_conics, g_depths, n, C):
    """Whether Gaussian ``n`` has zero cotangents in every camera."""
    for c in range(C):
        if (g_means2d[c, n, 0] != 0.0 or g_means2d[c, n, 1] != 0.0 or g_conics[c, n, 0] != 0.0
                or g_conics[c, n, 1] != 0.0 or g_conics[c, n, 2] != 0.0
                or g_depths[c, n] != 0.0):
            return False
    return True


@njit(cache=True, parallel=True)
def project_bwd(means, quats, scales, viewmats, Ks, width, height, near, far, eps2d, fov_clamp,
                g_means2d, g_conics, g_depths, g_means, g_quats, g_scales, g_view_parts):
    """Gradients of the projection: ``g_means`` [N,3], ``g_quats`` [N,4], ``g_scales`` [N,3],
    and per chunk of ``CHUNK`` Gaussians the camera parts ``g_view_parts`` [n_chunks, C, 12]
    (row-major ``dL/dR`` then ``dL/dt``), from the cotangents of means2d, conics and depths.

    The forward quantities are recomputed here, spelled out as in :func:`project_fwd`: moving
    them into a shared njit helper returning tuples made the projection 35-50 % slower
    (110k Gaussians, C = 5: forward 26 -> 39 ms, backward 39 -> 52 ms; not inlined), and
    ``inline="always"`` on it fails numba's parfor array analysis."""
    C = viewmats.shape[0]
    N = means.shape[0]
    n_chunks = g_view_parts.shape[0]
    for ch in prange(n_chunks):
        acc = g_view_parts[ch]
        for n in range(ch * CHUNK, min(N, (ch + 1) * CHUNK)):
            if _no_cotangent(g_means2d, g_conics, g_depths, n, C):
                # every term below would be a product with a zero cotangent: skip the
                # Gaussians no pixel saw (most of a large map at a coarse level)
                for i in range(3):
                    g_means[n, i] = 0.0
                    g_scales[n, i] = 0.0
                for i in range(4):
                    g_quats[n, i] = 0.0
                continue
            (norm, w, qx, qy, qz, r00, r01, r02, r10, r11, r12, r20, r21, r22) = _rotation(
                quats[n, 0], quats[n, 1], quats[n, 2], quats[n, 3])
            s0, s1, s2 = scales[n, 0], scales[n, 1], scales[n, 2]
            m00, m01, m02 = r00 * s0, r01 * s1, r02 * s2
            m10, m11, m12 = r10 * s0, r11 * s1, r12 * s2
            m20, m21, m22 = r20 * s0, r21 * s1, r22 * s2
            px, py, pz = means[n, 0], means[n, 1], means[n, 2]
            # gradient of M summed over cameras, and of the mean
            gm00 = gm01 = gm02 = gm10 = gm11 = gm12 = gm20 = gm21 = gm22 = 0.0
            gpx = gpy = gpz = 0.0
            for c in range(C):
                fx, fy, cx, cy = Ks[c, 0, 0], Ks[c, 1, 1], Ks[c, 0, 2], Ks[c, 1, 2]
                R00, R01, R02 = viewmats[c, 0, 0], viewmats[c, 0, 1], viewmats[c, 0, 2]
                R10, R11, R12 = viewmats[c, 1, 0], viewmats[c, 1, 1], viewmats[c, 1, 2]
                R20, R21, R22 = viewmats[c, 2, 0], viewmats[c, 2, 1], viewmats[c, 2, 2]
                x = R00 * px + R01 * py + R02 * pz + viewmats[c, 0, 3]
                y = R10 * px + R11 * py + R12 * pz + viewmats[c, 1, 3]
                z = R20 * px + R21 * py + R22 * pz + viewmats[c, 2, 3]
                in_range = z > near and z < far
                zs = z if in_range else 1.0
                tan_x, tan_y = 0.5 * width / fx, 0.5 * height / fy
                tx, pass_x = _clamp_pass(x / zs, -(cx / fx + fov_clamp * tan_x),
                                         (width - cx) / fx + fov_clamp * tan_x)
                ty, pass_y = _clamp_pass(y / zs, -(cy / fy + fov_clamp * tan_y),
                                         (height - cy) / fy + fov_clamp * tan_y)
                j00, j02 = fx / zs, -fx * tx / zs
                j11, j12 = fy / zs, -fy * ty / zs
                a0 = j00 * R00 + j02 * R20
                a1 = j00 * R01 + j02 * R21
                a2_ = j00 * R02 + j02 * R22
                b0 = j11 * R10 + j12 * R20
                b1 = j11 * R11 + j12 * R21
                b2_ = j11 * R12 + j12 * R22
                v00 = a0 * m00 + a1 * m10 + a2_ * m20
                v01 = a0 * m01 + a1 * m11 + a2_ * m21
                v02 = a0 * m02 + a1 * m12 + a2_ * m22
                v10 = b0 * m00 + b1 * m10 + b2_ * m20
                v11 = b0 * m01 + b1 * m11 + b2_ * m21
                v12 = b0 * m02 + b1 * m12 + b2_ * m22
                ca = v00 * v00 + v01 * v01 + v02 * v02 + eps2d
                cb = v00 * v10 + v01 * v11 + v02 * v12
                cc = v10 * v10 + v11 * v11 + v12 * v12 + eps2d
                det = ca * cc - cb * cb
                ok = in_range and det > 0.0 and math.isfinite(det)
                det_s = det if ok else 1.0
                # conics = (cc, -cb, ca) / det_s; det_s is det only where valid
                gA, gB, gC = g_conics[c, n, 0], g_conics[c, n, 1], g_conics[c, n, 2]
                g_det = -(gA * cc - gB * cb + gC * ca) / (det_s * det_s) if ok else 0.0
                g_ca = gC / det_s + g_det * cc
                g_cc = gA / det_s + g_det * ca
                g_cb = -gB / det_s - 2.0 * cb * g_det
                # V rows
                gv00 = 2.0 * g_ca * v00 + g_cb * v10
                gv01 = 2.0 * g_ca * v01 + g_cb * v11
                gv02 = 2.0 * g_ca * v02 + g_cb * v12
                gv10 = g_cb * v00 + 2.0 * g_cc * v10
                gv11 = g_cb * v01 + 2.0 * g_cc * v11
                gv12 = g_cb * v02 + 2.0 * g_cc * v12
                # V = A M with A = [a; b] (2x3): dM[j,k] += sum_i A[i,j] dV[i,k]
                gm00 += a0 * gv00 + b0 * gv10
                gm01 += a0 * gv01 + b0 * gv11
                gm02 += a0 * gv02 + b0 * gv12
                gm10 += a1 * gv00 + b1 * gv10
                gm11 += a1 * gv01 + b1 * gv11
                gm12 += a1 * gv02 + b1 * gv12
                gm20 += a2_ * gv00 + b2_ * gv10
                gm21 += a2_ * gv01 + b2_ * gv11
                gm22 += a2_ * gv02 + b2_ * gv12
                # dA[i,j] = sum_k dV[i,k] M[j,k]
                ga0 = gv00 * m00 + gv01 * m01 + gv02 * m02
                ga1 = gv00 * m10 + gv01 * m11 + gv02 * m12
                ga2 = gv00 * m20 + gv01 * m21 + gv02 * m22
                gb0 = gv10 * m00 + gv11 * m01 + gv12 * m02
                gb1 = gv10 * m10 + gv11 * m11 + gv12 * m12
                gb2 = gv10 * m20 + gv11 * m21 + gv12 * m22
                # a = j00 R0 + j02 R2, b = j11 R1 + j12 R2
                g_j00 = ga0 * R00 + ga1 * R01 + ga2 * R02
                g_j02 = ga0 * R20 + ga1 * R21 + ga2 * R22
                g_j11 = gb0 * R10 + gb1 * R11 + gb2 * R12
                g_j12 = gb0 * R20 + gb1 * R21 + gb2 * R22
                gR00, gR01, gR02 = j00 * ga0, j00 * ga1, j00 * ga2
                gR10, gR11, gR12 = j11 * gb0, j11 * gb1, j11 * gb2
                gR20 = j02 * ga0 + j12 * gb0
                gR21 = j02 * ga1 + j12 * gb1
                gR22 = j02 * ga2 + j12 * gb2
                # J entries and the 2-D mean
                inv_z = 1.0 / zs
                gu, gv = g_means2d[c, n, 0], g_means2d[c, n, 1]
                g_tx = -fx * inv_z * g_j02
                g_ty = -fy * inv_z * g_j12
                g_zs = (-fx * g_j00 + fx * tx * g_j02 - fy * g_j11 + fy * ty * g_j12) \
                    * inv_z * inv_z
                g_x = fx * inv_z * gu
                g_y = fy * inv_z * gv
                g_zs -= (fx * x * gu + fy * y * gv) * inv_z * inv_z
                # tx = clamp(x / zs)
                g_qx, g_qy = g_tx * pass_x, g_ty * pass_y
                g_x += g_qx * inv_z
                g_y += g_qy * inv_z
                g_zs -= (g_qx * x + g_qy * y) * inv_z * inv_z
                g_z = g_depths[c, n] + (g_zs if in_range else 0.0)
                # p_c = R p + t
                gpx += R00 * g_x + R10 * g_y + R20 * g_z
                gpy += R01 * g_x + R11 * g_y + R21 * g_z
                gpz += R02 * g_x + R12 * g_y + R22 * g_z
                acc[c, 0] += gR00 + g_x * px
                acc[c, 1] += gR01 + g_x * py
                acc[c, 2] += gR02 + g_x * pz
                acc[c, 3] += gR10 + g_y * px
                acc[c, 4] += gR11 + g_y * py
                acc[c, 5] += gR12 + g_y * pz
                acc[c, 6] += gR20 + g_z * px
                acc[c, 7] += gR21 + g_z * py
                acc[c, 8] += gR22 + g_z * pz
                acc[c, 9] += g_x
                acc[c, 10] += g_y
                acc[c, 11] += g_z
            g_means[n, 0], g_means[n, 1], g_means[n, 2] = gpx, gpy, gpz
            # M[j,k] = R_q[j,k] s[k]
            g_scales[n, 0] = gm00 * r00 + gm10 * r10 + gm20 * r20
            g_scales[n, 1] = gm01 * r01 + gm11 * r11 + gm21 * r21
            g_scales[n, 2] = gm02 * r02 + gm12 * r12 + gm22 * r22
            G00, G01, G02 = gm00 * s0, gm01 * s1, gm02 * s2
            G10, G11, G12 = gm10 * s0, gm11 * s1, gm12 * s2
            G20, G21, G22 = gm20 * s0, gm21 * s1, gm22 * s2
            # rotation matrix of the unit quaternion (w, x, y, z)
            gw = 2.0 * (-qz * G01 + qy * G02 + qz * G10 - qx * G12 - qy * G20 + qx * G21)
            gx = 2.0 * (qy * G01 + qz * G02 + qy * G10 - 2.0 * qx * G11 - w * G12 + qz * G20
                        + w * G21 - 2.0 * qx * G22)
            gy = 2.0 * (-2.0 * qy * G00 + qx * G01 + w * G02 + qx * G10 + qz * G12 - w * G20
                        + qz * G21 - 2.0 * qy * G22)
            gz = 2.0 * (-2.0 * qz * G00 - w * G01 + qx * G02 + w * G10 - 2.0 * qz * G11
                        + qy * G12 + qx * G20 + qy * G21)
            # normalisation q / max(|q|, 1e-12)
            if norm > 1e-12:
                dot = w * gw + qx * gx + qy * gy + qz * gz
                inv = 1.0 / norm
                g_quats[n, 0] = (gw - w * dot) * inv
                g_quats[n, 1] = (gx - qx * dot) * inv
                g_quats[n, 2] = (gy - qy * dot) * inv
                g_quats[n, 3] = (gz - qz * dot) * inv
            else:
                g_quats[n, 0], g_quats[n, 1] = gw * 1e12, gx * 1e12
                g_quats[n, 2], g_quats[n, 3] = gy * 1e12, gz * 1e12


def _np(x: torch.Tensor) -> np.ndarray:
    return x.detach().contiguous().numpy()


def _kernel_arrays(*tensors: torch.Tensor) -> tuple[np.ndarray, ...]:
    """The inputs as contiguous numpy arrays in the dtype of the first (``means``)."""
    return tuple(_np(t.to(tensors[0].dtype)) for t in tensors)


class _ProjectFused(torch.autograd.Function):
    @staticmethod
    def forward(ctx: Any, means: torch.Tensor, quats: torch.Tensor, scales: torch.Tensor,
                opacities: torch.Tensor, viewmats: torch.Tensor, Ks: torch.Tensor,
                width: int, height: int, near: float, far: float, eps2d: float
                ) -> tuple[torch.Tensor, ...]:
        arrs = _kernel_arrays(means, quats, scales, opacities, viewmats, Ks)
        C, N = viewmats.shape[0], means.shape[0]
        dt = arrs[0].dtype
        # planes in the input dtype: numba would compare a float32 z with a float64 plane
        near_t, far_t = dt.type(near), dt.type(far)
        means2d = np.empty((C, N, 2), dt)
        conics = np.empty((C, N, 3), dt)
        depths = np.empty((C, N), dt)
        valid = np.empty((C, N), np.bool_)
        extents = np.empty((C, N, 2), dt)
        radii = np.empty((C, N), np.int32)
        project_fwd(*arrs, width, height, near_t, far_t, eps2d, RC.FOV_CLAMP, RC.ALPHA_MIN,
                    means2d, conics, depths, valid, extents, radii)
        # saved through autograd, not as numpy views: an in-place change of an input before
        # backward then raises, as it does for the PyTorch projection, instead of silently
        # differentiating at the changed values
        ctx.save_for_backward(means, quats, scales, viewmats, Ks)  # opacities: forward only
        ctx.frame = (width, height, near_t, far_t, eps2d)
        ctx.dtype = means.dtype
        out = tuple(torch.from_numpy(a) for a in (means2d, conics, depths, valid, extents,
                                                  radii))
        ctx.mark_non_differentiable(*out[3:])
        return out

    @staticmethod
    def backward(ctx: Any, g_means2d: torch.Tensor | None, g_conics: torch.Tensor | None,
                 g_depths: torch.Tensor | None, *_non_differentiable: Any
                 ) -> tuple[torch.Tensor | None, ...]:
        width, height, near, far, eps2d = ctx.frame
        means, quats, scales, viewmats, Ks = _kernel_arrays(*ctx.saved_tensors)
        C, N = viewmats.shape[0], means.shape[0]
        dt = means.dtype

        def cot(g: torch.Tensor | None, shape: tuple[int, ...]) -> np.ndarray:
            return np.zeros(shape, dt) if g is None else _np(g.to(ctx.dtype))
        g_means = np.empty((N, 3), dt)
        g_quats = np.empty((N, 4), dt)
        g_scales = np.empty((N, 3), dt)
        parts = np.zeros(((N + CHUNK - 1) // CHUNK, C, 12), np.float64)
        project_bwd(means, quats, scales, viewmats, Ks, width, height, near, far, eps2d,
                    RC.FOV_CLAMP, cot(g_means2d, (C, N, 2)), cot(g_conics, (C, N, 3)),
                    cot(g_depths, (C, N)), g_means, g_quats, g_scales, parts)
        g_view = np.zeros((C, 4, 4), dt)
        summed = parts.sum(0)
        g_view[:, :3, :3] = summed[:, :9].reshape(C, 3, 3)
        g_view[:, :3, 3] = summed[:, 9:]
        need = ctx.needs_input_grad
        return (torch.from_numpy(g_means) if need[0] else None,
                torch.from_numpy(g_quats) if need[1] else None,
                torch.from_numpy(g_scales) if need[2] else None, None,
                torch.from_numpy(g_view) if need[4] else None, None, None, None, None, None,
                None)


def project_gaussians_fused(means: torch.Tensor, quats: torch.Tensor, scales: torch.Tensor,
                            opacities: torch.Tensor, viewmats: torch.Tensor,
                            Ks: torch.Tensor,  # gsplat's name
                            width: int, height: int, near_plane: float = RC.NEAR_PLANE,
                            far_plane: float = RC.FAR_PLANE, eps2d: float = RC.EPS2D
                            ) -> Projected:
    """:func:`~egs_bench.render.projection.project_gaussians` (same arguments and outputs) on
    CPU tensors, as two numba kernels; the dtype of ``means`` is the output dtype."""
    if means.device.type != "cpu":
        raise ValueError("the fused projection needs CPU tensors")
    means2d, conics, depths, valid, extents, radii = _ProjectFused.apply(
        means, quats, scales, opacities, viewmats, Ks, width, height, float(near_plane),
        float(far_plane), float(eps2d))
    return Projected(means2d, conics, depths, valid, extents, radii)
