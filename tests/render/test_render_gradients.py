"""Backward pass: tile backend vs dense reference (same cotangent), finite differences."""

from __future__ import annotations

from typing import Any

import pytest
import torch

from egs_bench.render import rasterize
from egs_bench.render.rasterize import Backend
from tests.helpers.render_scenes import leaf_copy, random_scene, se3_exp

PARAMS = ("means", "quats", "scales", "opacities", "colors", "viewmats")


def _grads(scene: dict[str, Any], backend: Backend, cot: dict[str, torch.Tensor],
           backgrounds: torch.Tensor | None = None) -> dict[str, torch.Tensor]:
    s = leaf_copy(scene)
    bg = None
    if backgrounds is not None:
        bg = backgrounds.detach().clone().requires_grad_(True)
    out = rasterize(**s, backend=backend, backgrounds=bg)
    loss = ((out.rgb * cot["rgb"]).sum() + (out.depth * cot["depth"]).sum()
            + (out.alpha * cot["alpha"]).sum() + (out.expected_depth * cot["ed"]).sum())
    loss.backward()
    g = {k: s[k].grad for k in PARAMS}
    if bg is not None:
        g["backgrounds"] = bg.grad
    assert all(v is not None for v in g.values())
    return g


def _cotangent(scene: dict[str, Any], seed: int, dtype: torch.dtype) -> dict[str, torch.Tensor]:
    c, h, w = scene["viewmats"].shape[0], scene["height"], scene["width"]
    gen = torch.Generator().manual_seed(seed)
    return {"rgb": torch.randn(c, h, w, 3, generator=gen, dtype=torch.float64).to(dtype),
            "depth": torch.randn(c, h, w, generator=gen, dtype=torch.float64).to(dtype),
            "alpha": torch.randn(c, h, w, generator=gen, dtype=torch.float64).to(dtype),
            "ed": torch.randn(c, h, w, generator=gen, dtype=torch.float64).to(dtype)}


@pytest.mark.parametrize("n,c,seed,opaque", [(200, 3, 0, False), (300, 2, 1, True),
                                              (60, 1, 2, False)])
def test_gradients_match_reference_float64(n: int, c: int, seed: int, opaque: bool) -> None:
    scene = random_scene(n=n, c=c, seed=seed, scale_range=(0.05, 0.3) if opaque else
                         (0.02, 0.25))
    if opaque:  # clamped alphas and the early stop both occur
        scene["opacities"] = torch.where(scene["opacities"] > 0.5, 0.995, scene["opacities"])
    cot = _cotangent(scene, seed + 10, torch.float64)
    bg = torch.rand(c, 3, dtype=torch.float64)
    ref = _grads(scene, "reference", cot, bg)
    got = _grads(scene, "numba", cot, bg)
    for k, g_ref in ref.items():
        assert g_ref.abs().max() > 0, k
        torch.testing.assert_close(got[k], g_ref, rtol=1e-9, atol=1e-9 * float(g_ref.abs().max()),
                                   msg=k)


def test_gradients_match_reference_float32() -> None:
    scene = random_scene(n=200, c=3, seed=3, dtype=torch.float32)
    cot = _cotangent(scene, 13, torch.float32)
    ref = _grads(scene, "reference", cot)
    got = _grads(scene, "numba", cot)
    for k in PARAMS:
        rel = (got[k] - ref[k]).norm() / ref[k].norm()
        assert rel < 1e-4, (k, float(rel))


@pytest.mark.parametrize("backend", ["numba", "reference"])
def test_pose_gradient_matches_finite_differences(backend: Backend) -> None:
    # se(3) perturbation of each camera, left-multiplied on the world-to-camera matrix (the
    # tracking parametrisation); central differences in float64.
    scene = random_scene(n=40, c=2, seed=4, opacity_scale=0.8)
    view0 = scene["viewmats"]
    cot = _cotangent(scene, 14, torch.float64)

    def loss_of(xi: torch.Tensor) -> torch.Tensor:
        s = dict(scene, viewmats=se3_exp(xi) @ view0)
        out = rasterize(**s, backend=backend)
        return ((out.rgb * cot["rgb"]).sum() + (out.depth * cot["depth"]).sum()
                + (out.alpha * cot["alpha"]).sum())

    xi = torch.zeros(2, 6, dtype=torch.float64, requires_grad=True)
    loss_of(xi).backward()
    assert xi.grad is not None
    analytic = xi.grad.clone()
    numeric = torch.zeros_like(analytic)
    eps = 1e-6
    with torch.no_grad():
        for c in range(2):
            for i in range(6):
                d = torch.zeros_like(xi)
                d[c, i] = eps
                numeric[c, i] = (loss_of(d) - loss_of(-d)) / (2 * eps)
    assert analytic.abs().min() > 1e-3  # every pose direction matters in this scene
    torch.testing.assert_close(analytic, numeric, rtol=1e-5, atol=1e-5)


def test_pose_only_backward_leaves_map_without_grad() -> None:
    scene = random_scene(n=100, c=2, seed=5, dtype=torch.float32)
    vm = scene["viewmats"].clone().requires_grad_(True)
    out = rasterize(**dict(scene, viewmats=vm))
    (out.rgb.mean() + out.depth.mean()).backward()
    assert vm.grad is not None and vm.grad.abs().max() > 0
    assert scene["means"].grad is None


def test_gradients_deterministic() -> None:
    scene = random_scene(n=300, c=3, seed=6, dtype=torch.float32)
    cot = _cotangent(scene, 16, torch.float32)
    a, b = _grads(scene, "numba", cot), _grads(scene, "numba", cot)
    for k in PARAMS:
        assert torch.equal(a[k], b[k]), k


def test_gaussians_out_of_view_get_zero_gradient() -> None:
    scene = random_scene(n=30, c=1, seed=7)
    scene["means"][0] = torch.tensor([0.0, 0.0, -2.0], dtype=torch.float64)  # behind
    scene["means"][1] = torch.tensor([80.0, 0.0, 2.0], dtype=torch.float64)  # off to the side
    cot = _cotangent(scene, 17, torch.float64)
    g = _grads(scene, "numba", cot)
    for k in ("means", "quats", "scales", "opacities", "colors"):
        assert torch.isfinite(g[k]).all()
        assert g[k][:2].abs().max() == 0, k
