"""One-command check of a CUDA machine: gsplat build, CUDA tests, paper-budget speed and accuracy.

Run it through ``benchmarks/gpu_check.sh`` (or ``make gpu-check``), which sets the build
environment. Steps, each timed and bounded:

1. environment (torch, CUDA device, gsplat version) and gsplat's JIT build (first use);
2. the CUDA tests (``pytest -m cuda``: gsplat against the reference rasteriser, SLAM on CUDA
   against the CPU);
3. the built-in 448x256 sequence (generated on first use);
4. ``egs`` and ``monogs`` on its first ``--frames`` frames, once per ``--runs`` entry
   ``PRESET[@SETTING][:MAPPING_MODE]`` (default: the paper budget sequential, the paper budget
   with the ``r3`` schedule of ``benchmarks/sweeps/paper_levers.yaml``, the ``cpu`` preset (the
   CPU default) and the paper budget concurrent; ``@SETTING`` names a setting of that sweep
   file, so the GPU measures exactly the schedule the CPU frontier measured): FPS, per-frame
   seconds, ATE and PSNR against the sharp ground truth, tracking iterations per frame, and
   the rendering work per frame (cameras, pixels, tile intersections; slam_stats.json's
   ``work``) next to the time; a run that would start after ``--until-s`` seconds is left out
   and listed as such;
5. the overhead counts of ``bench_slam_overhead.py`` with wall time per iteration;
6. a torch-profiler trace of one ``egs`` and one ``monogs`` mapping iteration on two
   keyframes (``--profile-views``): CUDA time per kernel, the data that explains why an
   ``egs`` mapping camera costs 8-10x a ``monogs`` one (docs/notes/engine_cost_2026-12-04.md).

Everything lands in one JSON file (``--json``, default ``gpu_check.json``) and its Markdown
table next to it (``gpu_check.md``), the table BENCHMARKS.md shows.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from egs_bench.datasets.sequence import Sequence

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def _timed(report: dict, key: str):
    class _Timer:
        def __enter__(self):
            self.t = time.perf_counter()

        def __exit__(self, *exc):
            report.setdefault("seconds", {})[key] = round(time.perf_counter() - self.t, 1)
            return False
    return _Timer()


def environment() -> dict:
    import torch

    info = {"torch": torch.__version__, "cuda_available": torch.cuda.is_available()}
    if not torch.cuda.is_available():
        raise SystemExit("gpu_check: no CUDA GPU visible to torch")
    info["device"] = torch.cuda.get_device_name(0)
    info["cuda"] = torch.version.cuda
    try:
        import gsplat
    except ImportError:
        raise SystemExit("gpu_check: gsplat is not installed: pip install -e '.[cuda]'") from None
    info["gsplat"] = gsplat.__version__
    return info


def build_gsplat() -> None:
    """First gsplat call: compiles its CUDA extension (about a minute) unless cached."""
    import torch

    from egs_bench.render import rasterize

    dev = torch.device("cuda")
    means = torch.tensor([[0.0, 0.0, 2.0]], device=dev)
    out = rasterize(means, torch.tensor([[1.0, 0, 0, 0]], device=dev),
                    torch.full((1, 3), 0.1, device=dev), torch.tensor([0.9], device=dev),
                    torch.ones(1, 3, device=dev), torch.eye(4, device=dev)[None],
                    torch.tensor([[[50.0, 0, 16], [0, 50, 12], [0, 0, 1]]], device=dev), 32, 24)
    torch.cuda.synchronize()
    if not bool(out.visibility[0, 0]):
        raise SystemExit("gpu_check: gsplat rendered nothing for a Gaussian in front of the camera")


def cuda_tests(timeout_s: float) -> dict:
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-m", "cuda",
           "-rA", "tests/render", "tests/slam"]
    try:
        proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=timeout_s)
    except subprocess.TimeoutExpired:
        return {"passed": False, "summary": f"timed out after {timeout_s:.0f} s"}
    lines = (proc.stdout + proc.stderr).strip().splitlines()
    return {"passed": proc.returncode == 0, "summary": lines[-1] if lines else "",
            "log_tail": lines[-40:]}


LEVERS_SWEEP = ROOT / "benchmarks" / "sweeps" / "paper_levers.yaml"
DEFAULT_RUNS = "paper:sequential,paper@r3:sequential,cpu:sequential,paper:concurrent"


def parse_run_entry(entry: str, levers_sweep: Path = LEVERS_SWEEP) -> tuple[str, str, str, dict]:
    """``PRESET[@SETTING][:MAPPING_MODE]`` -> (label, preset, mapping mode, options).

    The label is ``PRESET`` or ``PRESET@SETTING``; the options are that setting's fields in
    ``levers_sweep`` (empty without ``@SETTING``)."""
    import yaml

    head, _, schedule = entry.partition(":")
    preset, _, setting = head.partition("@")
    options: dict = {}
    if setting:
        settings = (yaml.safe_load(levers_sweep.read_text()) or {}).get("settings") or {}
        if setting not in settings:
            raise SystemExit(f"gpu_check: --runs {entry!r}: {levers_sweep.name} has no setting "
                             f"{setting!r} (it has {', '.join(sorted(settings))})")
        options = dict(settings[setting])
    return head, preset, schedule or "sequential", options


def run_method(method: str, seq: Sequence, frames: int, out: Path, schedule: str,
               preset: str = "paper", options: dict | None = None) -> dict:
    import numpy as np

    from egs_bench.eval.ate import ate_from_files
    from egs_bench.eval.image_metrics import psnr
    from egs_bench.runs.registry import get_method, with_options

    t = time.perf_counter()
    run = with_options(get_method(method), {**(options or {}), "mapping_mode": schedule}).run(
        seq, out, preset=preset, device="cuda", seed=0, max_frames=frames, progress=False)
    wall = time.perf_counter() - t
    timing = json.loads((run.path / "timing.json").read_text())
    stats = json.loads((run.path / "slam_stats.json").read_text())
    per_frame = timing.get("per_frame_s") or []
    ate = ate_from_files(run.path / "trajectory.txt", seq.path / "groundtruth.txt")
    psnrs = [psnr(run.read_render(i), seq.sharp(i)) for i in range(0, frames, 5)
             if seq.sharp(i) is not None]
    return {"frames": frames, "fps": stats["fps"], "slam_wall_s": timing.get("total_wall_s"),
            "wall_with_output_s": round(wall, 1),
            "frame0_s": per_frame[0] if per_frame else None,
            "per_frame_s_median": float(np.median(per_frame[1:])) if len(per_frame) > 1
            else None,
            "per_frame_s": per_frame, "keyframes": stats["keyframes"],
            "tracking_iterations_mean": float(np.mean(stats["tracking_iterations"][1:]))
            if len(stats["tracking_iterations"]) > 1 else None,
            "gaussians": stats["gaussians"], "divergences": len(stats["divergences"]),
            "fps_after_frame0": (len(per_frame) - 1) / sum(per_frame[1:])
            if len(per_frame) > 1 else None,
            "ate_rmse_cm": 100 * ate.rmse, "psnr_db": float(np.mean(psnrs)) if psnrs else None,
            "preset": preset, "options": options or {}, "compile_s": timing.get("compile_s"),
            "work_per_frame_after_frame0": (stats.get("work") or {}).get("per_frame_after_init")}


def profile_mapping(method: str, seq: Sequence, views: int = 2, iters: int = 5) -> dict:
    """CUDA time per kernel of ``iters`` mapping iterations of ``method`` (paper preset) on the
    first ``views`` frames as keyframes at their true poses (after 3 warm-up iterations)."""
    import torch
    from torch.profiler import ProfilerActivity, profile

    from egs_bench.runs.registry import get_method
    from egs_bench.slam.system import SlamSystem

    sys.path.insert(0, str(ROOT / "benchmarks"))
    from bench_slam_overhead import keyframe_at_truth

    cfg = get_method(method).config("paper", seq.meta)  # type: ignore[attr-defined]
    system = SlamSystem(seq, cfg, device="cuda", seed=0)
    states, obs = {}, {}
    for i in range(views):
        states[i], obs[i] = keyframe_at_truth(system, seq, i, cfg.budget.pcd_downsample_init)
    window = list(range(views))[::-1]
    system.mapper.optimise(states, obs, window, window, 3)  # warm: allocations, autotuning
    torch.cuda.synchronize()
    with profile(activities=[ProfilerActivity.CPU, ProfilerActivity.CUDA]) as prof:
        system.mapper.optimise(states, obs, window, window, iters)
        torch.cuda.synchronize()
    rows = []
    for e in prof.key_averages():
        cuda_us = getattr(e, "device_time_total", None) or getattr(e, "cuda_time_total", 0)
        if cuda_us:
            rows.append({"name": e.key, "calls": e.count,
                         "cuda_ms_per_iter": cuda_us / 1e3 / iters})
    rows.sort(key=lambda r: -r["cuda_ms_per_iter"])
    return {"method": method, "views": views, "cameras": views * len(obs[0].fractions),
            "gaussians": len(system.gmap),
            "iterations": iters, "kernels": rows[:25],
            "cuda_ms_per_iter_total": sum(r["cuda_ms_per_iter"] for r in rows)}


def markdown_table(report: dict) -> str:
    """The runs of a check as the Markdown table of BENCHMARKS.md."""
    env, seq = report.get("environment", {}), report.get("sequence", {})
    lines = [f"{env.get('device', '?')}, torch {env.get('torch', '?')}, gsplat "
             f"{env.get('gsplat', '?')}; {seq.get('name', '?')} {seq.get('resolution', '')}, "
             f"first {seq.get('frames_used', '?')} frames, seed 0, "
             f"{report.get('date', '')}", "",
             "| method | preset | mapping | FPS | FPS after frame 0 | frame 0 s | per-frame s "
             "(median) | tracking iterations / frame | Mpixels / frame | ATE cm | PSNR dB |",
             "|:--|:--|:--|--:|--:|--:|--:|--:|--:|--:|--:|"]

    def num(value, digits: int) -> str:
        return "--" if value is None else f"{value:.{digits}f}"

    for key, r in report.get("runs", {}).items():
        parts = key.split("/")
        method, preset, schedule = parts if len(parts) == 3 else (parts[0], "paper", parts[1])
        if "skipped" in r:
            lines.append(f"| {method} | {preset} | {schedule} | not run ({r['skipped']}) "
                         "| | | | | | | |")
            continue
        work = r.get("work_per_frame_after_frame0") or {}
        mpix = work.get("pixels") / 1e6 if work.get("pixels") is not None else None
        lines.append(f"| {method} | {preset} | {schedule} | {num(r['fps'], 2)} "
                     f"| {num(r['fps_after_frame0'], 2)} | {num(r['frame0_s'], 1)} "
                     f"| {num(r['per_frame_s_median'], 2)} "
                     f"| {num(r['tracking_iterations_mean'], 1)} | {num(mpix, 2)} "
                     f"| {num(r['ate_rmse_cm'], 2)} | {num(r['psnr_db'], 2)} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seq", default="office1", help="448x256 built-in sequence (or folder)")
    ap.add_argument("--frames", type=int, default=40, help="frames per run")
    ap.add_argument("--runs", default=DEFAULT_RUNS,
                    help="PRESET[@SETTING][:MAPPING_MODE] entries to run each method with "
                         "(SETTING: one of benchmarks/sweeps/paper_levers.yaml)")
    ap.add_argument("--profile-views", type=int, default=2,
                    help="keyframes of the profiled mapping iteration (0: no profile)")
    ap.add_argument("--until-s", type=float, default=540.0,
                    help="start no run after this many seconds of the check")
    ap.add_argument("--methods", default="egs,monogs")
    ap.add_argument("--json", type=Path, default=Path("gpu_check.json"))
    ap.add_argument("--out", type=Path, default=Path("gpu_check_runs"),
                    help="run folders (replaced if they exist from an earlier check)")
    ap.add_argument("--skip-tests", action="store_true")
    ap.add_argument("--test-timeout", type=float, default=240.0)
    args = ap.parse_args(argv)
    report: dict = {"date": time.strftime("%Y-%m-%d %H:%M:%S"), "command": sys.argv}
    t_check = time.perf_counter()

    def save() -> None:
        args.json.write_text(json.dumps(report, indent=1) + "\n")

    with _timed(report, "environment"):
        report["environment"] = environment()
    print(f"[1/5] {report['environment']}", flush=True)
    with _timed(report, "gsplat_first_call"):
        build_gsplat()
    print(f"      gsplat ready after {report['seconds']['gsplat_first_call']} s", flush=True)
    save()
    if not args.skip_tests:
        with _timed(report, "cuda_tests"):
            report["cuda_tests"] = cuda_tests(args.test_timeout)
        print(f"[2/5] CUDA tests: {report['cuda_tests']['summary']}", flush=True)
        save()
    from egs_bench.datasets.registry import resolve_sequence
    from egs_bench.datasets.sequence import Sequence

    with _timed(report, "sequence"):
        seq = Sequence.open(resolve_sequence(args.seq, progress=False))
    frames = min(args.frames, len(seq))
    report["sequence"] = {"name": seq.name, "resolution": f"{seq.width}x{seq.height}",
                          "frames_used": frames}
    print(f"[3/5] sequence {seq.name} {seq.width}x{seq.height} "
          f"({report['seconds']['sequence']} s)", flush=True)
    report["runs"] = {}
    from egs_bench.runs.folder import RunFolder

    for method in args.methods.split(","):
        for entry in args.runs.split(","):
            import shutil

            label, preset, schedule, options = parse_run_entry(entry)
            key = f"{method}/{label}/{schedule}"
            out = args.out / method / label / schedule
            if time.perf_counter() - t_check > args.until_s:
                report["runs"][key] = {"skipped": f"past --until-s {args.until_s:.0f} s"}
                print(f"[4/5] {key}: not run (past --until-s)", flush=True)
                continue
            if out.exists():
                if not RunFolder.is_run_folder(out):
                    raise SystemExit(f"gpu_check: {out} exists and is not a run folder; "
                                     "choose another --out")
                shutil.rmtree(out)  # a run folder of an earlier check
            with _timed(report, f"run_{method}_{schedule}"):
                report["runs"][key] = r = run_method(method, seq, frames, out, schedule, preset,
                                                         options)
            print(f"[4/5] {key}: {r['fps']:.2f} FPS over {frames} frames "
                  f"({r['fps_after_frame0']:.2f} after frame 0; frame 0 {r['frame0_s']:.1f} s), "
                  f"ATE {r['ate_rmse_cm']:.2f} cm, PSNR {r['psnr_db']:.2f} dB, "
                  f"{r['tracking_iterations_mean']:.1f} tracking iterations/frame", flush=True)
            save()
            args.json.with_suffix(".md").write_text(markdown_table(report) + "\n")
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from bench_slam_overhead import measure

    with _timed(report, "overhead"):
        report["overhead"] = [measure(m, seq, "paper", "cuda", 20, 3)
                              for m in args.methods.split(",")]
    for r in report["overhead"]:
        for phase in ("tracking", "mapping"):
            p = r[phase]
            print(f"[5/5] {r['method']} {phase}: {p['ms_per_iter']:.2f} ms/iteration, "
                  f"{p['slam_ops']:.0f} SLAM-side ops, {p['slam_syncs']:.1f} syncs", flush=True)
    save()
    if args.profile_views > 0 and time.perf_counter() - t_check < args.until_s:
        report["profile"] = []
        for m in args.methods.split(","):
            try:
                with _timed(report, f"profile_{m}"):
                    report["profile"].append(profile_mapping(m, seq, args.profile_views))
                p = report["profile"][-1]
                top = ", ".join(f"{k['name'][:40]} {k['cuda_ms_per_iter']:.2f}"
                                for k in p["kernels"][:4])
                print(f"[6/6] {m} mapping iteration, {p['cameras']} cameras: "
                      f"{p['cuda_ms_per_iter_total']:.2f} ms CUDA; top: {top}", flush=True)
            except Exception as exc:  # a profile is diagnostics: keep the check's results
                report["profile"].append({"method": m, "error": repr(exc)})
            save()
    print(f"wrote {args.json}")
    return 0 if report.get("cuda_tests", {}).get("passed", True) else 1


if __name__ == "__main__":
    os.environ.setdefault("MPLBACKEND", "Agg")
    raise SystemExit(main())
