"""Forward pass: tile backend vs the dense reference, analytic cases, edge cases."""

from __future__ import annotations

import math
from typing import Any

import pytest
import torch

from egs_bench.errors import ConfigError
from egs_bench.render import constants as RC
from egs_bench.render import project_gaussians, rasterize
from egs_bench.render.rasterize import Backend, RasterResult
from tests.helpers.render_scenes import random_scene

FIELDS = ("rgb", "depth", "expected_depth", "alpha")


def _both(scene: dict[str, Any], **kw: Any) -> tuple[RasterResult, RasterResult]:
    return rasterize(**scene, backend="reference", **kw), rasterize(**scene, backend="numba", **kw)


def _assert_same(ref: RasterResult, out: RasterResult, atol: float) -> None:
    for f in FIELDS:
        torch.testing.assert_close(getattr(out, f), getattr(ref, f), atol=atol, rtol=0, msg=f)
    assert out.visibility is not None and ref.visibility is not None
    assert torch.equal(out.visibility, ref.visibility)
    assert torch.equal(out.radii, ref.radii)


@pytest.mark.parametrize("n,c,seed", [(150, 1, 0), (300, 3, 1), (40, 2, 2)])
def test_numba_matches_reference_float64(n: int, c: int, seed: int) -> None:
    scene = random_scene(n=n, c=c, seed=seed)
    ref, out = _both(scene)
    assert 0.05 < ref.alpha.mean() < 0.999  # a scene where compositing actually matters
    _assert_same(ref, out, atol=1e-12)


def test_numba_matches_reference_dense_scene_with_stop_rule() -> None:
    # Many opaque, large Gaussians: T hits the 1e-4 stop and alpha clamps at 0.99.
    scene = random_scene(n=400, c=2, seed=3, scale_range=(0.1, 0.4))
    scene["opacities"] = torch.full_like(scene["opacities"], 0.995)
    ref, out = _both(scene)
    assert (ref.alpha > 1 - 2 * RC.T_MIN).float().mean() > 0.3
    assert ref.alpha.max() < 1 - RC.T_MIN  # the stop rule is exclusive
    _assert_same(ref, out, atol=1e-12)


def test_numba_matches_reference_float32() -> None:
    scene = random_scene(n=300, c=3, seed=4, dtype=torch.float32)
    ref, out = _both(scene)
    assert out.rgb.dtype == torch.float32
    for f in FIELDS:
        torch.testing.assert_close(getattr(out, f), getattr(ref, f), atol=2e-5, rtol=1e-5)


def test_single_gaussian_matches_closed_form() -> None:
    # Isotropic Gaussian on the optical axis: Sigma_2d = (f s / z)^2 I + EPS2D I.
    f, z, s, o = 40.0, 2.0, 0.05, 0.8
    means = torch.tensor([[0.0, 0.0, z]], dtype=torch.float64)
    K = torch.tensor([[[f, 0, 16.0], [0, f, 12.0], [0, 0, 1]]], dtype=torch.float64)
    out = rasterize(means, torch.tensor([[1.0, 0, 0, 0]], dtype=torch.float64),
                    torch.full((1, 3), s, dtype=torch.float64),
                    torch.tensor([o], dtype=torch.float64),
                    torch.tensor([[1.0, 0.5, 0.25]]).double(), torch.eye(4).double()[None], K,
                    32, 24)
    var = (f * s / z) ** 2 + RC.EPS2D
    v, u = torch.meshgrid(torch.arange(24.0), torch.arange(32.0), indexing="ij")
    d2 = ((u + 0.5 - 16.0) ** 2 + (v + 0.5 - 12.0) ** 2).double()
    alpha = torch.clamp(o * torch.exp(-0.5 * d2 / var), max=RC.ALPHA_MAX)
    alpha = torch.where(alpha >= RC.ALPHA_MIN, alpha, torch.zeros_like(alpha))
    torch.testing.assert_close(out.alpha[0], alpha, atol=1e-12, rtol=0)
    torch.testing.assert_close(out.rgb[0, ..., 1], 0.5 * alpha, atol=1e-12, rtol=0)
    torch.testing.assert_close(out.depth[0], z * alpha, atol=1e-12, rtol=0)
    hit = alpha > 0
    torch.testing.assert_close(out.expected_depth[0][hit], torch.full_like(alpha[hit], z))
    assert out.visibility is not None and bool(out.visibility[0, 0])
    r = math.sqrt(2 * math.log(255 * o) * var)
    assert abs(int(out.radii[0, 0]) - math.ceil(r)) <= 1


