"""EDI (egs_bench.baselines.edi): analytic cases, a synthetic blurred frame, the threshold
search, and the sequence view used by ``monogs-edi``."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import ArrayLike

from egs_bench.baselines.edi import (
    EdiConfig,
    ExposureEvents,
    deblur_frame,
    deblur_sequence_frame,
    edge_consistency,
    exposure_integral,
    latent_from_blur,
)
from egs_bench.errors import ConfigError, InputError
from tests.helpers.plane_scene import make_plane_sequence

T0, T1 = 1_000_000, 1_020_000  # a 20 ms exposure, microseconds


def _one_pixel(x: ArrayLike, y: ArrayLike, t: ArrayLike, p: ArrayLike, *, t_ref: int,
               c_pos: float = 0.25, c_neg: float = 0.25) -> float:
    """The exposure integral of the one-pixel sensor's events (x, y, t [us], p)."""
    return float(exposure_integral(np.asarray(x), np.asarray(y), np.asarray(t), np.asarray(p),
                                   height=1, width=1, t_start_us=T0, t_end_us=T1,
                                   t_ref_us=t_ref, c_pos=c_pos, c_neg=c_neg)[0, 0])


@pytest.mark.parametrize("eps", [0.0, 1e-3])
def test_one_step_pixel_is_recovered_exactly(eps: float) -> None:
    """A pixel that is L0 until one positive event at t1 and L0 e^c (in Y + eps) after: EDI
    returns L0 for any reference time before t1 and the post-step level from t1 on."""
    c, l0, t1 = 0.25, 0.3, T0 + 7_000
    l1 = (l0 + eps) * np.exp(c) - eps
    blurred = (l0 * (t1 - T0) + l1 * (T1 - t1)) / (T1 - T0)
    for t_ref, want in ((T0, l0), (T0 + 3_000, l0), (t1, l1), (T1, l1)):
        phi = _one_pixel([0], [0], [t1], [1], t_ref=t_ref)
        got = latent_from_blur(np.array([[blurred]]), np.array([[phi]]), eps)[0, 0]
        assert got == pytest.approx(want, rel=1e-12, abs=1e-15)
    # a wrong threshold gives a wrong image: the test can fail
    phi = _one_pixel([0], [0], [t1], [1], t_ref=T1, c_pos=0.4)
    wrong = latent_from_blur(np.array([[blurred]]), np.array([[phi]]), eps)[0, 0]
    assert abs(wrong - l1) > 0.03 * l1


def test_several_events_both_polarities_and_separate_thresholds() -> None:
    """Piecewise-constant pixel with +, +, - events and c+ != c-: exact at the exposure end."""
    cp, cn = 0.3, 0.2
    times = np.array([T0 + 2_000, T0 + 9_000, T0 + 15_000])
    pol = np.array([1, 1, -1])
    logs = np.log(0.2) + np.concatenate([[0.0], np.cumsum(np.where(pol > 0, cp, -cn))])
    edges = np.concatenate([[T0], times, [T1]])
    blurred = float(np.sum(np.exp(logs) * np.diff(edges)) / (T1 - T0))
    phi = _one_pixel(np.zeros(3, int), np.zeros(3, int), times, pol, t_ref=T1, c_pos=cp,
                     c_neg=cn)
    assert blurred / phi == pytest.approx(np.exp(logs[-1]), rel=1e-12)


def test_pixels_without_events_are_unchanged_and_pixels_do_not_mix() -> None:
    """Phi is exactly 1 where nothing happened; interleaving events of other pixels in time
    changes nothing at a pixel (the per-pixel sort keeps each pixel's time order)."""
    rng = np.random.default_rng(0)
    h, w = 5, 7
    n = 400
    t = np.sort(rng.integers(T0 + 1, T1 + 1, n))
    x, y = rng.integers(0, w, n), rng.integers(0, h, n)
    x[y == 0] = np.where(x[y == 0] == 3, 2, x[y == 0])  # pixel (3, 0) stays silent
    p = rng.choice([-1, 1], n)
    phi = ExposureEvents(x, y, t, p, height=h, width=w, t_start_us=T0, t_end_us=T1).phi(0.2, 0.3)
    assert phi[0, 3] == 1.0
    for yy, xx in ((1, 1), (4, 6)):
        sel = (x == xx) & (y == yy)
        alone = exposure_integral(x[sel] * 0, y[sel] * 0, t[sel], p[sel], height=1, width=1,
                                  t_start_us=T0, t_end_us=T1, t_ref_us=T1, c_pos=0.2, c_neg=0.3)
        assert phi[yy, xx] == pytest.approx(alone[0, 0], rel=1e-12)


def test_events_outside_the_exposure_are_ignored() -> None:
    phi = _one_pixel([0, 0, 0], [0, 0, 0], [T0 - 5, T0, T1 + 1], [1, 1, 1], t_ref=T1)
    assert phi == 1.0


