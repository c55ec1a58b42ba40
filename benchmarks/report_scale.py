"""Size and load time of a 100-run HTML report (targets: overview < 2 s to load, at most 2 MB
more per run with a 50k-Gaussian map, a run page's 3D view interactive within 3 s).

Builds a runs root of ``--methods`` x ``--sequences`` x ``--seeds`` imported runs
(:func:`egs_bench.interop.importing.import_tum_run`, what ``egs-bench import-run`` does):
each estimate is the ground truth plus seeded position noise, each render the sharp frame plus
seeded noise, so the runs are evaluated like real ones (ATE, PSNR, SSIM, LPIPS when its weights
are available); each run gets a ``map.ply`` of ``--gaussians`` seeded random Gaussians around
its trajectory (the 3D view's size and load time depend on the count, not on the content).
Then writes the report, measures its size on disk and opens its pages in headless Chromium:
the load time is navigation start to the end of the load event (Navigation Timing), the
median of ``--loads`` fresh loads of each page; a run page is interactive when its 3D view has
built the map and sorted it for the first view (navigation start to that moment).

    python benchmarks/report_scale.py --work /tmp/report_scale           # 5 x 2 x 10 = 100 runs
    python benchmarks/report_scale.py --screenshots REPORT_DIR docs/images  # the docs' images

Also the module the browser test drives Chromium with (:func:`open_chromium`): Debian's
``chromium`` through Debian's ``chromium-driver`` and selenium (see tests/report).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import shutil
import statistics
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

CHROMIUM = Path("/usr/bin/chromium")
CHROMEDRIVER = Path("/usr/bin/chromedriver")
#: WebGL on the CPU, the same on every machine: SwiftShader through ANGLE, opted into (without
#: it Chromium falls back to it with a deprecation warning), one device pixel per CSS pixel,
#: no GPU process rasterisation.
WEBGL_FLAGS = ("--use-angle=swiftshader", "--enable-unsafe-swiftshader",
               "--force-device-scale-factor=1", "--disable-gpu-rasterization")


def chromium_missing() -> str | None:
    """Why headless Chromium cannot be driven here, or ``None`` when it can."""
    try:
        import selenium  # noqa: F401
    except ImportError:
        return "selenium is not installed (pip install -e '.[dev]')"
    for path, package in ((CHROMIUM, "chromium"), (CHROMEDRIVER, "chromium-driver")):
        if not path.is_file():
            return f"{path} not found (apt-get install -y {package}; `make setup-browser`)"
    return None


@contextlib.contextmanager
def open_chromium(width: int = 1400, height: int = 1000,
                  file_access: bool = True) -> Iterator[Any]:
    """A headless Chromium (selenium WebDriver) that records the page's console messages
    (``driver.get_log("browser")``).

    Args:
        file_access: let ``file://`` pages read other local files (as a browser started with
            ``--allow-file-access-from-files``); False behaves as a user's browser does.
    """
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = str(CHROMIUM)
    for arg in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage",
                f"--window-size={width},{height}", *WEBGL_FLAGS):
        options.add_argument(arg)
    if file_access:
        options.add_argument("--allow-file-access-from-files")
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(str(CHROMEDRIVER)), options=options)
    try:
        yield driver
    finally:
        driver.quit()


def load_ms(driver: Any, page: Path) -> float:
    """Navigation start to the end of the load event of one fresh load of ``page``, ms."""
    driver.get("about:blank")
    driver.get(page.resolve().as_uri())
    for _ in range(200):  # get() returns after the load event; its end may lag a tick
        end = driver.execute_script(
            "const n = performance.getEntriesByType('navigation')[0];"
            "return n ? n.loadEventEnd - n.startTime : 0;")
        if end > 0:
            return float(end)
        time.sleep(0.01)
    raise RuntimeError(f"{page}: no load event")


def wait_view(driver: Any, timeout_s: float = 60.0) -> float:
    """Wait until the page's 3D view has built its map and finished sorting for its camera;
    returns the seconds waited. WebGL on SwiftShader needs real time (a virtual time budget
    shows a black canvas)."""
    from selenium.webdriver.support.ui import WebDriverWait

    t = time.perf_counter()
    WebDriverWait(driver, timeout_s, poll_frequency=0.02).until(lambda d: d.execute_script(
        "const v = window.EgsViewer && EgsViewer.views[0]; return Boolean(v && v.settled());"))
    return time.perf_counter() - t


def view_image(driver: Any) -> np.ndarray:
    """The 3D view's canvas as uint8 [H, W, 3] RGB, rendered at the moment of the call."""
    import base64

    import cv2

    url = driver.execute_script("return EgsViewer.views[0].capture();")
    png = np.frombuffer(base64.b64decode(url.split(",", 1)[1]), np.uint8)
    return np.ascontiguousarray(cv2.imdecode(png, cv2.IMREAD_COLOR)[:, :, ::-1])