def test_projection_matches_pinhole_and_autograd_jacobian() -> None:
    scene = random_scene(n=20, c=2, seed=5)
    proj = project_gaussians(scene["means"], scene["quats"], scene["scales"],
                             scene["opacities"], scene["viewmats"], scene["Ks"], 32, 24)
    for c in range(2):
        pc = scene["means"] @ scene["viewmats"][c, :3, :3].T + scene["viewmats"][c, :3, 3]
        K = scene["Ks"][c]
        uv = pc[:, :2] / pc[:, 2:] * K.diagonal()[:2] + K[:2, 2]
        torch.testing.assert_close(proj.means2d[c], uv)
        for i in range(3):
            # Sigma_2d from the Jacobian of the pinhole map computed by autograd
            def pix(p: torch.Tensor, K: torch.Tensor = K) -> torch.Tensor:
                return p[:2] / p[2] * K.diagonal()[:2]
            J = torch.autograd.functional.jacobian(pix, pc[i])
            R = scene["viewmats"][c, :3, :3]
            from egs_bench.render.projection import covariances_3d
            S = covariances_3d(scene["quats"][i:i + 1], scene["scales"][i:i + 1])[0]
            cov2 = J @ R @ S @ R.T @ J.T + RC.EPS2D * torch.eye(2, dtype=torch.float64)
            conic = torch.linalg.inv(cov2)
            torch.testing.assert_close(proj.conics[c, i],
                                       torch.stack([conic[0, 0], conic[0, 1], conic[1, 1]]))


@pytest.mark.parametrize("c", [1, 12])
def test_batch_equals_single_calls(c: int) -> None:
    scene = random_scene(n=120, c=c, seed=6, dtype=torch.float32)
    batched = rasterize(**scene)
    for k in range(c):
        single = dict(scene, viewmats=scene["viewmats"][k:k + 1], Ks=scene["Ks"][k:k + 1])
        one = rasterize(**single)
        for f in (*FIELDS, "visibility", "radii"):
            assert torch.equal(getattr(batched, f)[k], getattr(one, f)[0]), f


@pytest.mark.parametrize("backend", ["numba", "reference"])
def test_empty_scene_gives_background(backend: Backend) -> None:
    scene = random_scene(n=0, c=2, seed=0)
    bg = torch.tensor([[0.1, 0.2, 0.3], [1.0, 0.0, 0.5]], dtype=torch.float64)
    out = rasterize(**scene, backgrounds=bg, backend=backend)
    assert out.visibility is not None
    assert out.rgb.shape == (2, 24, 32, 3) and out.visibility.shape == (2, 0)
    torch.testing.assert_close(out.rgb, bg[:, None, None, :].expand(2, 24, 32, 3))
    assert out.alpha.abs().max() == 0 and out.depth.abs().max() == 0


@pytest.mark.parametrize("backend", ["numba", "reference"])
def test_behind_camera_and_off_image_gaussians_contribute_nothing(backend: Backend) -> None:
    scene = random_scene(n=60, c=1, seed=7)
    base = rasterize(**scene, backend=backend)
    extra = torch.tensor([[0.0, 0.0, -1.0], [0.0, 0.0, 0.005], [50.0, 0.0, 2.0],
                          [0.0, -40.0, 2.0]], dtype=torch.float64)
    s = dict(scene)
    s["means"] = torch.cat([scene["means"], extra])
    s["quats"] = torch.cat([scene["quats"], torch.tensor([[1.0, 0, 0, 0]]).double().repeat(4, 1)])
    s["scales"] = torch.cat([scene["scales"], torch.full((4, 3), 0.1).double()])
    s["opacities"] = torch.cat([scene["opacities"], torch.full((4,), 0.9).double()])
    s["colors"] = torch.cat([scene["colors"], torch.ones(4, 3).double()])
    out = rasterize(**s, backend=backend)
    for f in FIELDS:
        torch.testing.assert_close(getattr(out, f), getattr(base, f), atol=1e-14, rtol=0)
    assert out.visibility is not None
    assert not out.visibility[0, -4:].any() and (out.radii[0, -4:] == 0).all()


