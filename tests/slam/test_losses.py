"""Masks and regularisers of slam/losses.py."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from egs_bench.slam import losses


def test_edge_mask_marks_edges_only() -> None:
    img = np.full((64, 64, 3), 0.5, np.float32)
    img[:, 32:] = 0.9
    m = losses.edge_mask(img, edge_threshold=1.1, blocks=None)
    assert m[:, 30:34].mean() > 0.4 and m[:, :28].sum() == 0 and m[:, 36:].sum() == 0


def test_isotropic_loss_is_the_mean_deviation_from_each_gaussians_mean_scale() -> None:
    s = torch.tensor([[1.0, 2.0, 3.0], [2.0, 2.0, 2.0]], dtype=torch.float64)
    assert losses.isotropic_loss(s).item() == pytest.approx((1 + 0 + 1) / 6)
