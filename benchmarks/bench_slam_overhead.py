"""Count the work the SLAM loop issues per tracking and per mapping iteration.

On a GPU every ATen operation is a kernel launch of several microseconds and every host sync
(``float(t)``, ``t.item()``, ``bool(t)``, ``.cpu()``, ``.numpy()``, ``nonzero``) drains the launch
queue, so for small per-iteration workloads these counts, not FLOPs, set the speed. The counts
are device independent: they are taken here on whatever device runs the script (CPU by
default) with a ``TorchDispatchMode`` (every ATen op, forward and backward) and a
``TorchFunctionMode`` (host transfers the dispatcher does not see on the CPU).

Ops are split into *rasteriser* (issued inside :func:`egs_bench.render.rasterize`, and in
backward by autograd nodes that rasterize created) and *SLAM-side* (everything else: pose
algebra, losses, optimiser, bookkeeping). With ``--device cuda`` the script also times the
iterations (synchronised wall time).

Usage::

    python benchmarks/bench_slam_overhead.py --seq demo --preset paper
    python benchmarks/bench_slam_overhead.py --seq office1 --preset paper --device cuda
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np
import torch
from torch.overrides import TorchFunctionMode
from torch.utils._python_dispatch import TorchDispatchMode

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import importlib  # noqa: E402

from egs_bench.datasets.registry import resolve_sequence  # noqa: E402
from egs_bench.datasets.sequence import Sequence  # noqa: E402
from egs_bench.geometry import invert_pose  # noqa: E402
from egs_bench.slam import methods  # noqa: E402
from egs_bench.slam.frames import FrameObs, FrameState  # noqa: E402
from egs_bench.slam.system import SlamSystem  # noqa: E402
from egs_bench.slam.tracker import TrackRequest, predict_initial, track_frame  # noqa: E402

# The package re-exports the function under the module's name, so fetch the module itself.
rasterize_module = importlib.import_module("egs_bench.render.rasterize")

# ATen ops whose output size or value must reach the host: each is a sync on a GPU.
SYNC_OPS = {"_local_scalar_dense", "nonzero", "masked_select", "_unique2", "unique_dim",
            "unique_consecutive", "is_nonzero", "item"}
# Tensor methods that copy to the host (no ATen op on the CPU, a device-to-host sync on a GPU).
# Ops that only make a new view of existing memory: no kernel launch on a GPU.
VIEW_OPS = {"view", "_unsafe_view", "unsqueeze", "squeeze", "expand", "slice", "select",
            "detach", "alias", "as_strided", "permute", "transpose", "t", "unbind", "split",
            "lift_fresh", "_reshape_alias", "reshape", "_to_copy_view"}
# ``.numpy()`` is not listed: it only works on host tensors (after ``.cpu()``, the sync).
HOST_METHODS = {"cpu", "tolist"}


class OpCounter(TorchDispatchMode):
    """Counts ATen ops, split by whether the rasteriser issued them."""

    def __init__(self) -> None:
        super().__init__()
        self.slam: Counter[str] = Counter()
        self.raster: Counter[str] = Counter()
        self.raster_nodes: set[int] = set()
        self.in_raster = 0

    def _inside_raster(self) -> bool:
        if self.in_raster:
            return True
        node = torch._C._current_autograd_node()
        return node is not None and id(node) in self.raster_nodes

    def __torch_dispatch__(self, func, types, args=(), kwargs=None):
        name = func.overloadpacket.__name__
        (self.raster if self._inside_raster() else self.slam)[name] += 1
        return func(*args, **(kwargs or {}))


class HostCounter(TorchFunctionMode):
    """Counts host transfers by Tensor methods (``.item()``, ``float(t)``, ``.cpu()``, ...)."""

    def __init__(self, ops: OpCounter) -> None:
        super().__init__()
        self.ops = ops
        self.slam: Counter[str] = Counter()
        self.raster: Counter[str] = Counter()

    def __torch_function__(self, func, types, args=(), kwargs=None):
        name = getattr(func, "__name__", "")
        if name in HOST_METHODS:
            (self.raster if self.ops._inside_raster() else self.slam)[name] += 1
        return func(*args, **(kwargs or {}))


def _graph_nodes(roots: list[torch.Tensor], stop: set[int]) -> set[int]:
    """ids of autograd nodes reachable from ``roots`` without passing through ``stop``."""
    seen: set[int] = set()
    todo = [t.grad_fn for t in roots if t.grad_fn is not None]
    while todo:
        node = todo.pop()
        if node is None or id(node) in seen or id(node) in stop:
            continue
        seen.add(id(node))
        todo.extend(n for n, _ in node.next_functions if n is not None)
    return seen


@contextlib.contextmanager
def counting():
    """Patch :func:`rasterize` to mark its ops and autograd nodes; yield the counters."""
    ops = OpCounter()
    host = HostCounter(ops)
    original = rasterize_module.rasterize
    keep_alive: list[object] = []

    def marked(means, quats, scales, opacities, colors, viewmats, *args, **kwargs):
        inputs = [means, quats, scales, opacities, colors, viewmats]
        before = _graph_nodes([t for t in inputs if isinstance(t, torch.Tensor)], set())
        ops.in_raster += 1
        try:
            res = original(means, quats, scales, opacities, colors, viewmats, *args, **kwargs)
        finally:
            ops.in_raster -= 1
        outs = [res.rgb, res.depth, res.expected_depth, res.alpha, res.means2d, res.depths]
        ops.raster_nodes |= _graph_nodes([t for t in outs if t.requires_grad], before)
        keep_alive.append(res)  # ids stay unique while the graph lives
        return res

    rasterize_module.rasterize = marked
    try:
        with ops, host:
            yield ops, host
    finally:
        rasterize_module.rasterize = original


def _per_iter(counter: Counter[str], n: int) -> float:
    return sum(counter.values()) / n


def _launching(counter: Counter[str], n: int) -> float:
    return sum(v for k, v in counter.items() if k not in VIEW_OPS) / n


def _syncs(ops: Counter[str], host: Counter[str]) -> int:
    return sum(v for k, v in ops.items() if k in SYNC_OPS) + sum(host.values())


def _sync_device(device: str) -> None:
    if device.startswith("cuda"):
        torch.cuda.synchronize()


def keyframe_at_truth(system: SlamSystem, seq: Sequence, index: int, downsample: int
                      ) -> tuple[FrameState, FrameObs]:
    """Frame ``index`` at its ground-truth pose (``T_0 = T_tau``), inserted into the map with
    1 in ``downsample`` of its valid pixels: a keyframe without tracking error."""
    pose = invert_pose(np.asarray(seq.poses[index], dtype=np.float64))
    state, obs = FrameState(index, pose.copy(), pose.copy()), system.obs(index)
    system.insert(obs, state, downsample, index)
    return state, obs


def measure(method: str, seq: Sequence, preset: str, device: str, iters: int,
            warmup: int) -> dict[str, object]:
    """Counts (and on CUDA, times) ``iters`` tracking and mapping iterations of ``method``."""
    cfg = methods.BUILTIN[method].config(preset).replace(init_iters=30, converged_threshold=0.0)
    system = SlamSystem(seq, cfg, device=device, seed=0)
    # A real map of frame 0 so the rasteriser sees realistic Gaussian counts.
    s0, obs0 = keyframe_at_truth(system, seq, 0, cfg.budget.pcd_downsample_init)
    system.mapper.optimise({0: s0}, {0: obs0}, [0], [0], cfg.budget.init_iters, initial=True)
    obs1 = system.obs(1)
    t0, t1 = (int(v) for v in seq.exposure(1))
    e0 = int(seq.exposure(0)[1])
    init = predict_initial(1, [s0], cfg.tracking.motion_model, t0, t1, e0, None,
                           int(seq.exposure(0)[0]))

    def track(n: int):
        return track_frame(system.ctx, system.gmap, system.crf,
                           TrackRequest(obs1, init, iterations=n))

    track(warmup)
    with counting() as (ops, host):
        track(iters)
    out: dict[str, object] = {
        "method": method, "preset": preset, "device": device,
        "resolution": f"{system.ctx.width}x{system.ctx.height}", "gaussians": len(system.gmap),
        "tracking": {"slam_ops": _per_iter(ops.slam, iters),
                     "slam_launching_ops": _launching(ops.slam, iters),
                     "raster_ops": _per_iter(ops.raster, iters),
                     "slam_syncs": _syncs(ops.slam, host.slam) / iters,
                     "raster_syncs": _syncs(ops.raster, host.raster) / iters,
                     "top_slam_ops": ops.slam.most_common(),
                     "host_calls": dict(host.slam)},
    }
    if device.startswith("cuda"):
        _sync_device(device)
        t = time.perf_counter()
        track(iters)
        _sync_device(device)
        out["tracking"]["ms_per_iter"] = 1e3 * (time.perf_counter() - t) / iters  # type: ignore

    # Mapping: frame 1 becomes a keyframe; iterations over the window [1, 0].
    s1 = track(cfg.budget.tracking_iters).state
    states = {0: s0, 1: s1}
    observations = {0: obs0, 1: obs1}
    system.insert(obs1, s1, cfg.budget.pcd_downsample, 1)
    system.mapper.optimise(states, observations, [1, 0], [0, 1], warmup)
    with counting() as (ops, host):
        system.mapper.optimise(states, observations, [1, 0], [0, 1], iters)
    out["mapping"] = {"views": 2, "slam_ops": _per_iter(ops.slam, iters),
                      "slam_launching_ops": _launching(ops.slam, iters),
                      "raster_ops": _per_iter(ops.raster, iters),
                      "slam_syncs": _syncs(ops.slam, host.slam) / iters,
                      "raster_syncs": _syncs(ops.raster, host.raster) / iters,
                      "top_slam_ops": ops.slam.most_common(),
                      "host_calls": dict(host.slam)}
    if device.startswith("cuda"):
        _sync_device(device)
        t = time.perf_counter()
        system.mapper.optimise(states, observations, [1, 0], [0, 1], iters)
        _sync_device(device)
        out["mapping"]["ms_per_iter"] = 1e3 * (time.perf_counter() - t) / iters  # type: ignore
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seq", default="demo", help="sequence name or folder (default: demo)")
    ap.add_argument("--preset", default="paper")
    ap.add_argument("--methods", default="egs,monogs")
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--iters", type=int, default=20,
                    help="iterations counted (per-frame set-up is amortised over them)")
    ap.add_argument("--warmup", type=int, default=2)
    ap.add_argument("--json", type=Path, help="also write the results here")
    args = ap.parse_args(argv)
    seq = Sequence.open(resolve_sequence(args.seq))
    results = []
    for method in args.methods.split(","):
        t = time.perf_counter()
        r = measure(method, seq, args.preset, args.device, args.iters, args.warmup)
        r["script_s"] = round(time.perf_counter() - t, 1)
        results.append(r)
        for phase in ("tracking", "mapping"):
            p = r[phase]
            timing = f", {p['ms_per_iter']:.2f} ms/iter" if "ms_per_iter" in p else ""
            print(f"{method:7s} {phase:8s} per iteration: SLAM-side {p['slam_ops']:4.0f} ops "
                  f"({p['slam_launching_ops']:3.0f} not views) {p['slam_syncs']:4.1f} syncs | "
                  f"rasteriser {p['raster_ops']:5.0f} ops "
                  f"{p['raster_syncs']:4.1f} syncs{timing}")
        print(f"        top SLAM-side ops (tracking): {r['tracking']['top_slam_ops'][:8]}")
        print(f"        host calls (tracking): {r['tracking']['host_calls']}")
        print(f"        top SLAM-side ops (mapping): {r['mapping']['top_slam_ops'][:8]}")
        print(f"        host calls (mapping): {r['mapping']['host_calls']}")
    if args.json:
        args.json.write_text(json.dumps(results, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