def write_random_map(run_dir: Path, centres: np.ndarray, count: int, seed: int) -> None:
    """A ``map.ply`` of ``count`` random Gaussians within 2 m of the positions ``centres``
    [M, 3] (linear colours, log scales around 1 cm, random rotations and opacities)."""
    import torch

    from egs_bench.render.gaussian_map import GaussianMap
    from egs_bench.render.ply import save_ply
    from egs_bench.slam.appearance import MAP_FILE

    rng = np.random.default_rng(seed)
    around = centres[rng.integers(0, len(centres), count)] + rng.uniform(-2, 2, (count, 3))

    def t(x: np.ndarray) -> torch.Tensor:
        return torch.tensor(x, dtype=torch.float32)

    gmap = GaussianMap(t(around), t(rng.normal(size=(count, 4))),
                       t(rng.normal(np.log(0.01), 0.5, (count, 3))), t(rng.normal(0, 2, count)),
                       t(rng.uniform(0, 1, (count, 3))))
    save_ply(gmap, run_dir / MAP_FILE)


def make_runs(work: Path, methods: int, sequences: int, seeds: int, frames: int,
              gaussians: int = 0) -> Path:
    """``methods x sequences x seeds`` imported, evaluated runs under ``work/runs`` on small
    synthetic sequences (generated into ``work/data``), each with a ``gaussians``-Gaussian map
    (none for 0)."""
    from egs_bench.datasets.sequence import Sequence
    from egs_bench.datasets.synthetic import make_synthetic
    from egs_bench.eval.evaluate import evaluate_run
    from egs_bench.geometry import write_tum
    from egs_bench.images import write_ldr_image
    from egs_bench.interop.importing import import_tum_run

    runs = work / "runs"
    scenes = ["office", "livingroom", "studio", "corridor"]
    for s in range(sequences):
        path = work / "data" / f"seq{s}"
        if not (path / "meta.yaml").is_file():
            make_synthetic(scenes[s % len(scenes)], path, frames=frames, width=224, height=128,
                           speed=0.4, seed=20 + s, exposure_ms=25.0, progress=False)
        seq = Sequence.open(path)
        for m in range(methods):
            for seed in range(seeds):
                rng = np.random.default_rng(1000 * m + seed)
                est = np.asarray(seq.poses).copy()
                est[:, :3, 3] += rng.normal(0.0, 0.005 * (m + 1), (len(seq), 3))
                # one source path per method: the import records it in config.yaml, and runs
                # of one method with different settings would be different leaderboard rows
                src = work / "src" / f"m{m}"
                shutil.rmtree(src / "renders", ignore_errors=True)
                (src / "renders").mkdir(parents=True)
                write_tum(src / "traj.txt", np.asarray(seq.timestamps_s), est)
                for i in range(len(seq)):
                    noisy = seq.sharp(i).astype(float) + rng.normal(0, 3.0 * (m + 1),
                                                                    seq.sharp(i).shape)
                    write_ldr_image(src / "renders" / f"{i}.png",
                                    np.clip(noisy, 0, 255).astype(np.uint8))
                run = import_tum_run(src / "traj.txt",
                                     runs / f"seq{s}" / f"method{m}" / f"seed{seed}",
                                     method=f"method{m}", sequence_name=f"seq{s}",
                                     sequence_path=path, renders_dir=src / "renders")
                if gaussians:
                    write_random_map(run.path, est[:, :3, 3], gaussians, 1000 * m + seed)
                evaluate_run(run.path)  # before the report: its build time is its own
    shutil.rmtree(work / "src", ignore_errors=True)
    return runs


def folder_mb(path: Path) -> float:
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file()) / 1e6


def static_mb(report: Path) -> float:
    """Size of the report's shared static files (style, scripts, the 3D viewer), MB."""
    from egs_bench.report.assets import ASSETS_DIR, STATIC_FILES

    return sum((report / ASSETS_DIR / name).stat().st_size for name in STATIC_FILES) / 1e6


def interactive_ms(driver: Any, page: Path) -> float:
    """Navigation start to the moment the page's 3D view is ready (map built, first sort
    done), ms, for one fresh load of ``page``."""
    driver.get("about:blank")
    driver.get(page.resolve().as_uri())
    wait_view(driver)
    return float(driver.execute_script("return performance.now();"))


