"""SE(3)/SO(3) exponential and logarithm in PyTorch (differentiable, batched, float32/float64).

Pose updates follow MonoGS: a twist ``xi = (rho, theta)`` (translation first) left-multiplies a
world-to-camera matrix, ``T_cw <- exp(xi) @ T_cw``. Hand-written because the closed forms are
a few lines and we need stable gradients at exactly zero twist (kornia's versions divide by the
angle there).
"""

from __future__ import annotations

import torch

_SMALL = 1e-4  # below this angle (rad) the Taylor expansions are exact to float64 precision


def skew(v: torch.Tensor) -> torch.Tensor:
    """Skew-symmetric matrices [..., 3, 3] of vectors [..., 3] (``skew(a) @ b = a x b``)."""
    x, y, z = v.unbind(-1)
    zero = torch.zeros_like(x)
    rows = [
        torch.stack([zero, -z, y], -1),
        torch.stack([z, zero, -x], -1),
        torch.stack([-y, x, zero], -1),
    ]
    return torch.stack(rows, -2)


def _angle_coefficients(theta: torch.Tensor) -> tuple[torch.Tensor, ...]:
    """A = sin(t)/t, B = (1-cos t)/t^2, C = (t - sin t)/t^3 for angles [...], safe at t = 0."""
    small = theta < _SMALL
    t = torch.where(small, torch.ones_like(theta), theta)  # keeps the unused branch finite
    t2 = theta * theta
    a = torch.where(small, 1 - t2 / 6, torch.sin(t) / t)
    b = torch.where(small, 0.5 - t2 / 24, (1 - torch.cos(t)) / (t * t))
    c = torch.where(small, 1.0 / 6 - t2 / 120, (t - torch.sin(t)) / (t * t * t))
    return a, b, c


def _safe_norm(v: torch.Tensor) -> torch.Tensor:
    """Euclidean norm over the last axis with a finite (zero) gradient at v = 0."""
    sq = (v * v).sum(-1)
    nonzero = sq > 0
    return torch.where(nonzero, torch.sqrt(torch.where(nonzero, sq, torch.ones_like(sq))), sq)


def so3_exp(theta: torch.Tensor) -> torch.Tensor:
    """Rotation matrices [..., 3, 3] from rotation vectors [..., 3] (Rodrigues)."""
    angle = _safe_norm(theta)
    a, b, _ = _angle_coefficients(angle)
    w = skew(theta)
    eye = torch.eye(3, dtype=theta.dtype, device=theta.device).expand_as(w)
    return eye + a[..., None, None] * w + b[..., None, None] * (w @ w)


def so3_log(rot: torch.Tensor) -> torch.Tensor:
    """Rotation vectors [..., 3] of rotation matrices [..., 3, 3], valid for angles < pi.

    Exposure-time motion is far below pi, which is the only use here.
    """
    vee = torch.stack(
        [rot[..., 2, 1] - rot[..., 1, 2], rot[..., 0, 2] - rot[..., 2, 0],
         rot[..., 1, 0] - rot[..., 0, 1]], -1
    ) * 0.5  # = sin(angle) * axis
    cos = ((rot[..., 0, 0] + rot[..., 1, 1] + rot[..., 2, 2]) - 1) * 0.5
    sin = _safe_norm(vee)
    angle = torch.atan2(sin, cos)
    small = sin < _SMALL
    safe_sin = torch.where(small, torch.ones_like(sin), sin)
    scale = torch.where(small, 1 + angle * angle / 6, angle / safe_sin)
    return vee * scale[..., None]


def se3_exp(xi: torch.Tensor) -> torch.Tensor:
    """4x4 rigid transforms [..., 4, 4] from twists [..., 6] = (rho, theta)."""
    rho, theta = xi[..., :3], xi[..., 3:]
    angle = _safe_norm(theta)
    a, b, c = _angle_coefficients(angle)
    w = skew(theta)
    w2 = w @ w
    eye = torch.eye(3, dtype=xi.dtype, device=xi.device).expand_as(w)
    rot = eye + a[..., None, None] * w + b[..., None, None] * w2
    v = eye + b[..., None, None] * w + c[..., None, None] * w2
    trans = (v @ rho[..., None])[..., 0]
    return make_pose(rot, trans)


def make_pose(rot: torch.Tensor, trans: torch.Tensor) -> torch.Tensor:
    """Stack rotations [..., 3, 3] and translations [..., 3] into 4x4 transforms [..., 4, 4]."""
    top = torch.cat([rot, trans[..., None]], -1)
    bottom = torch.zeros(*rot.shape[:-2], 1, 4, dtype=rot.dtype, device=rot.device)
    bottom[..., 0, 3] = 1
    return torch.cat([top, bottom], -2)


def invert_rigid(pose: torch.Tensor) -> torch.Tensor:
    """Inverse [..., 4, 4] of rigid transforms [..., 4, 4] (R^T, -R^T t)."""
    rot_t = pose[..., :3, :3].transpose(-1, -2)
    return make_pose(rot_t, -(rot_t @ pose[..., :3, 3:4])[..., 0])


def apply_left_increment(pose_cw: torch.Tensor, xi: torch.Tensor) -> torch.Tensor:
    """MonoGS update ``exp(xi) @ T_cw`` for poses [..., 4, 4] and twists [..., 6]."""
    return se3_exp(xi) @ pose_cw
