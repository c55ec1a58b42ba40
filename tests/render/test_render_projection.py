"""Fused numba projection against the PyTorch statement of the math and finite differences."""

from __future__ import annotations

from typing import Any

import pytest
import torch

from egs_bench.render.numba_projection import CHUNK, project_gaussians_fused
from egs_bench.render.projection import project_gaussians
from tests.helpers.render_scenes import leaf_copy, random_scene

DIFFERENTIABLE = ("means", "quats", "scales", "viewmats")
ARGS = ("means", "quats", "scales", "opacities", "viewmats", "Ks", "width", "height")


def _edge_scene(n: int, c: int, seed: int, dtype: torch.dtype = torch.float64) -> dict:
    """A random scene plus Gaussians behind the cameras, beyond a far plane of 4 m, far off
    screen (the Jacobian clamp), nearly degenerate, and exactly on the near plane."""
    scene = random_scene(n=n, c=c, seed=seed, dtype=dtype)
    means = scene["means"].clone()
    means[0] = torch.tensor([0.1, 0.0, -1.0])  # behind
    means[1] = torch.tensor([0.0, 0.1, 4.5])  # beyond far=4
    means[2] = torch.tensor([5.0, -0.2, 1.0])  # far right of the image: x/z clamped
    means[3] = torch.tensor([-0.3, -6.0, 1.2])  # far above: y/z clamped
    means[4] = torch.tensor([0.0, 0.0, 0.2])  # near plane (0.2 below)
    scales = scene["scales"].clone()
    scales[5] = torch.tensor([1e-6, 1e-6, 1e-6])  # footprint is the dilation alone
    scene.update(means=means.to(dtype), scales=scales.to(dtype))
    return scene


def _both(scene: dict, near: float = 0.2, far: float = 4.0) -> list[tuple[dict, Any]]:
    out = []
    for project in (project_gaussians, project_gaussians_fused):
        s = leaf_copy(scene)
        p = project(*(s[k] for k in ARGS), near_plane=near, far_plane=far)  # type: ignore[misc]
        out.append((s, p))
    return out


def _backward_with(p: Any, cot: list[torch.Tensor]) -> None:
    """Back-propagate the cotangents ``cot`` of (means2d, conics, depths) through ``p``."""
    loss = sum((t * g).sum() for t, g in zip((p.means2d, p.conics, p.depths), cot, strict=True))
    loss.backward()


@pytest.mark.parametrize("seed", [0, 1])
def test_forward_matches_pytorch_float64(seed: int) -> None:
    (_, ref), (_, got) = _both(_edge_scene(300, 3, seed))
    for name in ("means2d", "conics", "depths", "extents"):
        torch.testing.assert_close(getattr(got, name), getattr(ref, name), rtol=1e-12,
                                   atol=1e-12, msg=name)
    assert torch.equal(got.valid, ref.valid)
    assert torch.equal(got.radii, ref.radii)
    assert not bool(ref.valid[:, 0].any()) and not bool(ref.valid[:, 1].any())
    assert bool(ref.valid[:, 2].all())  # clamped, still valid


@pytest.mark.parametrize("c", [2, 3])
def test_forward_matches_pytorch_float32(c: int) -> None:
    """Three cameras include the identity, where Gaussian 4 lies exactly on the near plane."""
    (_, ref), (_, got) = _both(_edge_scene(300, c, 3, torch.float32))
    assert got.means2d.dtype == torch.float32
    for name in ("means2d", "conics", "depths"):
        torch.testing.assert_close(getattr(got, name), getattr(ref, name), rtol=2e-5,
                                   atol=1e-5, msg=name)
    # the camera-space point and the culling are float32 in both: the same Gaussians survive
    assert torch.equal(got.valid, ref.valid)
    # the footprint is float64 after the division in the kernel: a box edge may round apart
    assert (got.radii - ref.radii).abs().max() <= 1


def test_float32_planes_cull_as_pytorch() -> None:
    """float32 points exactly on the near and far planes (0.2 and 4.0 m, neither exact in
    binary) and one float32 step inside each: culled and kept as PyTorch's comparison does."""
    scene = random_scene(n=6, c=1, seed=4, dtype=torch.float32)
    scene["viewmats"] = torch.eye(4).expand(1, 4, 4).clone()
    z = torch.tensor([0.2, 4.0], dtype=torch.float32)
    inside = torch.nextafter(z, torch.tensor([1.0, 1.0]))
    means = torch.zeros(6, 3)
    means[:4, 2] = torch.cat([z, inside])
    means[4:, 2] = 1.0
    scene["means"] = means
    (_, ref), (_, got) = _both(scene)
    assert ref.valid[0].tolist() == [False, False, True, True, True, True]
    assert torch.equal(got.valid, ref.valid)


def test_inplace_change_before_backward_raises() -> None:
    """Autograd's version check covers the fused projection's saved inputs, as it covers the
    PyTorch one's: gradients at silently changed values are refused."""
    for project in (project_gaussians, project_gaussians_fused):
        s = leaf_copy(_edge_scene(20, 2, 8))
        p = project(*(s[k] for k in ARGS), near_plane=0.2, far_plane=4.0)  # type: ignore[misc]
        with torch.no_grad():
            s["means"].add_(0.01)
        with pytest.raises(RuntimeError, match="inplace"):
            p.means2d.sum().backward()


