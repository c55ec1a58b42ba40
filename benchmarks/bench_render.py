"""Rasteriser speed: egs_bench.render (numba backend) side by side with the prototype.

Prints, for N = 20k Gaussians (the prototype's benchmark scene, ``reference/rasterizer_proto/
scene.py``) at 224x128 and 448x256 with K = 5 and K = 1 cameras, the median wall time of

* ``fwd``: projection + compositing under ``torch.no_grad()``;
* ``fwd+bwd``: the same plus ``backward()`` of a scalar loss on rgb, depth and alpha with every
  map parameter and the poses requiring grad;
* ``pose bwd``: the same with only the poses requiring grad (tracking);

and the peak resident-memory increase of fwd+bwd calls (measured in a fresh process). The prototype
(``../shared/reference/rasterizer_proto``) and egs_bench runs are interleaved call by call, so
both see the same machine load; the ratio column is prototype / ours (> 1: we are faster).
Without ``../shared`` the prototype columns are skipped.

With ``--gsplat`` (GPU machines) the gsplat backend is timed on CUDA tensors for the same cases
(with ``torch.cuda.synchronize()``); its memory is not measured here.

usage: NUMBA_CACHE_DIR=.cache/numba python benchmarks/bench_render.py [--runs 7] [--quick]
       [--no-timing] [--gsplat]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

# Shared 2-core machines: OpenMP pools that spin-wait (torch's and numba's are separate) steal
# each other's cores and made every variant 2-4x slower in our runs; passive waiting avoids it.
# Must be set before the OpenMP runtimes load. Override by exporting OMP_WAIT_POLICY.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import torch

ROOT = Path(__file__).resolve().parents[1]
PROTO_DIR = ROOT.parent / "shared" / "reference" / "rasterizer_proto"
sys.path.insert(0, str(ROOT))

from egs_bench.render import rasterize  # noqa: E402

N_GAUSSIANS = 20_000
SIZES = {"224x128": (224, 128, 200.0), "448x256": (448, 256, 400.0)}


def make_scene(n: int, width: int, height: int, focal: float, k: int, seed: int = 0) -> dict:
    """Same distribution as the prototype's scene.py (uniform in the frustum at z in [2, 8],
    log-uniform scales 0.01-0.1, logits ~ N(0,1), RGB ~ U(0,1); K poses on a short arc)."""
    import math

    g = torch.Generator().manual_seed(seed)
    tx, ty = (width / 2) / focal, (height / 2) / focal
    z = 2.0 + 6.0 * torch.rand(n, generator=g, dtype=torch.float64)
    x = (torch.rand(n, generator=g, dtype=torch.float64) * 2 - 1) * 1.1 * tx * z
    y = (torch.rand(n, generator=g, dtype=torch.float64) * 2 - 1) * 1.1 * ty * z
    lo, hi = math.log(0.01), math.log(0.1)
    p = dict(
        means=torch.stack([x, y, z], -1),
        quats=torch.randn(n, 4, generator=g, dtype=torch.float64),
        log_scales=lo + (hi - lo) * torch.rand(n, 3, generator=g, dtype=torch.float64),
        opacity_logits=torch.randn(n, generator=g, dtype=torch.float64),
        colors=torch.rand(n, 3, generator=g, dtype=torch.float64),
    )
    p = {key: v.float() for key, v in p.items()}
    mats = []
    for i in range(k):
        a = math.radians(0.5 * (i - (k - 1) / 2))
        ca, sa, cb, sb = math.cos(a), math.sin(a), math.cos(0.3 * a), math.sin(0.3 * a)
        ry = torch.tensor([[ca, 0, sa], [0, 1, 0], [-sa, 0, ca]], dtype=torch.float64)
        rx = torch.tensor([[1, 0, 0], [0, cb, -sb], [0, sb, cb]], dtype=torch.float64)
        m = torch.eye(4, dtype=torch.float64)
        m[:3, :3] = ry @ rx
        m[:3, 3] = torch.tensor([0.01 * (i - (k - 1) / 2), 0.002 * i, 0.0])
        mats.append(m)
    p["viewmats"] = torch.stack(mats).float()
    K = torch.tensor([[focal, 0, width / 2], [0, focal, height / 2], [0, 0, 1]])
    p["Ks"] = K.expand(k, 3, 3).clone()
    return p


def ours(p: dict, width: int, height: int) -> tuple[torch.Tensor, ...]:
    out = rasterize(p["means"], p["quats"], torch.exp(p["log_scales"]),
                    torch.sigmoid(p["opacity_logits"]), p["colors"], p["viewmats"], p["Ks"],
                    width, height, backend="numba")
    return out.rgb, out.depth, out.alpha


def gsplat_impl(p: dict, width: int, height: int) -> tuple[torch.Tensor, ...]:
    """The same render through the gsplat CUDA backend (``p`` holds CUDA tensors)."""
    out = rasterize(p["means"], p["quats"], torch.exp(p["log_scales"]),
                    torch.sigmoid(p["opacity_logits"]), p["colors"], p["viewmats"], p["Ks"],
                    width, height, backend="gsplat")
    return out.rgb, out.depth, out.alpha


def make_proto() -> Callable | None:
    if not PROTO_DIR.is_dir():
        return None
    sys.path.insert(0, str(PROTO_DIR))
    from numba_raster import RasterizeNumba  # type: ignore[import-not-found]
    from projection import project  # type: ignore[import-not-found]

    def proto(p: dict, width: int, height: int) -> tuple[torch.Tensor, ...]:
        K = p["Ks"][0]
        intr = torch.tensor([K[0, 0], K[1, 1], K[0, 2], K[1, 2]], dtype=torch.float64)
        m2, con, dep, op, ext = project(p["means"], p["quats"], p["log_scales"],
                                        p["opacity_logits"], p["viewmats"], intr, width, height)
        return RasterizeNumba.apply(m2, con, dep, op, p["colors"], ext, width, height)

    return proto


def _rss_mb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def peak_rss_child(impl: str, size: str, k: int) -> float:
    """Peak RSS increase (MiB) of two fwd+bwd calls of ``impl``, measured in a fresh process
    (``ru_maxrss`` after minus the RSS just before the first call, after a tiny warm-up render
    that loads the kernels), so that memory freed by earlier cases cannot hide it."""
    import subprocess

    out = subprocess.run([sys.executable, __file__, "--peak-child", impl, size, str(k)],
                         capture_output=True, text=True, check=True)
    return float(out.stdout.strip().splitlines()[-1])


def _peak_child(impl: str, size: str, k: int) -> None:
    import resource

    w, h, f = SIZES[size]
    fn = ours if impl == "ours" else make_proto()
    # A tiny render first loads the compiled kernels (numba cache, llvmlite), so the peak below
    # is the memory of rendering itself, not of loading code.
    tiny = with_grads(make_scene(16, 32, 32, 30.0, 1), "fwd+bwd")
    task(fn, tiny, 32, 32, "fwd+bwd")()
    p = with_grads(make_scene(N_GAUSSIANS, w, h, f, k), "fwd+bwd")
    run = task(fn, p, w, h, "fwd+bwd")
    base = _rss_mb()
    run()
    run()
    print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024 - base)


def task(impl: Callable, p: dict, width: int, height: int, mode: str) -> Callable[[], None]:
    cuda = p["means"].is_cuda

    def run() -> None:
        if mode == "fwd":
            with torch.no_grad():
                impl(p, width, height)
        else:
            rgb, dep, alpha = impl(p, width, height)
            (rgb.mean() + dep.mean() + alpha.mean()).backward()
            for v in p.values():
                v.grad = None
        if cuda:
            torch.cuda.synchronize()

    return run


def with_grads(p: dict, mode: str) -> dict:
    q = {k: v.detach().clone() for k, v in p.items()}
    for k, v in q.items():
        if k == "viewmats":
            v.requires_grad_(mode != "fwd")
        elif k != "Ks":
            v.requires_grad_(mode == "fwd+bwd")
    return q


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=7, help="timed calls per implementation and case")
    ap.add_argument("--quick", action="store_true", help="only 224x128, K=5")
    ap.add_argument("--no-timing", action="store_true", help="only the peak-memory columns")
    ap.add_argument("--gsplat", action="store_true",
                    help="also time backend='gsplat' on CUDA tensors (needs a GPU and gsplat)")
    ap.add_argument("--peak-child", nargs=3, metavar=("IMPL", "SIZE", "K"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.peak_child:
        _peak_child(args.peak_child[0], args.peak_child[1], int(args.peak_child[2]))
        return
    proto = make_proto()
    impls = {"ours": ours} | ({"proto": proto} if proto else {})
    cases = [(s, k) for s in SIZES for k in (5, 1)]
    if args.quick:
        cases = [("224x128", 5)]
    print(f"# torch {torch.__version__}, threads {torch.get_num_threads()}, "
          f"OMP_WAIT_POLICY={os.environ['OMP_WAIT_POLICY']}, N={N_GAUSSIANS}, "
          f"prototype {'found' if proto else 'absent'}; median of {args.runs} interleaved runs")
    rows = []
    for size, k in cases:
        w, h, f = SIZES[size]
        base = make_scene(N_GAUSSIANS, w, h, f, k)
        for mode in ("fwd", "fwd+bwd", "pose bwd"):
            if args.no_timing and mode != "fwd+bwd":
                continue
            p = with_grads(base, mode)
            runs = {name: task(fn, p, w, h, mode) for name, fn in impls.items()}
            if args.gsplat:
                pc = {key: v.detach().cuda().requires_grad_(v.requires_grad)
                      for key, v in p.items()}
                runs["gsplat"] = task(gsplat_impl, pc, w, h, mode)
            med = {name: float("nan") for name in runs}
            if not args.no_timing:
                for fn in runs.values():  # compile / warm up
                    fn()
                    fn()
                times: dict[str, list[float]] = {name: [] for name in runs}
                for _ in range(args.runs):
                    for name, fn in runs.items():
                        t0 = time.perf_counter()
                        fn()
                        times[name].append((time.perf_counter() - t0) * 1e3)
                med = {name: statistics.median(v) for name, v in times.items()}
            mem = {}
            if mode == "fwd+bwd":
                mem = {name: peak_rss_child(name, size, k) for name in runs if name != "gsplat"}
            row = {"size": size, "K": k, "mode": mode, "ours_ms": med["ours"],
                   "ours_peak_MiB": mem.get("ours")}
            if args.gsplat:
                row["gsplat_ms"] = med["gsplat"]
            if proto:
                row |= {"proto_ms": med["proto"], "proto_peak_MiB": mem.get("proto"),
                        "ratio": med["proto"] / med["ours"]}
            rows.append(row)
            print(" | ".join(f"{key}={val:.1f}" if isinstance(val, float) else f"{key}={val}"
                             for key, val in row.items() if val is not None), flush=True)
    try:
        import pandas as pd

        print()
        print(pd.DataFrame(rows).to_markdown(index=False, floatfmt=".1f"))
    except ImportError:
        pass


if __name__ == "__main__":
    main()
