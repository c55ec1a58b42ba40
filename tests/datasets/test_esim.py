"""ESIM simulator against analytic cases and an independent per-crossing reference loop."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from scipy import ndimage, stats

from egs_bench.datasets.esim import (
    EventSimConfig,
    EventSimulator,
    linear_luma,
    log_luma,
    simulate,
)
from egs_bench.datasets.events import Events
from egs_bench.errors import ConfigError


def _run(config: EventSimConfig, frames: list[np.ndarray], times: list[int]) -> Events:
    h, w = frames[0].shape
    return simulate(frames, times, config, h, w)


def _smooth_video(n: int, h: int, w: int, seed: int, amplitude: float = 1.5) -> np.ndarray:
    """[n, h, w] smooth random log-brightness video (blurred noise drifting in time)."""
    rng = np.random.default_rng(seed)
    noise = rng.normal(size=(n, h, w))
    video = ndimage.gaussian_filter(noise, sigma=(2.0, 3.0, 3.0))
    video *= amplitude / video.std()
    return video - 1.0


def _reference_esim(
    frames: np.ndarray, times: np.ndarray, pos: np.ndarray, neg: np.ndarray, refractory: int
) -> list[tuple[int, int, int, int, int]]:
    """Direct transcription of ESIM's per-crossing loop (pure Python, one pixel at a time).

    Returns events as (t, y * w + x, x, y, p) sorted by (t, pixel), crossing order kept.
    """
    _, h, w = frames.shape
    ref = frames[0].astype(np.float64).copy()
    last_event: dict[int, int] = {}
    out: list[tuple[int, int, int, int, int]] = []
    for k in range(1, len(frames)):
        l0, l1 = frames[k - 1], frames[k]
        t0, t1 = int(times[k - 1]), int(times[k])
        interval = []
        for y in range(h):
            for x in range(w):
                a, b = float(l0[y, x]), float(l1[y, x])
                if b == a:
                    continue
                pol = 1 if b > a else -1
                c = pos[y, x] if pol > 0 else neg[y, x]
                while True:
                    cross = ref[y, x] + pol * c
                    reached = cross <= b + 1e-9 if pol > 0 else cross >= b - 1e-9
                    if not reached:
                        break
                    t_float = (cross - a) / (b - a) * (t1 - t0)
                    t_ev = t0 + min(max(int(np.floor(t_float + 0.5)), 1), t1 - t0)
                    pix = y * w + x
                    if pix not in last_event or t_ev - last_event[pix] >= refractory:
                        last_event[pix] = t_ev
                        interval.append((t_ev, pix, x, y, pol))
                    ref[y, x] = cross
        interval.sort(key=lambda e: (e[0], e[1]))  # Python's sort is stable
        out.extend(interval)
    return out


def _as_tuples(events: Events, width: int) -> list[tuple[int, int, int, int, int]]:
    pix = events.y.astype(np.int64) * width + events.x
    return list(zip(events.t.tolist(), pix.tolist(), events.x.tolist(), events.y.tolist(),
                    events.p.tolist(), strict=True))


# --- luma ------------------------------------------------------------------------------------


def test_linear_luma_uses_bt601_weights_and_log_adds_eps() -> None:
    rgb = np.zeros((2, 3, 3))
    rgb[0, 0] = [1, 0, 0]
    rgb[0, 1] = [0, 1, 0]
    rgb[0, 2] = [0, 0, 1]
    rgb[1, :] = [0.2, 0.5, 0.8]
    luma = linear_luma(rgb)
    assert luma.shape == (2, 3) and luma.dtype == np.float64
    np.testing.assert_allclose(luma[0], [0.299, 0.587, 0.114], rtol=0, atol=1e-15)
    np.testing.assert_allclose(luma[1], 0.299 * 0.2 + 0.587 * 0.5 + 0.114 * 0.8, atol=1e-15)
    np.testing.assert_allclose(log_luma(rgb, 1e-3), np.log(luma + 1e-3), rtol=0, atol=0)
    with pytest.raises(ValueError):
        linear_luma(np.zeros((4, 4)))


# --- analytic single-pixel cases --------------------------------------------------------------


@pytest.mark.parametrize("n", [1, 3, 7])
@pytest.mark.parametrize("direction", [1, -1])
def test_ramp_of_n_thresholds_gives_n_events_at_predicted_times(n: int, direction: int) -> None:
    theta = 0.23
    l0 = np.log(0.37)  # not a round number: the n-th crossing lies exactly on the sample
    l1 = l0 + direction * n * theta
    t0, t1 = 1_000, 1_000 + 7_001
    ev = _run(EventSimConfig(pos_threshold=theta, neg_threshold=theta),
              [np.full((1, 1), l0), np.full((1, 1), l1)], [t0, t1])
    assert len(ev) == n
    assert np.all(ev.p == direction)
    predicted = t0 + np.arange(1, n + 1) / n * (t1 - t0)
    assert np.all(np.abs(ev.t - predicted) <= 0.5)
    assert ev.t[-1] == t1


def test_ramp_across_samples_carries_remainder() -> None:
    theta = 0.2
    rate = 0.37e-3  # log units per microsecond
    times = np.arange(0, 10_001, 1_000) + 50  # 11 samples, 3.7 log units in total
    log_values = -2.0 + rate * (times - times[0])
    frames = [np.full((1, 1), v) for v in log_values]
    ev = _run(EventSimConfig(pos_threshold=theta), frames, times.tolist())
    n_expected = int(np.floor(rate * (times[-1] - times[0]) / theta + 1e-9))
    assert n_expected == 18
    assert len(ev) == n_expected
    predicted = times[0] + np.arange(1, n_expected + 1) * theta / rate
    assert np.all(np.abs(ev.t - predicted) <= 0.5)
    # Every interval holds fewer than one threshold here, so events exist only thanks to the
    # remainder carried in the reference.
    assert np.all(np.diff(log_values) < theta * 2)


def test_constant_images_give_no_events() -> None:
    rng = np.random.default_rng(1)
    image = rng.normal(size=(8, 9))
    config = EventSimConfig(pos_threshold=0.05, neg_threshold=0.05, sigma=0.02)
    ev = _run(config, [image] * 6, [0, 10, 20, 30, 40, 50])
    assert len(ev) == 0


def test_polarity_follows_sign_and_counts_are_floor_of_change() -> None:
    rng = np.random.default_rng(2)
    l0 = rng.normal(size=(10, 12))
    delta = rng.uniform(-1.3, 1.3, size=(10, 12))
    theta = 0.25
    ev = _run(EventSimConfig(), [l0, l0 + delta], [0, 1000])
    counts = np.zeros((10, 12), np.int64)
    np.add.at(counts, (ev.y, ev.x), 1)
    np.testing.assert_array_equal(counts, np.floor(np.abs(delta) / theta).astype(np.int64))
    assert np.all(ev.p == np.sign(delta[ev.y, ev.x]))


def test_separate_positive_and_negative_thresholds() -> None:
    pos, neg = 0.2, 0.5
    base = np.log(0.3)
    frames = [np.full((1, 1), base + v) for v in (0.0, 1.0, 0.0)]
    ev = _run(EventSimConfig(pos_threshold=pos, neg_threshold=neg), frames, [0, 1000, 2000])
    up, down = ev.p[ev.t <= 1000], ev.p[ev.t > 1000]
    assert len(up) == 5 and np.all(up == 1)
    # The reference sits at base + 1.0 after the rise; falling by 1.0 crosses neg twice.
    assert len(down) == 2 and np.all(down == -1)
    np.testing.assert_array_equal(ev.t[ev.t > 1000], [1500, 2000])


def test_polarity_sum_tracks_log_change_within_one_threshold() -> None:
    n, h, w = 40, 24, 32
    video = _smooth_video(n, h, w, seed=3)
    for config in (EventSimConfig(pos_threshold=0.1, neg_threshold=0.1),
                   EventSimConfig(pos_threshold=0.08, neg_threshold=0.15, sigma=0.02, seed=4)):
        sim = EventSimulator(config, h, w)
        pos_map, neg_map = sim.thresholds
        sim.reset(video[0], 0)
        integral = np.zeros((h, w))
        n_events = 0
        for k in range(1, n):
            ev = sim.step(video[k], 500 * k)
            n_events += len(ev)
            weights = np.where(ev.p > 0, pos_map[ev.y, ev.x], -neg_map[ev.y, ev.x])
            np.add.at(integral, (ev.y, ev.x), weights)
            residual = (video[k] - video[0]) - integral
            # The reference lies in (L - C+, L + C-]: the residual stays within one threshold.
            assert np.all(residual < pos_map + 1e-9)
            assert np.all(residual > -neg_map - 1e-9)
        assert n_events > 10 * h * w  # the video is far from trivial


def test_matches_independent_reference_loop_with_mismatch_and_refractory() -> None:
    n, h, w = 12, 6, 7
    video = _smooth_video(n, h, w, seed=5, amplitude=2.0)
    rng = np.random.default_rng(6)
    gaps = rng.integers(50, 400, size=n)
    gaps[7] = 3_000_000  # a long interval takes the comparison-sort path
    times = np.cumsum(gaps)
    config = EventSimConfig(pos_threshold=0.12, neg_threshold=0.18, sigma=0.03,
                            refractory_us=60, seed=7)
    sim = EventSimulator(config, h, w)
    pos_map, neg_map = sim.thresholds
    ev = simulate(list(video), times.tolist(), config, h, w)
    expected = _reference_esim(video, times, pos_map, neg_map, config.refractory_us)
    assert len(expected) > 200
    assert _as_tuples(ev, w) == expected


def test_inserting_a_sample_on_the_linear_path_changes_nothing() -> None:
    h, w = 16, 16
    video = _smooth_video(6, h, w, seed=8, amplitude=2.0)
    times = [0, 1000, 2000, 3000, 4000, 5000]
    dense_frames, dense_times = [video[0]], [0]
    for k in range(1, 6):
        dense_frames += [0.5 * (video[k - 1] + video[k]), video[k]]
        dense_times += [times[k] - 500, times[k]]
    config = EventSimConfig(pos_threshold=0.1, neg_threshold=0.1)
    coarse = _run(config, list(video), times)
    dense = _run(config, dense_frames, dense_times)
    assert len(coarse) == len(dense) > 500
    # Same crossings; a time stamp may move by one µs when the float crossing time lies on a
    # rounding boundary, which can also swap two events in the (t, pixel) order.
    a = sorted(zip(coarse.y.tolist(), coarse.x.tolist(), coarse.p.tolist(), coarse.t.tolist(),
                   strict=True))
    b = sorted(zip(dense.y.tolist(), dense.x.tolist(), dense.p.tolist(), dense.t.tolist(),
                   strict=True))
    assert [e[:3] for e in a] == [e[:3] for e in b]
    assert max(abs(ea[3] - eb[3]) for ea, eb in zip(a, b, strict=True)) <= 1


# --- options ---------------------------------------------------------------------------------


def test_threshold_mismatch_statistics_and_seed_determinism() -> None:
    config = EventSimConfig(pos_threshold=0.25, neg_threshold=0.4, sigma=0.03, seed=11)
    h, w = 256, 256
    pos, neg = EventSimulator(config, h, w).thresholds
    n = h * w
    for m, theta in ((pos, 0.25), (neg, 0.4)):
        assert m.shape == (h, w)
        assert abs(m.mean() - theta) < 5 * 0.03 / np.sqrt(n)
        assert abs(m.std() - 0.03) < 5 * 0.03 / np.sqrt(2 * n)
    assert abs(np.corrcoef(pos.ravel(), neg.ravel())[0, 1]) < 5 / np.sqrt(n)
    pos2, neg2 = EventSimulator(config, h, w).thresholds
    np.testing.assert_array_equal(pos, pos2)
    np.testing.assert_array_equal(neg, neg2)
    pos3, _ = EventSimulator(EventSimConfig(sigma=0.03, seed=12), h, w).thresholds
    assert not np.array_equal(pos, pos3)
    # sigma = 0: exact nominal thresholds everywhere.
    pos0, neg0 = EventSimulator(EventSimConfig(0.3, 0.2), 4, 5).thresholds
    assert np.all(pos0 == 0.3) and np.all(neg0 == 0.2)


def test_threshold_mismatch_is_clamped() -> None:
    config = EventSimConfig(pos_threshold=0.05, neg_threshold=0.05, sigma=0.05, seed=1)
    pos, _ = EventSimulator(config, 100, 100).thresholds
    assert pos.min() == pytest.approx(0.01)
    clamped = np.mean(pos == 0.01)
    assert abs(clamped - stats.norm.cdf((0.01 - 0.05) / 0.05)) < 0.02


def test_refractory_drops_events_and_reference_still_moves() -> None:
    # A ramp crossing one threshold every 100 µs: crossings at 100, 200, ..., 1000.
    theta = 0.1
    frames = [np.full((1, 1), 0.0), np.full((1, 1), 1.0), np.full((1, 1), 1.0)]
    times = [0, 1000, 5000]
    free = _run(EventSimConfig(pos_threshold=theta), frames, times)
    np.testing.assert_array_equal(free.t, np.arange(100, 1001, 100))
    ev = _run(EventSimConfig(pos_threshold=theta, refractory_us=250), frames, times)
    # Kept when >= 250 µs after the last *kept* event.
    np.testing.assert_array_equal(ev.t, [100, 400, 700, 1000])
    # ESIM semantics: the dropped change is lost, not emitted after the refractory period,
    # even though the pixel stays at the new level long after.
    assert np.all(ev.t <= 1000)
    # The next crossing fires relative to the moved reference (1.0 + theta), not the last kept.
    frames.append(np.full((1, 1), 1.0 + 2 * theta))
    ev2 = _run(EventSimConfig(pos_threshold=theta, refractory_us=250), frames, times + [7000])
    np.testing.assert_array_equal(ev2.t, [100, 400, 700, 1000, 6000, 7000])


def test_noise_events_have_the_configured_rate() -> None:
    h, w, rate = 64, 64, 10.0
    image = np.zeros((h, w))
    times = list(range(0, 1_000_001, 50_000))  # 1 s in 20 intervals
    config = EventSimConfig(noise_rate_hz=rate, seed=3)
    ev = _run(config, [image] * len(times), times)
    expected = rate * h * w * 1.0
    assert abs(len(ev) - expected) < 5 * np.sqrt(expected)
    n_pos = int(np.sum(ev.p == 1))
    assert abs(n_pos - len(ev) / 2) < 5 * np.sqrt(len(ev)) / 2
    # Per-pixel counts are Poisson: variance / mean = 1 (std of that ratio ~ sqrt(2 / pixels)).
    counts = np.bincount(ev.y.astype(np.int64) * w + ev.x, minlength=h * w)
    assert abs(counts.var() / counts.mean() - 1) < 5 * np.sqrt(2 / (h * w))
    # Times uniform within each interval.
    phase = (ev.t - 1) % 50_000 / 50_000
    assert stats.kstest(phase, "uniform").pvalue > 1e-4
    # Deterministic by seed, different for another seed.
    again = _run(config, [image] * len(times), times)
    np.testing.assert_array_equal(ev.t, again.t)
    np.testing.assert_array_equal(ev.x, again.x)
    other = _run(EventSimConfig(noise_rate_hz=rate, seed=4), [image] * len(times), times)
    assert not np.array_equal(ev.t, other.t)


def test_noise_is_added_on_top_of_unchanged_signal_events() -> None:
    video = _smooth_video(10, 12, 12, seed=9)
    times = [1000 * k for k in range(10)]
    clean = _run(EventSimConfig(pos_threshold=0.1, neg_threshold=0.1), list(video), times)
    noisy = _run(EventSimConfig(pos_threshold=0.1, neg_threshold=0.1, noise_rate_hz=500.0),
                 list(video), times)
    assert len(noisy) > len(clean)
    clean_set = set(_as_tuples(clean, 12))
    noisy_list = _as_tuples(noisy, 12)
    assert clean_set <= set(noisy_list)


# --- streaming, order, dtypes, errors ---------------------------------------------------------


def test_streaming_in_chunks_equals_one_pass_and_reset_reproduces() -> None:
    n, h, w = 30, 20, 24
    video = _smooth_video(n, h, w, seed=10)
    times = (np.arange(n) * 700 + 123).tolist()
    config = EventSimConfig(pos_threshold=0.1, neg_threshold=0.12, sigma=0.02,
                            refractory_us=300, noise_rate_hz=50.0, seed=5)
    one_pass = simulate(iter(video), iter(times), config, h, w)

    sim = EventSimulator(config, h, w)
    for _ in range(2):  # the second round checks that reset() restarts all state
        sim.reset(video[0], times[0])
        chunks = []
        for start in (1, 8, 9, 20):
            stop = {1: 8, 8: 9, 9: 20, 20: n}[start]
            chunks.append(Events.concatenate(
                [sim.step(video[k], times[k]) for k in range(start, stop)]))
        streamed = Events.concatenate(chunks)
        for key in "xytp":
            np.testing.assert_array_equal(getattr(streamed, key), getattr(one_pass, key))
    assert len(one_pass) > 1000


def test_output_sorted_by_time_then_pixel_with_canonical_dtypes() -> None:
    n, h, w = 8, 16, 20
    video = _smooth_video(n, h, w, seed=12, amplitude=3.0)
    times = [0, 3, 10, 500, 501, 900, 2000, 70_000]  # includes 1 µs intervals
    config = EventSimConfig(pos_threshold=0.05, neg_threshold=0.05, noise_rate_hz=1000.0)
    sim = EventSimulator(config, h, w)
    sim.reset(video[0], times[0])
    for k in range(1, n):
        ev = sim.step(video[k], times[k])
        assert ev.x.dtype == np.uint16 and ev.y.dtype == np.uint16
        assert ev.t.dtype == np.int64 and ev.p.dtype == np.int8
        assert np.all((ev.p == 1) | (ev.p == -1))
        assert np.all((ev.t > times[k - 1]) & (ev.t <= times[k]))
        assert np.all(ev.x < w) and np.all(ev.y < h)
        pix = ev.y.astype(np.int64) * w + ev.x
        order = np.lexsort((pix, ev.t))
        np.testing.assert_array_equal(order, np.arange(len(ev)))
        assert len(ev) > 0


def test_invalid_input_is_rejected() -> None:
    for kwargs in ({"pos_threshold": 0.0}, {"neg_threshold": -0.1}, {"sigma": -1.0},
                   {"refractory_us": -5}, {"noise_rate_hz": -1.0}, {"eps": 0.0},
                   {"pos_threshold": float("nan")}):
        with pytest.raises(ConfigError):
            EventSimConfig(**kwargs)
    sim = EventSimulator(EventSimConfig(), 4, 5)
    with pytest.raises(RuntimeError):
        sim.step(np.zeros((4, 5)), 10)
    with pytest.raises(ValueError):
        sim.reset(np.zeros((5, 4)), 0)
    sim.reset(np.zeros((4, 5)), 100)
    with pytest.raises(ValueError, match="increase"):
        sim.step(np.zeros((4, 5)), 100)
    with pytest.raises(ValueError, match="increase"):
        sim.step(np.zeros((4, 5)), 50)
    with pytest.raises(ValueError):
        sim.step(np.full((4, 5), np.nan), 200)
    with pytest.raises(ValueError, match="integer"):
        sim.step(np.zeros((4, 5)), 200.5)  # type: ignore[arg-type]  # the runtime check
    with pytest.raises(ValueError):
        EventSimulator(EventSimConfig(), 0, 5)
    with pytest.raises(ValueError):
        simulate([np.zeros((4, 5))] * 3, [0, 1], EventSimConfig(), 4, 5)


def test_simulator_does_not_alias_caller_arrays() -> None:
    sim = EventSimulator(EventSimConfig(), 2, 2)
    image = np.zeros((2, 2))
    sim.reset(image, 0)
    image += 10.0  # caller reuses its buffer
    assert len(sim.step(np.zeros((2, 2)), 10)) == 0


@pytest.mark.parametrize("dt", [1000, 10**6])  # counting sort / comparison sort paths
def test_event_ordering_merges_crossings_and_noise_by_time_then_pixel(dt: Any) -> None:
    rng = np.random.default_rng(13)
    h, w = 5, 6

    def pixel_ordered(n: int, with_keep: bool) -> tuple[np.ndarray, ...]:
        pix = np.sort(rng.integers(0, h * w, n))
        cols: list[np.ndarray] = [(pix % w).astype(np.uint16), (pix // w).astype(np.uint16),
                rng.integers(1, 40, n).astype(np.int64),
                np.where(rng.random(n) < 0.5, 1, -1).astype(np.int8)]
        if with_keep:
            cols.append(rng.random(n) < 0.8)
        return tuple(cols)

    signal, noise = pixel_ordered(300, True), pixel_ordered(100, False)
    ev = EventSimulator._sorted_events(signal, noise, 5_000, dt)
    rows = [(5_000 + d, y, x, 0, i, p)
            for i, (x, y, d, p, k) in enumerate(zip(*signal, strict=True)) if k]
    rows += [(5_000 + d, y, x, 1, i, p)
             for i, (x, y, d, p) in enumerate(zip(*noise, strict=True))]
    rows.sort()  # (t, y, x, crossing before noise, input order)
    assert ev.t.tolist() == [r[0] for r in rows]
    assert ev.y.tolist() == [r[1] for r in rows]
    assert ev.x.tolist() == [r[2] for r in rows]
    assert ev.p.tolist() == [r[5] for r in rows]
