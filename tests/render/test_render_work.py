"""The rasteriser's work counts against an analytic case: Gaussians whose footprints are known
disks of pixels."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from egs_bench.render import constants as RC
from egs_bench.render.rasterize import rasterize
from egs_bench.render.work import RenderWork, counting

W, H, F, Z = 64, 48, 40.0, 2.0
SIGMA = 0.1  # m: 2 px on the image at F / Z = 20 px per m
OPACITY = 0.8
# Centres in pixels, each disk well inside one 16x16 tile, none touching another.
CENTRES = [(8.3, 8.1), (24.0, 7.6), (40.2, 24.4), (56.7, 40.1), (8.5, 39.0)]


def _scene(dtype: torch.dtype = torch.float64) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor,
                                                          torch.Tensor, torch.Tensor, torch.Tensor,
                                                          torch.Tensor]:
    n = len(CENTRES)
    uv = torch.tensor(CENTRES, dtype=dtype)
    cx, cy = W / 2, H / 2
    means = torch.stack([(uv[:, 0] - cx) * Z / F, (uv[:, 1] - cy) * Z / F,
                         torch.full((n,), Z, dtype=dtype)], -1).requires_grad_()
    quats = torch.tensor([[1.0, 0, 0, 0]] * n, dtype=dtype)
    scales = torch.full((n, 3), SIGMA, dtype=dtype)
    opac = torch.full((n,), OPACITY, dtype=dtype)
    colors = torch.ones((n, 3), dtype=dtype)
    K = torch.tensor([[[F, 0, cx], [0, F, cy], [0, 0, 1]]], dtype=dtype)
    return means, quats, scales, opac, colors, torch.eye(4, dtype=dtype)[None], K


def _footprint_pixels() -> int:
    """Pixels whose centre lies where ``opacity x G >= 1/255``: an ellipse
    ``d^T S^-1 d <= 2 ln(255 opacity)`` around each centre, with the projected covariance of
    an isotropic Gaussian at ``(x, y, Z)``, ``S = sigma^2 J J^T + EPS2D I`` and the
    perspective Jacobian ``J = F / Z [[1, 0, -x/Z], [0, 1, -y/Z]]``."""
    bound = 2.0 * math.log(OPACITY / RC.ALPHA_MIN)
    u, v = np.meshgrid(np.arange(W) + 0.5, np.arange(H) + 0.5)
    total = 0
    for cu, cv in CENTRES:
        tx, ty = (cu - W / 2) / F, (cv - H / 2) / F  # x / Z, y / Z
        J = (F / Z) * np.array([[1.0, 0.0, -tx], [0.0, 1.0, -ty]])
        S = SIGMA ** 2 * J @ J.T + RC.EPS2D * np.eye(2)
        d = np.stack([u - cu, v - cv], -1)
        total += int((np.einsum("...i,ij,...j->...", d, np.linalg.inv(S), d) <= bound).sum())
    return total


def test_counts_match_the_analytic_footprints() -> None:
    work = RenderWork()
    with counting(work):
        out = rasterize(*_scene(), W, H, backend="numba")
    expected = _footprint_pixels()
    assert expected > 100  # the case is not trivial: a few dozen pixels per Gaussian
    assert work.calls == 1 and work.cameras == 1 and work.pixels == W * H
    assert work.isects == len(CENTRES)  # each disk lies in one tile
    assert work.blends_fwd == expected
    assert work.blends_bwd == 0  # no backward yet
    out.rgb.sum().backward()
    assert work.blends_bwd == expected  # the backward differentiates the same blends


def test_nothing_is_booked_outside_a_counting_block() -> None:
    work = RenderWork()
    rasterize(*_scene(), W, H, backend="numba")
    assert work == RenderWork()


def test_two_cameras_and_nested_records() -> None:
    means, quats, scales, opac, colors, view, K = _scene()
    outer, inner = RenderWork(), RenderWork()
    with counting(outer):
        rasterize(means, quats, scales, opac, colors, view.expand(2, 4, 4), K.expand(2, 3, 3),
                  W, H, backend="numba")
        with counting(inner):
            rasterize(means, quats, scales, opac, colors, view, K, W, H, backend="numba")
    assert outer.cameras == 2 and outer.pixels == 2 * W * H
    assert outer.blends_fwd == 2 * _footprint_pixels()
    assert inner.cameras == 1 and inner.blends_fwd == _footprint_pixels()


def test_reference_backend_says_it_does_not_count_blends() -> None:
    work = RenderWork()
    with counting(work):
        rasterize(*_scene(), W, H, backend="reference")
    assert work.cameras == 1
    assert work.to_dict()["blends_fwd"] is None and work.blends is None


@pytest.mark.parametrize("scale", [0.5, 0.25])
def test_scaled_dilation_keeps_the_footprint_in_scene_units(scale: float) -> None:
    """At ``scale`` x the resolution with ``eps2d = EPS2D scale^2`` a Gaussian covers
    ``scale^2`` of the pixels it covers at full resolution (to the rounding of a disk)."""
    means, quats, scales, opac, colors, view, K = _scene()
    Ks = K.clone()
    Ks[0, :2] *= scale
    full, coarse = RenderWork(), RenderWork()
    with counting(full):
        rasterize(means, quats, scales, opac, colors, view, K, W, H, backend="numba")
    with counting(coarse):
        rasterize(means, quats, scales, opac, colors, view, Ks, int(W * scale), int(H * scale),
                  backend="numba", eps2d=RC.EPS2D * scale ** 2)
    assert coarse.blends_fwd == pytest.approx(full.blends_fwd * scale ** 2, rel=0.25)
