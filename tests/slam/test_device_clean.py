"""Every tensor the SLAM creates lives on the system's device (caught without a GPU).

A tensor made without an explicit device lands on torch's default device. Here the default is
set to ``meta`` while the SLAM runs on the CPU: every such tensor becomes a meta tensor, and
the first operation that mixes it with the system's CPU tensors raises, exactly as a CUDA run
raises "Expected all tensors to be on the same device" when a CPU tensor slips in (the crash of
``--preset cpu --device cuda`` in the constant-velocity prediction). Host-side numpy work is
unaffected; the numba rasteriser, CPU-only by design, runs with the CPU default.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import torch

from egs_bench.datasets.sequence import Sequence
from egs_bench.slam import methods
from egs_bench.slam.system import SlamSystem

FAST = dict(resolution_scale=1.0, init_iters=3, tracking_iters=3, mapping_iters=2,
            kf_interval=1, pcd_downsample_init=4, pcd_downsample=8, pose_window=2,
            refine_iters=2)


@pytest.fixture
def stray_tensors_on_meta(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """Default device ``meta`` everywhere except inside the numba rasteriser backend."""
    numba_backend = importlib.import_module("egs_bench.render.numba_backend")
    composite = numba_backend.composite_tiles

    def on_cpu(*args: Any, **kwargs: Any) -> Any:
        with torch.device("cpu"):
            return composite(*args, **kwargs)

    monkeypatch.setattr(numba_backend, "composite_tiles", on_cpu)
    with torch.device("meta"):
        yield


@pytest.mark.parametrize("method", ["egs", "monogs"])
@pytest.mark.parametrize("motion_model", ["constant-velocity", "constant-position"])
def test_slam_makes_no_tensor_off_the_system_device(tiny_sequence: Path, method: str,
                                                    motion_model: str,
                                                    stray_tensors_on_meta: None) -> None:
    seq = Sequence.open(tiny_sequence)
    cfg = methods.BUILTIN[method].config("cpu").replace(motion_model=motion_model, **FAST)
    result = SlamSystem(seq, cfg, device="cpu", seed=0).run(len(seq))
    assert len(result.states) == len(seq) and len(result.keyframes) >= 2
    assert result.gmap.means.device.type == "cpu"


def test_the_check_catches_a_tensor_made_without_a_device(stray_tensors_on_meta: None) -> None:
    """The mechanism itself: a CPU tensor combined with one made without a device raises."""
    cpu = torch.ones(3, device="cpu")
    with pytest.raises((RuntimeError, NotImplementedError)):
        (cpu * torch.tensor([0.5])).sum().item()
