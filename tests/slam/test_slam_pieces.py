"""Lie group, exposure trajectory, CRF, losses and keyframe rules against independent references."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from egs_bench.color import linear_to_srgb
from egs_bench.geometry import interpolate_pose, invert_pose
from egs_bench.render.rasterize import rasterize
from egs_bench.slam import crf as crf_mod
from egs_bench.slam import exposure, keyframes, losses
from egs_bench.slam.config import cpu_preset
from egs_bench.slam.crf import make_crf
from egs_bench.slam.frames import FrameObs
from egs_bench.slam.render_model import (
    blur_loss,
    blur_loss_terms,
    prepare_targets,
    stack_targets,
)


def _random_pose(rng: np.random.Generator, rot_scale: float = 1.0) -> np.ndarray:
    p = np.eye(4)
    p[:3, :3] = Rotation.from_rotvec(rng.normal(size=3) * rot_scale).as_matrix()
    p[:3, 3] = rng.normal(size=3)
    return p


def test_exposure_path_matches_numpy_slerp_lerp() -> None:
    """Sub-poses equal geometry.interpolate_pose (scipy slerp + lerp of camera-to-world poses);
    their Jacobians are tested in test_pose_algebra.py."""
    rng = np.random.default_rng(2)
    a_wc = _random_pose(rng)
    b_wc = a_wc @ _random_pose(rng, 0.2)
    fr = np.array([0.0, 0.25, 0.5, 0.9, 1.0])
    expect_wc = interpolate_pose(a_wc, b_wc, fr)
    got_cw, _ = exposure.exposure_path(invert_pose(a_wc), invert_pose(b_wc), fr)
    np.testing.assert_allclose(invert_pose(got_cw), expect_wc, atol=1e-10)


def test_subpose_fractions_equal_event_counts_and_uniform_fallback() -> None:
    # Events dense in the first half of [0, 1000) us: boundaries must crowd there.
    t = np.concatenate([np.linspace(0, 499, 900), np.linspace(500, 999, 100)]).astype(np.int64)
    fr = exposure.subpose_fractions(t, 0, 1000, 4)
    assert fr[0] == 0 and fr[-1] == 1 and np.all(np.diff(fr) > 0)
    edges = exposure.segment_edges_us(fr, 0, 1000)
    counts = np.histogram(t, bins=edges)[0]
    assert counts.max() - counts.min() <= 0.05 * len(t)
    np.testing.assert_allclose(exposure.subpose_fractions(np.array([], np.int64), 0, 1000, 4),
                               np.linspace(0, 1, 5))
    # One instant burst: still strictly increasing.
    burst = exposure.subpose_fractions(np.full(100, 10, np.int64), 0, 1000, 4)
    assert np.all(np.diff(burst) > 0) and burst[-1] == 1


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


def _raster(rgb: torch.Tensor, depth: torch.Tensor, alpha: torch.Tensor | None = None):
    """A stand-in RasterResult with the given renders [C, H, W, 3] / [C, H, W]."""
    from egs_bench.render.rasterize import RasterResult

    a = torch.ones_like(depth) if alpha is None else alpha
    return RasterResult(rgb, depth, depth / a, a, None, None, None, None)


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

    s = torch.tensor([[1.0, 2.0, 3.0], [2.0, 2.0, 2.0]], dtype=f64)
    assert losses.isotropic_loss(s).item() == pytest.approx((1 + 0 + 1) / 6)


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
        single = sum(blur_loss(_raster(*r), t, crf, exp_ab[i:i + 1], cfg, tracking=tracking,
                               eps=1e-3) for i, (r, t) in pairs)
        batched = blur_loss(_raster(*(torch.cat(x) for x in zip(*renders, strict=True))),
                            stack_targets(targets), crf, exp_ab, cfg, tracking=tracking, eps=1e-3)
        assert batched.item() == pytest.approx(single.item(), rel=1e-12)


def test_edge_mask_marks_edges_only() -> None:
    img = np.full((64, 64, 3), 0.5, np.float32)
    img[:, 32:] = 0.9
    m = losses.edge_mask(img, edge_threshold=1.1, blocks=None)
    assert m[:, 30:34].mean() > 0.4 and m[:, :28].sum() == 0 and m[:, 36:].sum() == 0


def _vis(idx: list[int], n: int = 10) -> np.ndarray:
    v = np.zeros(n, bool)
    v[idx] = True
    return v


def _pose_at(x: float) -> np.ndarray:
    p = np.eye(4)
    p[0, 3] = -x  # world-to-camera of a camera at (x, 0, 0)
    return p


def test_keyframe_selection_rules() -> None:
    from egs_bench.slam.config import KeyframeConfig

    r = KeyframeConfig(interval=4, overlap=0.9, min_translation=0.02, translation=0.04)
    same = _vis(list(range(10)))
    half = _vis(list(range(5)))
    policy = keyframes.MonoGSKeyframes(r, window_size=3)

    def wanted(frame: int, x: float, vis: np.ndarray, window_len: int) -> bool:
        return policy.is_keyframe(keyframes.KeyframeCandidate(
            frame, 0, _pose_at(x), _pose_at(0.0), vis, same, 1.0, window_len))

    assert not wanted(3, 1.0, half, 1)  # too soon
    # window not full: overlap decides
    assert wanted(4, 0.0, half, 1)
    assert not wanted(4, 1.0, same, 1)
    # window full: large translation alone, small translation needs low overlap
    assert wanted(4, 0.05, same, 3)
    assert not wanted(4, 0.03, same, 3)
    assert wanted(4, 0.03, half, 3)
    assert not wanted(4, 0.01, half, 3)


def test_window_removal_overlap_then_dso() -> None:
    from egs_bench.slam.config import KeyframeConfig

    r = KeyframeConfig(cutoff=0.4)
    vis = {0: _vis([0, 1]), 1: _vis([1, 2, 3]), 2: _vis([2, 3, 4]), 3: _vis([3, 4, 5]),
           4: _vis([3, 4, 5])}
    poses = {k: _pose_at(float(k)) for k in range(5)}
    # New KF 4; window [3, 2, 1, 0]; unprotected 2, 1, 0. Overlap with 4: kf2 2/3, kf1 1/3,
    # kf0 0 -> candidates 1 and 0, the oldest (0) goes; window [4,3,2,1] still > 3 -> DSO.
    win, removed = keyframes.update_window([3, 2, 1, 0], 4, vis, poses, r, 3)
    assert removed[0] == 0 and len(win) == 3 and win[:2] == [4, 3]
    # DSO among {2, 1}: score(2) = sqrt(2) * 1/1, score(1) = sqrt(3) * 1/1 -> remove 1.
    assert removed[1] == 1 and win == [4, 3, 2]
    # Nothing removed while the window has room and overlaps are high.
    vis_all = {k: _vis(list(range(10))) for k in range(5)}
    win2, removed2 = keyframes.update_window([3, 2, 1, 0], 4, vis_all, poses, r, 10)
    assert removed2 == [] and win2 == [4, 3, 2, 1, 0]


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
    if kind == "learnable":
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


def _pose_cw(t: tuple[float, float, float], yaw_deg: float = 0.0) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, :3] = Rotation.from_euler("z", yaw_deg, degrees=True).as_matrix()
    pose[:3, 3] = t
    return pose


def test_last_motion_and_constant_velocity_prediction() -> None:
    """No velocity before two end poses exist (unless frame 0's exposure trajectory is
    non-degenerate); with two, the prediction extrapolates the last motion by the time gap."""
    from egs_bench.slam.frames import FrameState
    from egs_bench.slam.tracker import last_motion, predict_initial

    p0 = _pose_cw((0.0, 0.0, 0.0))
    first = [FrameState(0, p0, p0.copy())]
    assert last_motion(first, "constant-velocity", 30_000, None, 10_000) is None
    start = predict_initial(1, first, "constant-velocity", 40_000, 60_000, 30_000, None, 10_000)
    np.testing.assert_allclose(start.pose1_cw, p0)
    p1 = _pose_cw((0.02, 0.0, 0.0), 1.0)
    two = [first[0], FrameState(1, p1, p1.copy())]
    rel, span = last_motion(two, "constant-velocity", 60_000, 30_000, 40_000)
    np.testing.assert_allclose(rel, p1 @ invert_pose(p0), atol=1e-12)
    assert span == 30_000
    assert last_motion(two, "constant-position", 60_000, 30_000, 40_000) is None
    # Twice the gap: twice the translation and the yaw (a pure yaw with t along x composes
    # to these within the small-motion twist approximation of predict_initial).
    pred = predict_initial(2, two, "constant-velocity", 100_000, 120_000, 60_000, 30_000, 80_000)
    step = pred.pose1_cw @ invert_pose(p1)
    yaw = Rotation.from_matrix(step[:3, :3]).as_euler("zyx", degrees=True)[0]
    assert yaw == pytest.approx(2.0, abs=1e-9)
    assert np.linalg.norm(step[:3, 3]) == pytest.approx(0.04, rel=0.02)
    # A non-degenerate frame-0 exposure trajectory is itself a velocity.
    moving = [FrameState(0, p0, _pose_cw((0.01, 0.0, 0.0)))]
    assert last_motion(moving, "constant-velocity", 30_000, None, 10_000) is not None