def measure(report: Path, loads: int) -> dict[str, float]:
    """Median load time [ms] of the overview, the first sequence page and the first run page,
    and the median time until that run page's 3D view is interactive."""
    pages = {"index": report / "index.html",
             "sequence": sorted((report / "sequences").glob("*.html"))[0],
             "run": sorted((report / "runs").glob("*.html"))[0]}
    out = {}
    with open_chromium() as driver:
        for name, page in pages.items():
            out[f"{name}_load_ms_median"] = statistics.median(load_ms(driver, page)
                                                              for _ in range(loads))
        out["run_view_interactive_ms_median"] = statistics.median(
            interactive_ms(driver, pages["run"]) for _ in range(loads))
    return out


def screenshots(report: Path, out: Path) -> list[Path]:
    """Screenshots, 1280 px wide, of the overview and the first sequence page (tall enough
    for its figures and image strip) as ``report_overview.png`` and ``report_sequence.png``;
    of the 3D view of the first run page with a map, at the frame with stored images nearest
    its middle and 3x size
    (``report_run_view.png``), and of the first sequence page's 3D view
    (``report_sequence_view.png``)."""
    from selenium.webdriver.common.by import By

    sequence = sorted((report / "sequences").glob("*.html"))[0]
    pages = [(report / "index.html", out / "report_overview.png", 1400),
             (sequence, out / "report_sequence.png", 2300)]
    for page, png, height in pages:
        with open_chromium(1280, height) as driver:
            driver.get(page.resolve().as_uri())
            driver.save_screenshot(str(png))
    run = next(p for p in sorted((report / "runs").glob("*.html"))
               if "egs-view-canvas" in p.read_text())
    views = [(run, out / "report_run_view.png"), (sequence, out / "report_sequence_view.png")]
    with open_chromium(1400, 1400) as driver:
        for page, png in views:
            driver.get(page.resolve().as_uri())
            wait_view(driver)
            if page == run:
                # at the middle frame's pose, then a step back to show its frustum and the
                # trajectories
                driver.execute_script(
                    "const v = EgsViewer.views[0]; v.setScale(3);"
                    "const mid = v.data.frames[Math.floor(v.data.frames.length / 2)];"
                    "v.setFrame(mid.images_from ?? v.data.frames.indexOf(mid));"
                    "v.setMode('orbit');"
                    "v.camera.translateZ(0.6 * v.orbitRadius);"
                    "v.camera.translateY(0.2 * v.orbitRadius);"
                    "v.controls.update(); v.requestRender();")
                wait_view(driver)
            driver.find_element(By.CSS_SELECTOR, ".egs-view").screenshot(str(png))
    return [p for _, p, _ in pages] + [p for _, p in views]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--work", type=Path, default=Path("bench_out/report_scale"))
    parser.add_argument("--methods", type=int, default=5)
    parser.add_argument("--sequences", type=int, default=2)
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--frames", type=int, default=40)
    parser.add_argument("--gaussians", type=int, default=50_000,
                        help="Gaussians in each run's map (0: no maps)")
    parser.add_argument("--loads", type=int, default=7)
    parser.add_argument("--screenshots", nargs=2, type=Path, metavar=("REPORT", "OUT_DIR"),
                        help="only take the docs' screenshots of an existing report")
    args = parser.parse_args()
    if args.screenshots:
        for path in screenshots(*args.screenshots):
            print(f"wrote {path}")
        return
    from egs_bench.report import build_report

    missing = chromium_missing()
    if missing:
        raise SystemExit(f"cannot measure load times: {missing}")
    runs = args.work / "runs"
    t = time.perf_counter()
    if not runs.is_dir():
        make_runs(args.work, args.methods, args.sequences, args.seeds, args.frames,
                  args.gaussians)
    made_s = time.perf_counter() - t
    report = args.work / "report"
    t = time.perf_counter()
    result = build_report(runs, report, overwrite=report.exists())
    build_s = time.perf_counter() - t
    numbers = {"runs": result.runs, "sequences": result.sequences, "frames": args.frames,
               "make_and_evaluate_runs_s": round(made_s, 1), "build_report_s": round(build_s, 1),
               "gaussians_per_map": args.gaussians,
               "report_mb": round(folder_mb(report), 2),
               # what each run adds: everything but the shared style, scripts and viewer
               "mb_per_run": round((folder_mb(report) - static_mb(report)) / result.runs, 3),
               "assets_written": result.assets_written, "assets_reused": result.assets_reused,
               **{k: round(v, 1) for k, v in measure(report, args.loads).items()}}
    print(json.dumps(numbers, indent=1))


if __name__ == "__main__":
    main()