@pytest.mark.parametrize("t_ref_ms", [0.0, 10.0, 20.0])
def test_exponential_ramp_is_within_the_quantisation_bound(t_ref_ms: float) -> None:
    """L(t) = L0 e^(a t): ESIM fires at t_k = k c / a, B = L0 (e^(aT) - 1) / (aT). EDI sees a
    staircase, so it is not exact, but L_EDI / L_true lies in [e^-c, e^c] (measured 1.125,
    0.969, 1.071 at 0, 10, 20 ms; bound 1.284)."""
    c, a, l0 = 0.25, 40.0, 0.3
    span_s = (T1 - T0) * 1e-6
    k = np.arange(1, int(a * span_s / c) + 1)
    t = T0 + np.round(k * c / a * 1e6).astype(np.int64)
    t = t[t <= T1]
    blurred = l0 * (np.exp(a * span_s) - 1) / (a * span_s)
    t_ref = T0 + int(t_ref_ms * 1000)
    phi = _one_pixel(np.zeros(len(t), int), np.zeros(len(t), int), t, np.ones(len(t), int),
                     t_ref=t_ref, c_pos=c)
    ratio = (blurred / phi) / (l0 * np.exp(a * (t_ref - T0) * 1e-6))
    assert np.exp(-c) <= ratio <= np.exp(c)
    assert abs(np.log(ratio)) < 0.13  # the measured ratios: the bound is not met loosely


def test_edge_consistency_prefers_the_gradients_that_made_the_events() -> None:
    """An edge map equal to a block-wise combination of the image gradients is explained
    fully (1 - R^2 = 0); a random map is not."""
    import cv2

    rng = np.random.default_rng(1)
    img = cv2.GaussianBlur(rng.random((48, 64)), (0, 0), 2.0)
    gx = cv2.Sobel(img, cv2.CV_64F, 1, 0, ksize=3)
    gy = cv2.Sobel(img, cv2.CV_64F, 0, 1, ksize=3)
    assert edge_consistency(img, 0.7 * gx - 0.2 * gy, 16) == pytest.approx(0.0, abs=1e-9)
    assert edge_consistency(img, np.asarray(rng.normal(size=img.shape)), 16) > 0.8
    assert edge_consistency(img, np.zeros_like(img), 16) == 1.0


def test_config_is_validated() -> None:
    for bad in (dict(c=-0.1), dict(c_min=0.5, c_max=0.2), dict(grid=1), dict(tv_weight=-1),
                dict(edge_fraction=0.0), dict(block=1)):
        with pytest.raises(ConfigError):
            EdiConfig(**bad)


def test_no_events_returns_the_frame_unchanged() -> None:
    blurred = np.full((4, 5, 3), 0.4)
    res = deblur_frame(blurred, np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0),
                       t_start_us=T0, t_end_us=T1, eps=1e-3)
    assert res.c is None and res.n_events == 0
    np.testing.assert_array_equal(res.latent, blurred)


# --------------------------------------------------------------------------------------------
# a synthetic blurred frame (textured plane translating fast, generated by the pipeline)