def test_camera_gradient_independent_of_thread_count() -> None:
    """The camera gradient is summed over fixed chunks in order: the same bits on 1 thread
    and on every thread numba has (more than one chunk of Gaussians)."""
    numba = pytest.importorskip("numba")
    threads = numba.config.NUMBA_NUM_THREADS
    if threads < 2:
        pytest.skip("numba has one thread here")
    scene = _edge_scene(3 * CHUNK + 5, 3, 9, torch.float32)
    grads = []
    before = numba.get_num_threads()
    try:
        for n in (1, threads):
            numba.set_num_threads(n)
            s = leaf_copy(scene)
            p = project_gaussians_fused(*(s[k] for k in ARGS),  # type: ignore[misc]
                                        near_plane=0.2, far_plane=4.0)
            (p.means2d.sum() + p.conics.sum() + p.depths.sum()).backward()
            grads.append(s["viewmats"].grad)
    finally:
        numba.set_num_threads(before)
    assert grads[0].abs().max() > 0
    assert torch.equal(grads[0], grads[1])


@pytest.mark.parametrize("n", [300, CHUNK + 37])
def test_gradients_match_pytorch_autograd(n: int) -> None:
    """Every input gradient, including the ``where``/clamp branches, for a random cotangent;
    more than one chunk of camera partial sums for the larger scene."""
    (s_ref, ref), (s_got, got) = _both(_edge_scene(n, 3, 7))
    gen = torch.Generator().manual_seed(11)
    cot = [torch.randn(t.shape, generator=gen, dtype=torch.float64)
           for t in (ref.means2d, ref.conics, ref.depths)]
    for p in (ref, got):
        _backward_with(p, cot)
    for k in DIFFERENTIABLE:
        g_ref, g_got = s_ref[k].grad, s_got[k].grad
        assert g_ref.abs().max() > 0, k
        torch.testing.assert_close(g_got, g_ref, rtol=1e-9, atol=1e-9 * g_ref.abs().max(),
                                   msg=k)


def test_gradients_with_sparse_cotangents_match_pytorch_autograd() -> None:
    """The backward skips Gaussians whose cotangents are zero in every camera (most of a large
    map at a coarse level): those get exact zeros, and a Gaussian with a single non-zero
    cotangent entry (only its depth, only one conic entry in one camera) gets its full
    gradient."""
    (s_ref, ref), (s_got, got) = _both(_edge_scene(300, 3, 12))
    gen = torch.Generator().manual_seed(13)
    cot = [torch.randn(t.shape, generator=gen, dtype=torch.float64)
           for t in (ref.means2d, ref.conics, ref.depths)]
    seen = torch.nonzero(ref.valid[:, 150:].all(0)).flatten() + 150
    depth_only, one_entry = torch.arange(100, 150), seen[:20]
    silent = torch.ones(300, dtype=torch.bool)
    silent[:150] = silent[one_entry] = False
    cot[0][:, 100:] = cot[1][:, 100:] = 0.0
    cot[2][:, 150:] = 0.0
    cot[1][1, one_entry[:10], 1] = 0.7  # camera 1's conic b alone
    cot[1][2, one_entry[10:], 2] = -1.5  # camera 2's conic c alone
    for p in (ref, got):
        _backward_with(p, cot)
    for k in DIFFERENTIABLE:
        g_ref, g_got = s_ref[k].grad, s_got[k].grad
        torch.testing.assert_close(g_got, g_ref, rtol=1e-9, atol=1e-9 * g_ref.abs().max(),
                                   msg=k)
        if k != "viewmats":
            assert bool((g_got[silent] == 0).all()), k
    for singles in (depth_only, one_entry):
        assert bool((s_ref["means"].grad[singles].abs().sum(-1) > 0).all())


def test_gradients_against_finite_differences() -> None:
    scene = _edge_scene(12, 2, 5)
    s = leaf_copy(scene)
    weights = [torch.rand(shape, dtype=torch.float64, generator=torch.Generator().manual_seed(
        i)) for i, shape in enumerate(((2, 12, 2), (2, 12, 3), (2, 12)))]

    def f(means: torch.Tensor, quats: torch.Tensor, scales: torch.Tensor,
          viewmats: torch.Tensor) -> torch.Tensor:
        p = project_gaussians_fused(means, quats, scales, s["opacities"], viewmats, s["Ks"],
                                    s["width"], s["height"], near_plane=0.2, far_plane=4.0)
        return torch.stack([(t * w).sum() for t, w in zip((p.means2d, p.conics, p.depths), weights,
                                                          strict=True)]).sum()

    assert torch.autograd.gradcheck(f, tuple(s[k] for k in DIFFERENTIABLE), eps=1e-6,
                                    atol=1e-5, rtol=1e-4)


def test_camera_alone_equals_camera_in_batch() -> None:
    """Each (camera, Gaussian) pair is computed on its own: bit-identical outputs."""
    scene = random_scene(n=500, c=4, seed=2, dtype=torch.float32)
    args: list[Any] = [scene[k] for k in ARGS]
    batch = project_gaussians_fused(*args)
    for c in range(4):
        means, quats, scales, opacities = args[:4]
        one = project_gaussians_fused(means, quats, scales, opacities, scene["viewmats"][c:c + 1],
                                      scene["Ks"][c:c + 1], scene["width"], scene["height"])
        assert torch.equal(one.means2d[0], batch.means2d[c])
        assert torch.equal(one.conics[0], batch.conics[c])
