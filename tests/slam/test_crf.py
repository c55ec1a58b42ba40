"""The camera responses (slam/crf.py): the learnable leaky curve's shape, gradients and starts."""

from __future__ import annotations

import numpy as np
import torch

from egs_bench.color import linear_to_srgb
from egs_bench.slam import crf as crf_mod


def test_crf_monotone_continuous_and_gradcheck() -> None:
    torch.manual_seed(0)
    crf = crf_mod.LeakyPiecewiseLinearCRF(n_nodes=8, alpha=0.01, init="srgb").double()
    with torch.no_grad():
        crf.gap_logits.copy_(torch.randn(7, dtype=torch.float64) * 2)
    x = torch.linspace(-0.5, 3.0, 2001, dtype=torch.float64)
    y = crf(x)
    assert torch.all(torch.diff(y) >= 0)
    assert abs(crf(torch.tensor([0.0], dtype=torch.float64)).item()) < 1e-12
    assert abs(crf(torch.tensor([1.0], dtype=torch.float64)).item() - 1) < 1e-12
    np.testing.assert_allclose(crf(torch.tensor([-2.0], dtype=torch.float64)).item(), -0.02)
    np.testing.assert_allclose(crf(torch.tensor([4.0], dtype=torch.float64)).item(),
                               1 + 0.01 - 0.01 / 2)
    # The node interpolation passes through every node.
    nodes = crf.nodes().detach()
    np.testing.assert_allclose(crf(nodes).detach().numpy(), crf.levels.double().numpy(),
                               atol=1e-12)
    np.testing.assert_allclose(crf.inverse(crf(x)).detach().numpy(), x.numpy(), atol=1e-9)
    # Gradients w.r.t. the input and the learnable nodes (points away from the knots).
    inp = torch.tensor([-0.3, 0.013, 0.21, 0.47, 0.77, 0.95, 1.7], dtype=torch.float64,
                       requires_grad=True)
    assert torch.autograd.gradcheck(crf, (inp,))

    levels = crf.levels.double()

    def by_logits(logits: torch.Tensor) -> torch.Tensor:
        nodes = crf_mod.nodes_from_logits(logits)
        return crf_mod.leaky_piecewise_linear(inp.detach(), nodes, levels, 0.01)

    logits = crf.gap_logits.detach().clone().requires_grad_(True)
    assert torch.autograd.gradcheck(by_logits, (logits,))


def test_crf_srgb_init_matches_srgb_curve() -> None:
    crf = crf_mod.LeakyPiecewiseLinearCRF(n_nodes=64, init="srgb").double()
    x = torch.linspace(0.05, 1, 50, dtype=torch.float64)
    np.testing.assert_allclose(crf(x).detach().numpy(), linear_to_srgb(x).numpy(), atol=5e-3)


def test_crf_default_start_is_the_identity_with_leaky_ends() -> None:
    crf = crf_mod.make_crf("learnable", n_nodes=16, alpha=0.01).double()
    x = torch.linspace(0.0, 1.0, 37, dtype=torch.float64)
    np.testing.assert_allclose(crf(x).detach().numpy(), x.numpy(), atol=1e-6)
    np.testing.assert_allclose(crf.inverse(x).numpy(), x.numpy(), atol=1e-6)
    # outside [0, 1]: slope alpha below 0, 1 + alpha - alpha / sqrt(I) above 1
    ends = crf(torch.tensor([-2.0, 4.0], dtype=torch.float64)).detach().numpy()
    np.testing.assert_allclose(ends, [-0.02, 1.0 + 0.01 - 0.01 / 2.0], atol=1e-12)