@pytest.fixture(scope="module")
def blurred_plane(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """2 frames, 96x64, of the plane scene at 4 m/s: a 15 ms exposure smears it by ~40 px;
    events with c = 0.25 (generation ~1 s)."""
    return make_plane_sequence(tmp_path_factory.mktemp("edi") / "plane", frames=2, width=96,
                               height=64, speed_mps=4.0)


def test_edi_frame_is_much_sharper_than_the_blurred_frame(blurred_plane: Path) -> None:
    """PSNR against the sharp ground truth at the exposure end (measured: blurred 15.1 /
    15.4 dB, EDI with the searched c 23.5 / 23.7 dB, with the true c 23.7 / 24.1 dB). The
    search picks c = 0.21-0.22 (true 0.25)."""
    from egs_bench.datasets.sequence import Sequence
    from egs_bench.eval.image_metrics import psnr

    seq = Sequence.open(blurred_plane)
    for i in range(len(seq)):
        sharp = seq.sharp(i)
        assert sharp is not None
        blurred_db = psnr(seq.rgb(i), sharp)
        image, res = deblur_sequence_frame(seq, i)
        known, _ = deblur_sequence_frame(seq, i, EdiConfig(c=0.25))
        edi_db, known_db = psnr(image, sharp), psnr(known, sharp)
        assert image.dtype == np.uint8 and image.shape == sharp.shape
        assert edi_db > blurred_db + 7.0
        assert known_db > blurred_db + 7.5
        assert edi_db > known_db - 1.0  # the search loses little against the true threshold
        assert res.c is not None and 0.18 <= res.c <= 0.3
        assert res.n_events > 10_000


def test_edi_needs_linear_intensity(blurred_plane: Path) -> None:
    """Applied to the sRGB-encoded values instead of decoded linear intensity (the events are
    log changes of linear luma), the same EDI is measurably worse (measured 19.2 vs 24.1 dB)."""
    from egs_bench.datasets.sequence import Sequence
    from egs_bench.eval.image_metrics import psnr

    seq = Sequence.open(blurred_plane)
    t0, t1 = seq.exposure(1)
    ev = seq.events.window(t0 + 1, t1 + 1)
    encoded = seq.rgb(1) / 255.0
    res = deblur_frame(encoded, ev.x, ev.y, ev.t, ev.p, t_start_us=t0, t_end_us=t1, eps=seq.eps,
                       config=EdiConfig(c=0.25))
    wrong = np.round(np.clip(res.latent, 0, 1) * 255).astype(np.uint8)
    right, _ = deblur_sequence_frame(seq, 1, EdiConfig(c=0.25))
    sharp1 = seq.sharp(1)
    assert sharp1 is not None
    assert psnr(right, sharp1) > psnr(wrong, sharp1) + 2.0


def test_edi_sequence_view(blurred_plane: Path, tmp_path: Path) -> None:
    """The view returns EDI frames from rgb() and everything else from the sequence; it
    refuses a sequence without events."""
    import yaml

    from egs_bench.baselines.monogs_edi import EdiSequence
    from egs_bench.datasets.sequence import Sequence

    seq = Sequence.open(blurred_plane)
    view = EdiSequence(seq, EdiConfig(c=0.25), cache_frames=1)
    assert len(view) == len(seq) and view.path == seq.path and view.name == seq.name
    np.testing.assert_array_equal(view.depth(1), seq.depth(1))
    np.testing.assert_array_equal(view.poses, seq.poses)
    expected, _ = deblur_sequence_frame(seq, 1, EdiConfig(c=0.25))
    np.testing.assert_array_equal(view.rgb(1), expected)
    assert not np.array_equal(view.rgb(1), seq.rgb(1))
    view.rgb(0)
    np.testing.assert_array_equal(view.rgb(1), expected)  # recomputed after eviction
    assert view.frames_csv().splitlines()[0] == "index,c,energy,events,seconds"

    no_events = tmp_path / "no_events"
    shutil.copytree(blurred_plane, no_events)
    meta = yaml.safe_load((no_events / "meta.yaml").read_text())
    meta["has_events"] = False
    (no_events / "meta.yaml").write_text(yaml.safe_dump(meta))
    with pytest.raises(InputError, match="needs events"):
        EdiSequence(Sequence.open(no_events))


@pytest.fixture(scope="module")
def tiny_room(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """6 frames, 64x48, of the synthetic office (a 3-D camera path, which ATE alignment needs;
    generation ~10 s)."""
    from egs_bench.datasets.synthetic import make_synthetic

    return make_synthetic("office", tmp_path_factory.mktemp("room") / "office", frames=6,
                          width=64, height=48, speed=0.4, seed=1, progress=False)


@pytest.mark.slow
def test_monogs_edi_is_a_registered_method_writing_a_normal_run(tiny_room: Path,
                                                                 tmp_path: Path) -> None:
    """Listed, runs the monogs configuration on EDI frames, records the EDI settings and the
    per-frame thresholds, and is evaluated like any run (against the original sequence)."""
    from egs_bench.datasets.sequence import Sequence
    from egs_bench.eval.evaluate import evaluate_run
    from egs_bench.runs.folder import RunFolder
    from egs_bench.runs.registry import available_methods, get_method
    from egs_bench.slam.methods import BUILTIN, ConfiguredSlamMethod

    assert "monogs-edi" in available_methods()
    method = get_method("monogs-edi")
    assert isinstance(method, ConfiguredSlamMethod)
    assert method.overrides == BUILTIN["monogs"].overrides
    fast = dict(resolution_scale=1.0, init_iters=10, tracking_iters=10, mapping_iters=2,
                kf_interval=2, pcd_downsample_init=2, pcd_downsample=4)
    run = method.with_options(fast).run(Sequence.open(tiny_room), tmp_path / "run",
                                        preset="cpu", progress=False)
    run = RunFolder.open(run.path)
    assert run.method == "monogs-edi" and run.read_status().state == "done"
    assert run.sequence_path == tiny_room.resolve()
    cfg = run.read_config()
    assert cfg["edi"]["c"] is None and cfg["edi"]["grid"] == EdiConfig().grid
    assert cfg["slam"]["method"]["blur_model"] is False
    assert cfg["slam"]["method"]["event_tracking"] is False
    rows = (run.path / "edi_frames.csv").read_text().splitlines()
    assert len(rows) == 1 + 6 and all(float(r.split(",")[1]) > 0 for r in rows[1:])
    metrics = evaluate_run(run.path)
    assert metrics["ate"]["n_matched"] == 6 and metrics["rendering"]["n_frames"] == 2
