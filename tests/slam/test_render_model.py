"""Blurred prediction and its loss (slam/render_model.py) against hand computation."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from egs_bench.render.rasterize import RasterResult, rasterize
from egs_bench.slam import losses
from egs_bench.slam.config import cpu_preset
from egs_bench.slam.crf import LeakyPiecewiseLinearCRF, make_crf
from egs_bench.slam.frames import FrameObs
from egs_bench.slam.render_model import (
    blur_loss,
    blur_loss_terms,
    prepare_targets,
    stack_targets,
)


def _raster(rgb: torch.Tensor, depth: torch.Tensor, alpha: torch.Tensor | None = None
            ) -> RasterResult:
    """A stand-in RasterResult with the given renders [C, H, W, 3] / [C, H, W] (the
    per-Gaussian outputs, which the loss does not read, empty)."""
    a = torch.ones_like(depth) if alpha is None else alpha
    none = torch.empty(0)
    return RasterResult(rgb, depth, depth / a, a, None, none, none, none)


def _obs(rgb: torch.Tensor, depth: torch.Tensor, fractions: list[float],
         events: torch.Tensor | None = None) -> FrameObs:
    return FrameObs(0, rgb, depth, losses.rgb_boundary_mask(rgb), losses.depth_valid_mask(depth),
                    None, np.array(fractions), events, 0)


def test_losses_against_hand_computation() -> None:
    f64 = torch.float64
    cfg = cpu_preset().replace(lambda_id=1.0, lambda_i=1.0, lambda_d=1.0, lambda_e=1.0,
                               lambda_ne=0.5, expected_depth=False, exposure_compensation=False)
    identity = make_crf("identity")
    obs_rgb = torch.zeros(2, 2, 3, dtype=f64)
    obs_rgb[0, 0] = torch.tensor([0.3, 0.6, 0.9])  # |diff| sum 1.8
    obs_rgb[1, 1] = torch.tensor([0.003, 0.003, 0.003])  # near black -> masked by the boundary mask
    assert losses.rgb_boundary_mask(obs_rgb).tolist() == [[True, False], [False, False]]
    d_obs = torch.tensor([[1.0, 2.0], [0.0, 4.0]], dtype=f64)
    # three sub-poses: depth errors +0.5, +0.1, -0.3 on three valid pixels
    d_pred = torch.stack([d_obs + 0.5, d_obs + 0.1, d_obs - 0.3])
    res = _raster(torch.zeros(3, 2, 2, 3, dtype=f64), d_pred)
    obs = _obs(obs_rgb, d_obs, [0.0, 0.5, 1.0])
    mapping_targets = prepare_targets(obs, cfg, (0.25, 0.3), tracking=False, use_events=False)
    t = blur_loss_terms(res, mapping_targets, identity, None, cfg, tracking=False, eps=1e-3)
    assert t["photometric"].item() == pytest.approx(1.8 / 12)
    # per pose mean over 4 pixels: 1.5/4, 0.3/4, 0.9/4 -> min 0.075
    assert t["depth"].item() == pytest.approx(0.075)
    assert t["total"].item() == pytest.approx(1.8 / 12 + 0.075)
    # Tracking masks: rendered opacity < 0.95 drops the second pose's pixel (0, 0) from the
    # depth term (0.2/4 then, so the min is 0.05) and halves the photometric weight there.
    alpha = torch.ones(3, 2, 2, dtype=f64)
    alpha[1, 0, 0] = 0.5
    res_t = _raster(torch.zeros(3, 2, 2, 3, dtype=f64), d_pred, alpha)
    t = blur_loss_terms(res_t, prepare_targets(obs, cfg, (0.25, 0.3), tracking=True,
                                               use_events=False),
                        identity, None, cfg, tracking=True, eps=1e-3)
    assert t["depth"].item() == pytest.approx(0.05)
    assert t["photometric"].item() == pytest.approx(1.8 * (2.5 / 3) / 12)
    # Exposure compensation exp(a) I + b on the prediction: with a = log 2, b = 0.1 a black
    # render predicts 0.1 everywhere.
    t = blur_loss_terms(res, mapping_targets, identity,
                        torch.tensor([[np.log(2.0), 0.1]], dtype=f64), cfg, tracking=False,
                        eps=1e-3)
    assert t["photometric"].item() == pytest.approx((0.2 + 0.5 + 0.8) / 12)

    # Event maps: two renders of a 1x2 image with luma 0.5 -> 0.8 and 0.4 -> 0.4.
    eps = 1e-3
    hdr = torch.tensor([[[[0.5] * 3, [0.4] * 3]], [[[0.8] * 3, [0.4] * 3]]], dtype=f64)
    pm = losses.rendered_event_maps(hdr, eps)
    expect = np.log(0.8 + eps) - np.log(0.5 + eps)
    assert pm[0, 0, 0].item() == pytest.approx(expect)
    assert pm[0, 0, 1].item() == pytest.approx(0.0, abs=1e-12)
    # Observed: 2 positive events at pixel 0, none at pixel 1; the render at pixel 1 changes
    # by 0.1 in log luma (an error of the no-event loss).
    hdr2 = hdr.clone()
    hdr2[1, 0, 1] = (0.4 + eps) * np.exp(0.1) - eps
    one = torch.ones(1, 2, dtype=f64)
    for sign, theta in ((1, 0.25), (-1, 0.3)):
        ev = _obs(torch.full((1, 2, 3), 0.5, dtype=f64), one, [0.0, 1.0],
                  torch.tensor([[[2 * sign, 0]]]))
        res_e = _raster(hdr2, torch.ones(2, 1, 2, dtype=f64))
        t = blur_loss_terms(res_e, prepare_targets(ev, cfg, (0.25, 0.3), tracking=False,
                                                   use_events=True), identity, None, cfg,
                            tracking=False, eps=eps)
        assert t["event_he"].item() == pytest.approx(abs(2 * sign * theta - expect) / 2)
        assert t["event_ne"].item() == pytest.approx(0.1 / 2)
        no_events = blur_loss(res_e, prepare_targets(ev, cfg, (0.25, 0.3), tracking=False,
                                                     use_events=False), identity, None, cfg,
                              tracking=False, eps=eps)
        # total = photometric + depth + lambda_E (L_HE + lambda_NE L_NE)
        assert t["total"].item() == pytest.approx(
            no_events.item() + t["event_he"].item() + 0.5 * t["event_ne"].item())


def test_batched_loss_is_the_sum_of_per_frame_losses() -> None:
    """Mapping evaluates V frames in one call; it must equal the sum of single-frame calls."""
    rng = torch.Generator().manual_seed(0)
    f64 = torch.float64
    cfg = cpu_preset()
    crf = make_crf("learnable", 8, 0.01, "srgb")
    frames, renders = [], []
    for _ in range(3):
        rgb = torch.rand(6, 5, 3, generator=rng, dtype=f64)
        depth = 1 + torch.rand(6, 5, generator=rng, dtype=f64)
        ev = torch.randint(-2, 3, (2, 6, 5), generator=rng)
        frames.append(_obs(rgb, depth, [0.0, 0.4, 1.0], ev))
        renders.append((torch.rand(3, 6, 5, 3, generator=rng, dtype=f64) * 1.5,
                        1 + torch.rand(3, 6, 5, generator=rng, dtype=f64),
                        torch.rand(3, 6, 5, generator=rng, dtype=f64)))
    exp_ab = torch.rand(3, 2, generator=rng, dtype=f64) * 0.1
    for tracking in (False, True):
        targets = [prepare_targets(o, cfg, (0.25, 0.3), tracking=tracking, use_events=True)
                   for o in frames]
        pairs = enumerate(zip(renders, targets, strict=True))
        single = torch.stack([blur_loss(_raster(*r), t, crf, exp_ab[i:i + 1], cfg,
                                        tracking=tracking, eps=1e-3)
                              for i, (r, t) in pairs]).sum()
        batched = blur_loss(_raster(*(torch.cat(x) for x in zip(*renders, strict=True))),
                            stack_targets(targets), crf, exp_ab, cfg, tracking=tracking, eps=1e-3)
        assert batched.item() == pytest.approx(single.item(), rel=1e-12)


def test_normalised_depth_keeps_alpha_in_the_graph() -> None:
    """L_D on the rasteriser's sum(w z) / sum(w): a lone surface renders the same normalised
    depth whatever its opacity, so the depth term must not move the opacity (with alpha
    detached it lowered every opacity where the depth was too long and eroded maps into
    holes)."""
    h, w = 4, 5
    ones = torch.ones(h, w, dtype=torch.bool)
    obs = FrameObs(0, torch.full((h, w, 3), 0.5, dtype=torch.float64),
                   torch.full((h, w), 2.0, dtype=torch.float64), ones, ones, None,
                   np.array([1.0]), None, 0)
    cfg = cpu_preset().replace(blur_model=False, event_tracking=False, event_mapping=False,
                               exposure_compensation=False, expected_depth=True, lambda_i=0.0)
    crf = make_crf("identity", 16, 0.01, "linear")
    f64 = torch.float64
    K = torch.tensor([[[4.0, 0.0, 2.5], [0.0, 4.0, 2.0], [0.0, 0.0, 1.0]]], dtype=f64)
    for tracking in (True, False):
        opacity = torch.tensor([0.97], dtype=f64, requires_grad=True)
        res = rasterize(torch.tensor([[0.0, 0.0, 2.5]], dtype=f64),  # a wall 0.5 m too far
                        torch.tensor([[1.0, 0.0, 0.0, 0.0]], dtype=f64),
                        torch.tensor([[50.0, 50.0, 1e-3]], dtype=f64), opacity,
                        torch.full((1, 3), 0.5, dtype=f64), torch.eye(4, dtype=f64)[None], K,
                        w, h, backend="reference")
        targets = prepare_targets(obs, cfg, (0.25, 0.25), tracking=tracking, use_events=False)
        parts = blur_loss_terms(res, targets, crf, None, cfg, tracking=tracking, eps=1e-3)
        assert parts["depth"].item() == pytest.approx(0.5)
        (grad,) = torch.autograd.grad(parts["total"], opacity, retain_graph=True)
        assert abs(float(grad)) < 1e-9
        detached = res.depth / res.alpha.detach()
        (grad_detached,) = torch.autograd.grad((detached - 2.0).abs().mean(), opacity)
        assert float(grad_detached) > 0.1  # the old form: descent lowers the opacity
    plain = blur_loss_terms(res, prepare_targets(obs, cfg, (0.25, 0.25), tracking=False,
                                                 use_events=False), crf, None,
                            cfg.replace(expected_depth=False), tracking=False, eps=1e-3)
    assert plain["depth"].item() == pytest.approx(0.97 * 2.5 - 2.0, abs=0.01)


@pytest.mark.parametrize("kind", ["learnable", "identity"])
def test_fixed_response_backward_matches_finite_differences(kind: str) -> None:
    """Tracking's response + exposure node has a hand-written backward: gradcheck it (float64
    central differences) on HDR values away from the curve's kinks, below 0, inside and above
    1, and compare its value with the autograd form used in mapping."""
    from egs_bench.slam.render_model import respond

    crf = make_crf(kind, 8, 0.01, "srgb")
    frozen = crf.frozen()
    rng = torch.Generator().manual_seed(0)
    hdr = torch.cat([torch.rand(20, generator=rng) * 3 - 0.5]).double()
    if isinstance(crf, LeakyPiecewiseLinearCRF):
        nodes = crf.nodes().detach().double()
        near_kink = (hdr[:, None] - torch.cat([nodes, torch.tensor([0.0, 1.0]).double()])
                     ).abs().min(1).values < 1e-3
        hdr = hdr[~near_kink]
    hdr = hdr.reshape(1, 1, -1, 1).expand(2, 1, -1, 3).contiguous().requires_grad_()
    exp_ab = torch.tensor([[0.1, -0.02], [-0.05, 0.03]], dtype=torch.float64,
                          requires_grad=True)
    assert torch.autograd.gradcheck(lambda h, ab: respond(frozen, h, ab), (hdr, exp_ab))
    generic = torch.addcmul(exp_ab[:, 1].view(-1, 1, 1, 1), crf.double()(hdr),
                            exp_ab[:, 0].exp().view(-1, 1, 1, 1))
    torch.testing.assert_close(respond(frozen, hdr, exp_ab), generic)


def _srgb_by_hand(x: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1 encoding of linear values clipped to [0, 1] (float64)."""
    c = np.clip(x, 0.0, 1.0)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)


