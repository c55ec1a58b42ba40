"""Host-side pose algebra: Lie-group functions, exposure-path Jacobians, host Adam.

References: central finite differences in float64, an independent autograd graph (the torch
implementation in this file), scipy's rotations, torch.optim.Adam.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from egs_bench.geometry.lie import (
    se3_exp,
    so3_exp,
    so3_left_jacobian,
    so3_left_jacobian_inv,
    so3_log,
    twist_gradient,
)
from egs_bench.slam.exposure import exposure_path
from egs_bench.slam.host_adam import HostAdam


def _random_pose(rng: np.random.Generator, angle: float = 0.8) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, :3] = Rotation.from_rotvec(rng.normal(size=3) * angle).as_matrix()
    pose[:3, 3] = rng.normal(size=3)
    return pose


@pytest.mark.parametrize("angle", [0.0, 1e-9, 3e-5, 2e-3, 0.15, 0.3, 1.2, 3.0])
def test_so3_exp_log_match_scipy(angle: float) -> None:
    rng = np.random.default_rng(1)
    axis = rng.normal(size=(4, 3))
    phi = axis / np.linalg.norm(axis, axis=-1, keepdims=True) * angle
    rot = so3_exp(phi)
    np.testing.assert_allclose(rot, Rotation.from_rotvec(phi).as_matrix(), atol=1e-15)
    np.testing.assert_allclose(so3_log(rot), phi, atol=1e-12)


@pytest.mark.parametrize("angle", [1e-7, 5e-3, 0.1, 0.19, 0.21, 1.0, 2.5])
def test_left_jacobian_is_the_derivative_of_exp(angle: float) -> None:
    """Exp(phi + d) Exp(phi)^T = Exp(J_l(phi) d) to first order (central differences)."""
    rng = np.random.default_rng(2)
    phi = rng.normal(size=3)
    phi *= angle / np.linalg.norm(phi)
    h = 1e-6
    numeric = np.zeros((3, 3))
    for i in range(3):
        d = np.zeros(3)
        d[i] = h
        plus = so3_log(so3_exp(phi + d) @ so3_exp(phi).T)
        minus = so3_log(so3_exp(phi - d) @ so3_exp(phi).T)
        numeric[:, i] = (plus - minus) / (2 * h)
    np.testing.assert_allclose(so3_left_jacobian(phi), numeric, atol=1e-9)
    np.testing.assert_allclose(so3_left_jacobian_inv(phi) @ so3_left_jacobian(phi), np.eye(3),
                               atol=1e-12)


def test_se3_exp_matches_the_matrix_exponential() -> None:
    from scipy.linalg import expm

    rng = np.random.default_rng(3)
    for scale in (1e-8, 1e-3, 0.5, 2.0):
        xi = rng.normal(size=6) * scale
        hat = np.zeros((4, 4))
        hat[:3, :3] = [[0, -xi[5], xi[4]], [xi[5], 0, -xi[3]], [-xi[4], xi[3], 0]]
        hat[:3, 3] = xi[:3]
        np.testing.assert_allclose(se3_exp(xi), expm(hat), atol=1e-12)


def _torch_subposes(xi: torch.Tensor, pose0: np.ndarray, pose1: np.ndarray,
                    fractions: np.ndarray) -> torch.Tensor:
    """Independent float64 autograd reference: matrix exponential of the twists, then slerp of
    camera-to-world rotations (via quaternions) and lerp of camera centres."""
    def hat(x: torch.Tensor) -> torch.Tensor:
        z = torch.zeros((), dtype=x.dtype)
        return torch.stack([torch.stack([z, -x[5], x[4], x[0]]),
                            torch.stack([x[5], z, -x[3], x[1]]),
                            torch.stack([-x[4], x[3], z, x[2]]),
                            torch.stack([z, z, z, z])])

    p0 = torch.linalg.matrix_exp(hat(xi[:6])) @ torch.tensor(pose0)
    p1 = torch.linalg.matrix_exp(hat(xi[6:])) @ torch.tensor(pose1)
    r0, r1 = p0[:3, :3].T, p1[:3, :3].T  # camera-to-world rotations
    c0, c1 = -r0 @ p0[:3, 3], -r1 @ p1[:3, 3]
    rel = r0.T @ r1
    angle = torch.arccos(((torch.trace(rel) - 1) / 2).clamp(-1, 1))
    axis = torch.stack([rel[2, 1] - rel[1, 2], rel[0, 2] - rel[2, 0], rel[1, 0] - rel[0, 1]])
    axis = axis / (2 * torch.sin(angle))
    out = []
    for f in fractions:
        w = torch.linalg.matrix_exp(hat(torch.cat([torch.zeros(3, dtype=xi.dtype),
                                                   axis * angle * float(f)])))[:3, :3]
        rot = r0 @ w
        centre = (1 - float(f)) * c0 + float(f) * c1
        top = torch.cat([rot.T, (-rot.T @ centre)[:, None]], 1)
        out.append(torch.cat([top, torch.tensor([[0.0, 0, 0, 1]], dtype=xi.dtype)], 0))
    return torch.stack(out)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_exposure_path_values_and_jacobian_match_autograd(seed: int) -> None:
    rng = np.random.default_rng(seed)
    pose0 = _random_pose(rng)
    delta = np.eye(4)
    delta[:3, :3] = Rotation.from_rotvec(rng.normal(size=3) * 0.2).as_matrix()
    delta[:3, 3] = rng.normal(size=3) * 0.1
    pose1 = delta @ pose0
    fractions = np.array([0.0, 0.2, 0.55, 0.8, 1.0])
    views, jac = exposure_path(pose0, pose1, fractions)
    xi = torch.zeros(12, dtype=torch.float64, requires_grad=True)
    ref = _torch_subposes(xi, pose0, pose1, fractions)
    np.testing.assert_allclose(views, ref.detach().numpy(), atol=1e-12)
    # A random loss on the sub-poses: dL/dxi from autograd vs from the Jacobians.
    weights = torch.tensor(rng.normal(size=(5, 4, 4)))
    (ref * weights).sum().backward()
    g_eta = twist_gradient(views, weights.numpy())  # [M, 6]
    ours = np.einsum("mi,mij->j", g_eta, jac)
    assert xi.grad is not None
    np.testing.assert_allclose(ours, xi.grad.numpy(), rtol=1e-9, atol=1e-9)


def test_exposure_path_without_blur_is_the_end_pose() -> None:
    rng = np.random.default_rng(5)
    pose1 = _random_pose(rng)
    views, jac = exposure_path(_random_pose(rng), pose1, np.array([1.0]))
    np.testing.assert_array_equal(views[0], pose1)
    np.testing.assert_array_equal(jac[0, :, :6], 0)
    np.testing.assert_array_equal(jac[0, :, 6:], np.eye(6))


def test_host_adam_equals_torch_adam_with_exponential_decay() -> None:
    rng = np.random.default_rng(4)
    lr = np.array([0.001] * 3 + [0.003] * 3 + [0.01] * 2)
    gamma = 0.95
    param = torch.zeros(8, dtype=torch.float64, requires_grad=True)
    opt = torch.optim.Adam([{"params": [param], "lr": 1.0}])
    # per-element lr through a scaled parametrisation is not Adam; use one group per lr value
    groups = [torch.zeros(k, dtype=torch.float64, requires_grad=True) for k in (3, 3, 2)]
    opt = torch.optim.Adam([{"params": [g], "lr": v} for g, v in zip(groups, (0.001, 0.003,
                                                                              0.01), strict=True)])
    sched = torch.optim.lr_scheduler.ExponentialLR(opt, gamma)
    host = HostAdam(lr, gamma)
    ours = np.zeros(8)
    for _ in range(25):
        grad = rng.normal(size=8) * rng.uniform(0.01, 10)
        for g, part in zip(groups, np.split(grad, [3, 6]), strict=True):
            g.grad = torch.tensor(part)
        opt.step()
        sched.step()
        ours += host.step(grad)
    np.testing.assert_allclose(ours, torch.cat([g.detach() for g in groups]).numpy(),
                               rtol=1e-12, atol=1e-15)


def test_host_adam_skip_advances_the_decay_as_the_scheduler_does() -> None:
    """``skip(n)`` leaves the moments alone and moves the learning rate n scheduler steps on:
    the next update equals torch's after n scheduler steps without an optimiser step."""
    rng = np.random.default_rng(5)
    gamma, lr = 0.8, np.array([0.01, 0.02, 0.03])
    grads = rng.normal(size=(2, 3))
    host = HostAdam(lr, gamma)
    ours = host.step(grads[0])
    host.skip(4)
    ours = ours + host.step(grads[1])
    # torch, one optimiser per element (per-element rates): its scheduler steps 1 + 4 times
    # between the two updates
    expected = np.zeros(3)
    for i in range(3):
        p = torch.zeros(1, dtype=torch.float64, requires_grad=True)
        o = torch.optim.Adam([p], lr=float(lr[i]))
        s = torch.optim.lr_scheduler.ExponentialLR(o, gamma)
        for step, scheduler_steps in ((0, 1 + 4), (1, 1)):
            p.grad = torch.tensor([grads[step, i]], dtype=torch.float64)
            o.step()
            for _ in range(scheduler_steps):
                s.step()
        expected[i] = float(p.detach()[0])
    np.testing.assert_allclose(ours, expected, rtol=1e-12, atol=1e-15)