@pytest.mark.parametrize("backend", ["numba", "reference"])
def test_degenerate_scales_stay_finite(backend: Backend) -> None:
    scene = random_scene(n=50, c=2, seed=8)
    scene["scales"][:10] = 0.0  # flat/point Gaussians: only the 0.3 px^2 dilation remains
    scene["scales"][10:13] = 1e4  # huge ones
    scene["scales"][13:16, 0] = 1e-9  # needles
    scene["quats"][16] = 0.0  # zero quaternion
    out = rasterize(**scene, backend=backend)
    for f in FIELDS:
        assert torch.isfinite(getattr(out, f)).all(), f
    if backend == "numba":
        ref = rasterize(**scene, backend="reference")
        _assert_same(ref, out, atol=1e-10)


def test_deterministic() -> None:
    scene = random_scene(n=300, c=3, seed=9, dtype=torch.float32)
    a, b = rasterize(**scene), rasterize(**scene)
    for f in (*FIELDS, "visibility", "radii"):
        assert torch.equal(getattr(a, f), getattr(b, f))


def test_visibility_means_touched_above_half_transmittance() -> None:
    # Two identical opaque Gaussians, one behind the other: the front one takes T to 0.1, so
    # the back one contributes only while T < 0.5 and is not "touched".
    means = torch.tensor([[0.0, 0.0, 2.0], [0.0, 0.0, 3.0]], dtype=torch.float64)
    K = torch.tensor([[[40.0, 0, 16], [0, 40, 12], [0, 0, 1]]], dtype=torch.float64)
    args = (means, torch.tensor([[1.0, 0, 0, 0]]).double().repeat(2, 1),
            torch.tensor([[0.5, 0.5, 0.5], [0.1, 0.1, 0.1]]).double(),
            torch.tensor([0.9, 0.9]).double(), torch.ones(2, 3).double(),
            torch.eye(4).double()[None], K, 32, 24)
    for backend in ("numba", "reference"):
        out = rasterize(*args, backend=backend)
        assert out.visibility is not None
        assert out.visibility.tolist() == [[True, False]], backend
        assert (out.depth[0, 12, 16] > 0.9 * 2.0)


def test_bad_inputs_are_programming_errors() -> None:
    """Wrong shapes or dtypes come from calling code, not from a user: ValueError (reported by
    the CLI as an internal error), never ConfigError."""
    scene = random_scene(n=5, c=2)
    with pytest.raises(ValueError, match=r"rasterize: quats has shape \(5, 3\), expected"):
        rasterize(**dict(scene, quats=scene["quats"][:, :3]))
    with pytest.raises(ValueError, match=r"rasterize: Ks has shape \(1, 3, 3\), need \[2,3,3\]"):
        rasterize(**dict(scene, Ks=scene["Ks"][:1]))
    with pytest.raises(ValueError, match="unknown backend 'magic'"):
        rasterize(**scene, backend="magic")  # type: ignore[arg-type]  # the runtime check
    with pytest.raises(ValueError, match="must share one float32/float64 dtype"):
        rasterize(**dict(scene, colors=scene["colors"].float()))
    for bad in (lambda: rasterize(**dict(scene, quats=scene["quats"][:, :3])),
                lambda: rasterize(**scene, backend="magic")):  # type: ignore[arg-type]
        with pytest.raises(Exception) as info:
            bad()
        assert not isinstance(info.value, ConfigError)
