"""SO(3)/SE(3) exponential, logarithm and Jacobians in float64 numpy, batched over leading axes.

Twists are ``xi = (rho, phi)`` (translation first, as MonoGS) and act on the left of a
world-to-camera matrix: ``T <- Exp(xi) @ T`` with ``Exp(xi) = [[Exp(phi), J_l(phi) rho], [0, 1]]``.

The SLAM runs its pose algebra here, on the host, rather than as autograd graphs on the
device: per tracking iteration a handful of 3x3 products replace several hundred tiny tensor
operations, each of which is a kernel launch on a GPU. Gradients with respect to twists come
from the closed-form Jacobians below (exact at zero twist, which is where they are used),
tested against finite differences. Hand-written because scipy's ``Rotation`` has no Jacobians
and the closed forms are a few lines.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.spatial.transform import Rotation

# Angles (rad) below which each coefficient is taken from its Taylor series. A = sin t / t and
# B = 2 sin^2(t/2) / t^2 are stable closed forms (the series only avoids 0/0); C and D subtract
# nearly equal numbers, losing about 1e-16 / t^2 relative precision, so their series (whose
# first omitted terms are below 1e-17 relative at these angles) take over earlier.
_SERIES_AB, _SERIES_CD = 1e-4, 0.2


def skew(v: np.ndarray) -> np.ndarray:
    """Skew-symmetric matrices [..., 3, 3] of vectors [..., 3] (``skew(a) @ b = a x b``)."""
    v = np.asarray(v, dtype=np.float64)
    out = np.zeros((*v.shape[:-1], 3, 3))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


def _coefficients(phi: np.ndarray) -> tuple[np.ndarray, ...]:
    """Per angle ``t = |phi|`` [...]: A = sin t / t, B = (1 - cos t) / t^2, C = (t - sin t) / t^3
    and D = (1 - t sin t / (2 (1 - cos t))) / t^2 (the J_l^-1 coefficient)."""
    t = np.linalg.norm(phi, axis=-1)
    t2 = t * t
    t4 = t2 * t2

    def closed(below: float, series: np.ndarray,
               form: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
        small = t < below
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(small, series, form(np.where(small, 1.0, t)))

    a = closed(_SERIES_AB, 1 - t2 / 6 + t4 / 120, lambda x: np.sin(x) / x)
    b = closed(_SERIES_AB, 0.5 - t2 / 24 + t4 / 720, lambda x: 2 * np.sin(0.5 * x) ** 2 / (x * x))
    c = closed(_SERIES_CD, 1 / 6 - t2 / 120 + t4 / 5040 - t4 * t2 / 362880 + t4 * t4 / 39916800,
               lambda x: (x - np.sin(x)) / x ** 3)
    d = closed(_SERIES_CD, 1 / 12 + t2 / 720 + t4 / 30240 + t4 * t2 / 1209600
               + t4 * t4 / 47900160, lambda x: (1 - 0.5 * x / np.tan(0.5 * x)) / (x * x))
    return a, b, c, d


def _eye_plus(k1: np.ndarray, w: np.ndarray, k2: np.ndarray) -> np.ndarray:
    """``I + k1 W + k2 W^2`` for coefficients [...] and skew matrices W [..., 3, 3]."""
    return np.eye(3) + k1[..., None, None] * w + k2[..., None, None] * (w @ w)


def so3_exp(phi: np.ndarray) -> np.ndarray:
    """Rotation matrices [..., 3, 3] of rotation vectors [..., 3] (Rodrigues)."""
    phi = np.asarray(phi, dtype=np.float64)
    a, b, _, _ = _coefficients(phi)
    return _eye_plus(a, skew(phi), b)


def so3_log(rot: np.ndarray) -> np.ndarray:
    """Rotation vectors [..., 3] of rotation matrices [..., 3, 3] (angles in [0, pi])."""
    rot = np.asarray(rot, dtype=np.float64)
    vee = 0.5 * np.stack([rot[..., 2, 1] - rot[..., 1, 2], rot[..., 0, 2] - rot[..., 2, 0],
                          rot[..., 1, 0] - rot[..., 0, 1]], -1)  # sin(angle) * axis
    cos = 0.5 * (np.trace(rot, axis1=-2, axis2=-1) - 1)
    sin = np.linalg.norm(vee, axis=-1)
    angle = np.arctan2(sin, cos)
    small = sin < _SERIES_AB
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.where(small, 1 + angle * angle / 6, angle / np.where(small, 1.0, sin))
    out = vee * scale[..., None]
    # Beyond 90 deg the axis is better read from the symmetric part; scipy's quaternion route
    # does that (and is exact at pi, where sin(angle) * axis vanishes).
    wide = cos < 0
    if np.any(wide):
        out[wide] = Rotation.from_matrix(rot[wide]).as_rotvec()
    return out


def so3_left_jacobian(phi: np.ndarray) -> np.ndarray:
    """``J_l(phi)`` [..., 3, 3]: ``Exp(phi + d) = Exp(J_l(phi) d) Exp(phi)`` to first order."""
    phi = np.asarray(phi, dtype=np.float64)
    _, b, c, _ = _coefficients(phi)
    return _eye_plus(b, skew(phi), c)


def so3_left_jacobian_inv(phi: np.ndarray) -> np.ndarray:
    """``J_l(phi)^-1`` [..., 3, 3]: ``Log(Exp(d) Exp(phi)) = phi + J_l^-1(phi) d`` to first
    order. The right Jacobian's inverse is ``so3_left_jacobian_inv(-phi)``."""
    phi = np.asarray(phi, dtype=np.float64)
    _, _, _, d = _coefficients(phi)
    return _eye_plus(np.full(d.shape, -0.5), skew(phi), d)


def se3_exp(xi: np.ndarray) -> np.ndarray:
    """4x4 rigid transforms [..., 4, 4] of twists [..., 6] = (rho, phi)."""
    xi = np.asarray(xi, dtype=np.float64)
    rho, phi = xi[..., :3], xi[..., 3:]
    a, b, c, _ = _coefficients(phi)
    w = skew(phi)
    out = np.zeros((*xi.shape[:-1], 4, 4))
    out[..., :3, :3] = _eye_plus(a, w, b)
    out[..., :3, 3] = (_eye_plus(b, w, c) @ rho[..., None])[..., 0]
    out[..., 3, 3] = 1.0
    return out


def twist_gradient(viewmats: np.ndarray, grad_viewmats: np.ndarray) -> np.ndarray:
    """Gradient [..., 6] of a loss w.r.t. left twists ``xi`` of ``T(xi) = Exp(xi) @ T`` at xi = 0.

    Args:
        viewmats: the transforms ``T`` [..., 4, 4].
        grad_viewmats: ``dL/dT`` [..., 4, 4] (e.g. from the rasteriser's backward).
    """
    v = np.asarray(viewmats, dtype=np.float64)
    g = np.asarray(grad_viewmats, dtype=np.float64)
    p = g[..., :3, :] @ np.swapaxes(v[..., :3, :], -1, -2)  # [..., 3, 3]
    rot = np.stack([p[..., 2, 1] - p[..., 1, 2], p[..., 0, 2] - p[..., 2, 0],
                    p[..., 1, 0] - p[..., 0, 1]], -1)
    return np.concatenate([g[..., :3, 3], rot], -1)