def _leaky_curve_by_hand(x: np.ndarray, nodes: np.ndarray, levels: np.ndarray,
                         alpha: float) -> np.ndarray:
    """The paper's leaky piecewise-linear CRF (float64): linear interpolation through the
    nodes on [0, 1], slope ``alpha`` below 0, ``1 + alpha - alpha / sqrt(x)`` above 1."""
    inside = np.interp(np.clip(x, 0.0, 1.0), nodes, levels)
    high = 1 + alpha - alpha / np.sqrt(np.maximum(x, 1.0))
    return np.where(x < 0, alpha * x, np.where(x > 1, high, inside))


@pytest.mark.parametrize("kind", ["learnable", "srgb"])
@pytest.mark.parametrize("tracking", [False, True], ids=["mapping", "tracking"])
@pytest.mark.parametrize("with_exposure", [False, True], ids=["plain", "exposure"])
def test_blurred_prediction_is_the_response_of_the_mean_linear_render(
        kind: str, tracking: bool, with_exposure: bool) -> None:
    """The predicted observation of a frame is ``exp(a) CRF(mean_k hdr_k) + b``: the K+1
    sub-pose renders are averaged in linear light and then go through the (non-affine)
    response, never the reverse. The observation is set to that prediction, computed here in
    float64 from the sub-renders, so the photometric loss must vanish; averaging the
    responses of the sub-renders instead leaves a mean error far above the tolerance."""
    f64 = torch.float64
    views, subposes, h, w = 2, 4, 5, 6
    rng = np.random.default_rng(3)
    # Sub-renders spread over [0.02, 1.4]: a blurred edge mixes dark and bright instants, and
    # values above 1 reach the curve's saturating end.
    hdr = rng.uniform(0.02, 1.4, size=(views, subposes, h, w, 3))
    crf = make_crf(kind, 8, 0.01, "srgb").double()
    if isinstance(crf, LeakyPiecewiseLinearCRF):
        with torch.no_grad():  # nodes away from the sRGB start: a generic monotone curve
            crf.gap_logits.add_(torch.from_numpy(rng.normal(scale=0.5, size=7)))
        nodes = crf.nodes().detach().numpy()
        levels = crf.levels.numpy()  # 8 even steps, as the curve stores them (float32-rounded)

        def response(x: np.ndarray) -> np.ndarray:
            return _leaky_curve_by_hand(x, nodes, levels, 0.01)
    else:
        response = _srgb_by_hand
    exp_ab = np.array([[0.2, 0.03], [-0.1, 0.05]]) if with_exposure else np.array([[0.0, 0.0]] * 2)
    gain, offset = np.exp(exp_ab[:, 0])[:, None, None, None], exp_ab[:, 1][:, None, None, None]
    expected = gain * response(hdr.mean(1)) + offset  # [V, H, W, 3]
    response_averaged = gain * response(hdr).mean(1) + offset
    assert np.abs(response_averaged - expected).mean() > 1e-2  # the data tells the two apart

    cfg = cpu_preset().replace(lambda_id=1.0, lambda_i=1.0, lambda_d=1.0,
                               exposure_compensation=with_exposure)
    depth = torch.ones(subposes, h, w, dtype=f64)
    res = _raster(torch.from_numpy(hdr.reshape(views * subposes, h, w, 3)),
                  depth.repeat(views, 1, 1))
    fractions = list(np.linspace(0.0, 1.0, subposes))

    def photometric(observed: np.ndarray) -> float:
        frames = [_obs(torch.from_numpy(observed[v]), depth[0], fractions) for v in range(views)]
        assert all(bool(f.rgb_mask.all()) for f in frames)  # no pixel is masked out
        targets = stack_targets([prepare_targets(f, cfg, (0.25, 0.25), tracking=tracking,
                                                 use_events=False) for f in frames])
        terms = blur_loss_terms(res, targets, crf.frozen() if tracking else crf,
                                torch.from_numpy(exp_ab) if with_exposure else None, cfg,
                                tracking=tracking, eps=1e-3)
        return terms["photometric"].item()

    assert photometric(expected) == pytest.approx(0.0, abs=1e-12)
    # The loss is live: an observation 0.05 brighter everywhere costs 0.05 in each frame.
    assert photometric(expected + 0.05) == pytest.approx(views * 0.05, rel=1e-9)
