"""Pruning by contribution (``budget.prune_contribution``): each Gaussian's blending weight
against a closed form, the pruning rule on a hidden, a visible and an unseen Gaussian, and a
run that prunes."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from egs_bench.datasets.sequence import Sequence
from egs_bench.geometry import Intrinsics
from egs_bench.render import GaussianMap
from egs_bench.render import constants as RC
from egs_bench.slam import methods
from egs_bench.slam.config import cpu_preset
from egs_bench.slam.context import SlamContext
from egs_bench.slam.contribution import blend_weights, in_view, low_contribution
from egs_bench.slam.levels import level_eps2d
from egs_bench.slam.runner import RunSettings, run_slam

W, H, F = 64, 48, 60.0
CAM = Intrinsics(F, F, 32.0, 24.0, W, H)


def _context(device: str = "cpu") -> SlamContext:
    cfg = cpu_preset()
    no_frames = np.zeros(0, np.int64)
    return SlamContext(cfg, CAM, torch.tensor(CAM.K, dtype=torch.float32, device=device),
                       torch.device(device), (0.2, 0.2), 1e-3, no_frames, no_frames)


def _map(points: list[tuple[float, float, float]], sigmas: list[float],
         opacities: list[float]) -> GaussianMap:
    n = len(points)
    o = torch.tensor(opacities, dtype=torch.float32)
    return GaussianMap(torch.tensor(points, dtype=torch.float32),
                       torch.tensor([[1.0, 0.0, 0.0, 0.0]] * n),
                       torch.log(torch.tensor(sigmas, dtype=torch.float32))[:, None].repeat(1, 3),
                       torch.log(o / (1 - o)), torch.full((n, 3), 0.5))


def _alpha_on_axis(z: float, sigma: float, opacity: float, scale: float) -> np.ndarray:
    """alpha [h, w] of an isotropic Gaussian on the optical axis at depth z, by the rule of
    egs_bench.render.constants, in float64: there the projection's Jacobian is diag(f/z, f/z),
    so its 2-D covariance is ((f sigma / z)^2 + eps2d) I, centred on the principal point."""
    w, h = round(W * scale), round(H * scale)
    f, cx, cy = F * w / W, CAM.cx * w / W, CAM.cy * h / H
    var = (f * sigma / z) ** 2 + level_eps2d(scale)
    u, v = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    alpha = np.minimum(RC.ALPHA_MAX, opacity * np.exp(-0.5 * ((u - cx) ** 2 + (v - cy) ** 2) / var))
    return np.where(alpha >= RC.ALPHA_MIN, alpha, 0.0)


IDENTITY = torch.eye(4)[None]


@pytest.mark.parametrize("scale", [1.0, 0.5])
def test_a_lone_gaussian_blends_its_alpha_summed_over_the_pixels(scale: float) -> None:
    ctx = _context()
    weights = blend_weights(ctx, _map([(0.0, 0.0, 2.0)], [0.05], [0.7]), IDENTITY, scale)
    # at scale 0.5 each coarse pixel counts as 4 internal ones
    expected = _alpha_on_axis(2.0, 0.05, 0.7, scale).sum() / scale**2
    assert weights.item() == pytest.approx(expected, rel=1e-4)
    assert expected > 10  # a footprint of many pixels, so the sum means something


@pytest.mark.cuda
@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA GPU")
def test_gsplat_gives_the_same_weights() -> None:
    pytest.importorskip("gsplat")
    gmap = _map([(0.0, 0.0, 2.0), (0.0, 0.0, 3.0), (0.1, 0.05, 2.5)], [0.1, 0.03, 0.02],
                [0.95, 0.6, 0.8])
    cpu = blend_weights(_context(), gmap, IDENTITY, 1.0)
    cuda = blend_weights(_context("cuda"), gmap.to("cuda"), IDENTITY.cuda(), 1.0).cpu()
    # gsplat clamps alpha at 0.999 (ours 0.99) and culls at 3 sigma (ours where alpha < 1/255):
    # about 1 % of a footprint's weight
    assert cuda.tolist() == pytest.approx(cpu.tolist(), rel=0.03)


def test_a_gaussian_behind_another_blends_what_the_front_one_lets_through() -> None:
    ctx = _context()
    gmap = _map([(0.0, 0.0, 2.0), (0.0, 0.0, 3.0)], [0.1, 0.03], [0.95, 0.6])
    weights = blend_weights(ctx, gmap, IDENTITY, 1.0)
    front = _alpha_on_axis(2.0, 0.1, 0.95, 1.0)
    back = _alpha_on_axis(3.0, 0.03, 0.6, 1.0)
    # the stop rule (T after a Gaussian below T_MIN) cannot fire: alpha <= 0.99 twice
    assert (1 - front).min() * (1 - back).min() >= RC.T_MIN
    assert weights[0].item() == pytest.approx(front.sum(), rel=1e-4)
    assert weights[1].item() == pytest.approx((back * (1 - front)).sum(), rel=1e-4)


def test_weights_add_over_the_views() -> None:
    ctx = _context()
    gmap = _map([(0.0, 0.0, 2.0)], [0.05], [0.7])
    twice = blend_weights(ctx, gmap, IDENTITY.repeat(2, 1, 1), 1.0)
    assert twice.item() == pytest.approx(2 * blend_weights(ctx, gmap, IDENTITY, 1.0).item(),
                                         rel=1e-6)


def test_the_rule_prunes_the_hidden_and_keeps_the_visible_and_the_unseen() -> None:
    ctx = _context()
    hidden = (0.0, 0.0, 3.0)  # straight behind an opaque Gaussian 20x its size on screen
    gmap = _map([(0.0, 0.0, 2.0), hidden, (5.0, 0.0, 2.0), (0.0, 0.0, -2.0)],
                [0.2, 0.01, 0.01, 0.01], [0.999, 0.5, 0.5, 0.5])
    weights = blend_weights(ctx, gmap, IDENTITY, 1.0)
    # the hidden one blends through the front one's 1 % (alpha capped at 0.99): about
    # 0.01 x 0.5 x 2 pi (f sigma / z)^2 + eps2d = 0.01 x 0.5 x 2 pi x 0.34
    assert 0.005 < weights[1].item() < 0.02
    assert weights[2].item() == weights[3].item() == 0.0  # off the image / behind the camera
    assert in_view(ctx, gmap.means, IDENTITY).tolist() == [True, True, False, False]
    remove = low_contribution(ctx, gmap, IDENTITY, 1.0, 0.05)
    assert remove.tolist() == [False, True, False, False]
    # a second view from the side sees the hidden one: summed over both views it stays
    side = torch.eye(4)
    side[0, 3] = 1.0  # camera 1 m to the left: the hidden Gaussian 10 px beside the front one
    both = torch.stack([IDENTITY[0], side])
    assert blend_weights(ctx, gmap, both, 1.0)[1].item() > 0.5
    assert low_contribution(ctx, gmap, both, 1.0, 0.05).tolist() == [False, False, False, False]


def _final_gaussians(seq_path: Path, out: Path, **budget: float) -> tuple[int, dict]:
    base = dict(resolution_scale=1.0, init_iters=6, tracking_iters=6, mapping_iters=4,
                views_per_iter=2, kf_interval=2, pcd_downsample_init=1, pcd_downsample=1,
                kf_overlap=1.0, prune_every=4, prune_offset=3, mapping_coarse_scale=0.5)
    cfg = methods.BUILTIN["egs"].config("cpu").replace(**base, **budget)
    run = run_slam(Sequence.open(seq_path), out, method_name="egs", config=cfg,
                   settings=RunSettings(preset="cpu", seed=0, progress=False))
    stats = json.loads((run.path / "slam_stats.json").read_text())
    return stats["gaussians"], stats


def test_a_run_prunes_by_contribution_once_per_pruning(tiny_room: Path, tmp_path: Path) -> None:
    kept, plain = _final_gaussians(tiny_room, tmp_path / "plain", prune_contribution=0.0)
    pruned, stats = _final_gaussians(tiny_room, tmp_path / "pruned", prune_contribution=0.5)
    assert pruned < kept
    assert stats["keyframes"] == plain["keyframes"]
    # each pruning (one per keyframe round here) renders the window once more, one sharp camera
    # per keyframe, at mapping's coarse level (half the resolution)
    rounds = 0
    for before, after in zip(plain["work"]["per_frame"], stats["work"]["per_frame"], strict=True):
        assert ("mapping" in before) == ("mapping" in after)
        if "mapping" not in after:
            continue
        rounds += 1
        extra = after["mapping"]["cameras"] - before["mapping"]["cameras"]
        assert 1 <= extra <= rounds + 1  # the window holds at most the keyframes so far
        assert after["mapping"]["pixels"] - before["mapping"]["pixels"] == extra * (W // 2) * (
            H // 2)
    assert rounds > 0
