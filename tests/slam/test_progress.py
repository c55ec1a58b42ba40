"""The SLAM progress line during long phases: no ETA from iterations that compiled kernels."""

from __future__ import annotations

from egs_bench.slam.progress import COMPILING, PhaseProgress
from tests.helpers.clock import FakeClock as _Clock


def test_compiling_is_said_and_the_eta_ignores_the_compiling_iteration() -> None:
    clock, ready = _Clock(), [False]
    progress = PhaseProgress(lambda: ready[0], clock, cold_cache=lambda: True)
    assert progress.text("map init", 0, 150) == f"map init 0/150 iterations, {COMPILING}"
    clock.now, ready[0] = 300.0, True  # the first iteration compiled for 300 s
    assert progress.text("map init", 1, 150) == "map init 1/150 iterations"
    clock.now = 302.0  # then 1 s per iteration
    assert progress.text("map init", 3, 150) == "map init 3/150 iterations, ETA 147 s"
    clock.now = 349.0
    assert progress.text("map init", 50, 150) == "map init 50/150 iterations, ETA 100 s"


def test_kernels_in_the_cache_are_not_said_to_compile_but_their_load_is_no_eta() -> None:
    clock, ready, asked = _Clock(), [False], []
    progress = PhaseProgress(lambda: ready[0], clock, cold_cache=lambda: bool(asked.append(1)))  # type: ignore[func-returns-value]
    assert progress.text("map init", 0, 150) == "map init 0/150 iterations"
    assert progress.text("map init", 0, 150) == "map init 0/150 iterations"
    assert asked == [1]  # the cache is looked at once
    clock.now, ready[0] = 2.0, True  # the first iteration loaded the kernels
    assert progress.text("map init", 1, 150) == "map init 1/150 iterations"
    clock.now = 4.0
    assert progress.text("map init", 3, 150) == "map init 3/150 iterations, ETA 147 s"


def test_the_default_cache_check_reads_numba_s_cache() -> None:
    from egs_bench.kernel_cache import uncached_kernels
    from egs_bench.slam.progress import _render_kernels_uncached

    assert _render_kernels_uncached() == bool(uncached_kernels("egs_bench.render"))


def test_a_later_phase_with_compiled_kernels_gets_an_eta_from_its_start() -> None:
    clock = _Clock()
    progress = PhaseProgress(lambda: True, clock)
    progress.text("map init", 0, 10)
    clock.now = 10.0
    progress.text("map init", 10, 10)
    clock.now = 50.0  # a new phase restarts the measurement (the gap is not counted)
    assert progress.text("mapping", 0, 30) == "mapping 0/30 iterations"
    clock.now = 52.0
    assert progress.text("mapping", 4, 30) == "mapping 4/30 iterations, ETA 13 s"


def test_without_a_readiness_check_nothing_is_said_to_compile() -> None:
    clock = _Clock()
    progress = PhaseProgress(None, clock)
    assert progress.text("mapping", 0, 4) == "mapping 0/4 iterations"
    clock.now = 1.0
    assert progress.text("mapping", 2, 4) == "mapping 2/4 iterations, ETA 1 s"


def test_the_cpu_rasteriser_is_ready_once_it_has_rendered_and_back_propagated() -> None:
    import torch

    from egs_bench.render import rasterize
    from egs_bench.render.cpu_kernels import kernels_ready

    means = torch.tensor([[0.0, 0.0, 2.0]], requires_grad=True)
    quats = torch.tensor([[1.0, 0.0, 0.0, 0.0]])
    scales = torch.full((1, 3), 0.1)
    opacities = torch.tensor([0.9])
    colors = torch.tensor([[0.5, 0.5, 0.5]])
    viewmats = torch.eye(4)[None]
    Ks = torch.tensor([[[16.0, 0.0, 8.0], [0.0, 16.0, 8.0], [0.0, 0.0, 1.0]]])
    out = rasterize(means, quats, scales, opacities, colors, viewmats, Ks, 16, 16,
                    backend="numba")
    out.rgb.sum().backward()
    assert kernels_ready()
