"""The report of a small real sweep, opened in headless Chromium.

2 methods (egs, monogs) x 1 built-in sequence (``demo``'s scene, motion and camera, cut to 3
frames) x 2 seeds, cpu preset with a few iterations, plus one run that failed (marked by the
run folder's own failure guard). The page must load without console errors, list the expected
leaderboard rows, reorder them when a column header is clicked, load every image and plot,
and flag the failed run with its reason.

The run page's 3D view is checked against the toolkit's own renderer: through the page's frame
slider the view's camera goes to each frame's estimated pose, and the canvas, at the run's
resolution, must match ``egs-bench render-map RUN --frame I`` (display space) at
:data:`VIEW_PSNR_DB` or more, while the same check on a view with a planted convention error
(the y axis flipped) must fail by at least :data:`PLANTED_MARGIN_DB`.

Driver: selenium with Debian's ``chromium-driver``, because the driver comes from the same
Debian release as the ``chromium`` it drives (no version mismatch, nothing downloaded), while
playwright pins its own browser build and would need ``playwright install``.
"""

from __future__ import annotations

import dataclasses
import json
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from egs_bench.cli import main
from tests.helpers.bench_scripts import load_script
from tests.helpers.sweep_fixtures import worker_env

scale = load_script("report_scale")

#: The view against ``render-map`` at the same pose: the least PSNR accepted, dB.
VIEW_PSNR_DB = 25.0
#: How far below the correct view a planted convention error must score, dB.
PLANTED_MARGIN_DB = 10.0


@pytest.fixture(scope="module")
def chromium() -> Iterator[Any]:
    missing = scale.chromium_missing()
    if missing:
        pytest.skip(f"headless Chromium unavailable: {missing}")
    with scale.open_chromium() as driver:
        yield driver


@pytest.fixture(scope="module")
def sweep_out(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from egs_bench.datasets.registry import BUILTIN_SEQUENCES
    from egs_bench.datasets.synthetic import make_synthetic
    from egs_bench.experiments.spec import load_sweep
    from egs_bench.experiments.sweep import run_sweep
    from egs_bench.runs.folder import RunFolder

    root = tmp_path_factory.mktemp("browser")
    with pytest.MonkeyPatch.context() as mp:
        worker_env(mp)
        settings = dataclasses.asdict(BUILTIN_SEQUENCES["demo"])
        settings.pop("description")
        seq = make_synthetic(out=root / "data" / "demo", progress=False,
                             **{**settings, "frames": 3})
        sweep = root / "s.yaml"
        sweep.write_text(yaml.safe_dump({
            "methods": ["egs", "monogs"], "sequences": [str(seq)], "seeds": [0, 1],
            "preset": "cpu", "device": "cpu", "protocol": "egs", "out": str(root / "out"),
            "set": {"init_iters": 4, "tracking_iters": 3, "mapping_iters": 2},
            "local": {"jobs": 2}}))
        said: list[str] = []
        report = run_sweep(load_sweep(sweep), say=said.append)
    assert report.all_done, report.summary_md
    out = root / "out"
    assert any(line.startswith("report: ") for line in said), said
    assert (out / "report" / "index.html").is_file()
    # a third egs seed that crashed, marked failed the way every run is
    good = out / "runs" / "demo" / "egs" / "seed0"
    config = yaml.safe_load((good / "config.yaml").read_text())
    failed = RunFolder.create(out / "runs" / "demo" / "egs" / "seed7", method="egs",
                              sequence_name="demo", sequence_path=seq,
                              config={**config, "seed": 7})
    with pytest.raises(RuntimeError), failed.failure_guard():
        raise RuntimeError("injected: out of memory at frame 2")
    assert main(["report", str(out), "-o", str(out / "report"), "--overwrite"]) == 0
    return out


def _errors(driver: Any) -> list[dict]:  # selenium WebDriver
    return [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]


def _images(driver: Any) -> list[tuple[str, bool, int]]:
    """``(src, complete, naturalWidth)`` of the page's shown images (the 3D view's panel
    hides the images a frame does not have)."""
    return [tuple(x) for x in driver.execute_script(
        "return Array.from(document.images).filter(i => !i.hidden)"
        ".map(i => [i.src, i.complete, i.naturalWidth]);")]


def _column(driver: Any, table: str, index: int) -> list[str]:
    return driver.execute_script(
        "return Array.from(document.querySelectorAll(arguments[0] + ' tbody tr'))"
        ".filter(r => !r.hidden).map(r => r.cells[arguments[1]].textContent.trim());",
        table, index)


@pytest.mark.slow
def test_report_of_a_real_sweep_in_chromium(sweep_out: Path, chromium: Any) -> None:
    from selenium.webdriver.common.by import By

    report = sweep_out / "report"
    chromium.get((report / "index.html").resolve().as_uri())
    assert _errors(chromium) == []
    heads = [th.text for th in chromium.find_elements(By.CSS_SELECTOR,
                                                      "#leaderboard-egs thead th")]
    assert _column(chromium, "#leaderboard-egs", 0) == ["egs", "monogs"]

    # sorting by a metric column orders the rows by its values, a second click reverses them
    # (on the first metric whose two values differ as shown: equal ones keep their order)
    def shown(col: int) -> list[float]:
        return [float(v.split(" ± ")[0]) for v in _column(chromium, "#leaderboard-egs", col)]

    # (3 frames of 3 tracking iterations leave both methods near the motion prior: their ATE
    # and PSNR may agree to the digits shown; their FPS does not)
    metrics = [heads.index(h) for h in ("demo ATE [cm] ↓", "demo PSNR [dB] ↑", "demo FPS ↑")]
    col = next((c for c in metrics if len(set(shown(c))) > 1), None)
    assert col is not None, "the fixture's methods differ in no metric shown"
    header = chromium.find_elements(By.CSS_SELECTOR, "#leaderboard-egs thead th")[col]
    header.click()
    first = shown(col)
    assert first in (sorted(first), sorted(first, reverse=True))
    order = _column(chromium, "#leaderboard-egs", 0)
    header.click()
    assert shown(col) == first[::-1]
    assert _column(chromium, "#leaderboard-egs", 0) == order[::-1]
    seeds = chromium.find_elements(By.CSS_SELECTOR, "#runs thead th")[3]
    seeds.click()
    seeds.click()
    assert _column(chromium, "#runs", 3) == ["7", "1", "1", "0", "0"]

    # the failed run is flagged with its reason
    flagged = chromium.find_elements(By.CSS_SELECTOR, "#flagged tbody tr")
    assert len(flagged) == 1
    cells = [td.text for td in flagged[0].find_elements(By.TAG_NAME, "td")]
    assert cells[0] == "runs/demo/egs/seed7" and cells[4] == "failed"
    assert "injected: out of memory at frame 2" in cells[5]
    assert "flag" in flagged[0].get_attribute("class")

    # the method filter hides the other method's rows
    chromium.execute_script("const s = document.querySelector('select[data-axis=method]');"
                            "s.value = 'monogs'; s.dispatchEvent(new Event('change'));")
    assert _column(chromium, "#leaderboard-egs", 0) == ["monogs"]
    assert set(_column(chromium, "#runs", 1)) == {"monogs"}

    # every page: no console error, every image and plot loaded
    pages = [report / "index.html", *sorted((report / "sequences").glob("*.html")),
             *sorted((report / "runs").glob("*.html"))]
    assert len(pages) == 1 + 1 + 5
    counts = {}
    for page in pages:
        chromium.get(page.resolve().as_uri())
        assert _errors(chromium) == [], page
        images = _images(chromium)
        assert all(complete and width > 0 for _, complete, width in images), (page, images)
        counts[page.name] = len(images)
    assert counts["demo.html"] == 5  # top view, per axis, ATE, PSNR, image strip
    assert counts["runs-demo-egs-seed0.html"] >= 2 + 3  # ATE, timing, thumbnails
    chromium.get((report / "runs" / "runs-demo-egs-seed7.html").resolve().as_uri())
    status = chromium.find_element(By.ID, "status")
    assert "flag" in status.get_attribute("class")
    assert "injected: out of memory at frame 2" in status.text
    manifest = json.loads((report / "report.json").read_text())
    assert manifest["runs"] == 5 and manifest["kind"] == "sweep"


def _slide_to(driver: Any, position: int) -> None:
    """Move the run view's frame slider the way a user does (an ``input`` event)."""
    driver.execute_script(
        "const s = document.querySelector('input.egs-view-frame'); s.value = arguments[0];"
        "s.dispatchEvent(new Event('input'));", position)


def _view_psnrs(driver: Any, run: Path, frames: list[int], out: Path,
                views: list[np.ndarray] | None = None) -> list[float]:
    """PSNR [dB] of the 3D view at each frame (set through the slider) against
    ``render-map RUN --frame I``; the view's images are appended to ``views``."""
    from egs_bench.eval.image_metrics import psnr
    from egs_bench.images import read_ldr_image

    values = []
    for position, frame in enumerate(frames):
        _slide_to(driver, position)
        scale.wait_view(driver)
        view = scale.view_image(driver)
        if views is not None:
            views.append(view)
        png = out / f"render-map-{frame}.png"
        assert main(["render-map", str(run), "--frame", str(frame), "-o", str(png),
                     "--overwrite"]) == 0
        ref = read_ldr_image(png)
        assert view.shape == ref.shape, (view.shape, ref.shape)
        values.append(psnr(view, ref))
    return values


@pytest.mark.slow
def test_run_view_matches_render_map(sweep_out: Path, chromium: Any, tmp_path: Path) -> None:
    from selenium.webdriver.common.by import By

    from egs_bench.images import read_ldr_image
    from egs_bench.render.ply import read_ply
    from egs_bench.runs.folder import RunFolder

    run_dir = sweep_out / "runs" / "demo" / "egs" / "seed0"
    run = RunFolder.open(run_dir)
    report = sweep_out / "report"
    chromium.get((report / "runs" / "runs-demo-egs-seed0.html").resolve().as_uri())
    scale.wait_view(chromium)
    assert _errors(chromium) == []
    assert chromium.execute_script("return location.protocol") == "file:"

    # the scene holds the run's map, both trajectories and one frustum per keyframe
    counts = chromium.execute_script("return EgsViewer.views[0].sceneCounts;")
    keyframes = run.read_keyframes()
    assert keyframes is not None and len(keyframes) > 0
    gmap, _ = read_ply(run_dir / "map.ply")
    assert counts == {"splats": len(gmap), "trajectories": 2, "frusta": len(keyframes)}
    data = chromium.execute_script("return window.EGS_VIEW;")
    traj = run.read_trajectory()
    assert len(data["est"]) == len(traj) == len(data["frames"])
    frames = [f["index"] for f in data["frames"]]
    assert frames == [0, 1, 2]

    # the slider moves the camera to the frame's estimated pose; the panel shows that frame
    for position, frame in enumerate(frames):
        _slide_to(chromium, position)
        camera = chromium.execute_script(
            "return EgsViewer.views[0].camera.position.toArray();")
        assert camera == pytest.approx(traj.poses[position][:3, 3], abs=1e-5)
        panel = chromium.find_element(By.CSS_SELECTOR, ".egs-view-images")
        assert panel.get_attribute("data-frame") == str(frame)
        assert panel.find_element(By.CSS_SELECTOR, ".egs-view-image-frame").text == \
            f"frame {frame}"
        shown = chromium.execute_script(
            "return document.querySelector('img.egs-view-render').getAttribute('src');")
        assert (read_ldr_image((report / "runs" / shown).resolve())
                == run.read_render(frame)).all()
    chromium.execute_script("EgsViewer.views[0].setScale(1);")
    # only the map is compared: the trajectories and frusta are switched off as a user does
    for box in chromium.find_elements(By.CSS_SELECTOR, "input.egs-view-toggle"):
        if box.get_attribute("data-what") != "map":
            box.click()
            assert not box.is_selected()
    views: list[np.ndarray] = []
    correct = _view_psnrs(chromium, run_dir, frames, tmp_path, views)
    # SwiftShader (report_scale.WEBGL_FLAGS) draws the same pixels on a fresh load
    chromium.get((report / "runs" / "runs-demo-egs-seed0.html").resolve().as_uri())
    scale.wait_view(chromium)
    chromium.execute_script("EgsViewer.views[0].setScale(1);")
    for box in chromium.find_elements(By.CSS_SELECTOR, "input.egs-view-toggle"):
        if box.get_attribute("data-what") != "map":
            box.click()
    scale.wait_view(chromium)
    assert (scale.view_image(chromium) == views[0]).all()
    chromium.execute_script("EgsViewer.views[0].setPlantedError('flip-y');")
    planted = _view_psnrs(chromium, run_dir, frames, tmp_path)
    print(f"view against render-map, PSNR [dB]: {correct}; with the y axis flipped: {planted}")
    assert min(correct) >= VIEW_PSNR_DB, correct
    # the check catches a convention error: it fails on every frame, by a wide margin
    assert max(planted) < VIEW_PSNR_DB, planted
    assert all(c - p >= PLANTED_MARGIN_DB for c, p in zip(correct, planted, strict=True))
    assert _errors(chromium) == []

    # fly: W moves the camera forward (along its optical axis); orbit: a drag turns it
    from selenium.webdriver.common.action_chains import ActionChains

    chromium.execute_script("EgsViewer.views[0].setPlantedError(null);")
    _slide_to(chromium, 0)
    camera_position = "return EgsViewer.views[0].camera.position.toArray();"
    before = np.array(chromium.execute_script(camera_position))
    canvas = chromium.find_element(By.CSS_SELECTOR, "canvas.egs-view-canvas")
    chromium.find_element(By.CSS_SELECTOR, "button.egs-view-fly").click()
    # Held until the camera has moved 5 cm (at most 10 s): the viewer moves it in its
    # animation-frame loop, which a busy machine may not run within a fixed half second.
    ActionChains(chromium).move_to_element(canvas).click().key_down("w").perform()
    deadline = time.monotonic() + 10.0
    step = np.zeros(3)
    while np.linalg.norm(step) <= 0.05 and time.monotonic() < deadline:
        time.sleep(0.1)
        step = np.array(chromium.execute_script(camera_position)) - before
    ActionChains(chromium).key_up("w").perform()
    forward = traj.poses[0][:3, 2]
    assert np.linalg.norm(step) > 0.05 and step @ forward > 0.9 * np.linalg.norm(step)
    chromium.find_element(By.CSS_SELECTOR, "button.egs-view-orbit").click()
    turn = "return EgsViewer.views[0].camera.quaternion.toArray();"
    q0 = np.array(chromium.execute_script(turn))
    ActionChains(chromium).move_to_element(canvas).click_and_hold().move_by_offset(60, 0) \
        .release().perform()
    assert abs(float(np.array(chromium.execute_script(turn)) @ q0)) < 0.9999
    assert _errors(chromium) == []


@pytest.mark.slow
def test_sequence_view_toggles_each_trajectory(sweep_out: Path, chromium: Any) -> None:
    from selenium.webdriver.common.by import By

    page = sweep_out / "report" / "sequences" / "demo.html"
    chromium.get(page.resolve().as_uri())
    scale.wait_view(chromium)
    assert _errors(chromium) == []
    data = chromium.execute_script("return window.EGS_VIEW;")
    labels = [r["label"] for r in data["runs"]]
    assert sorted(labels) == ["egs", "monogs"]
    assert chromium.execute_script("return EgsViewer.views[0].sceneCounts;") == \
        {"trajectories": len(labels) + 1}
    boxes = chromium.find_elements(By.CSS_SELECTOR, "input.egs-view-toggle")
    assert len(boxes) == len(labels) + 1
    boxes[0].click()
    visible = chromium.execute_script(
        "const v = EgsViewer.views[0]; return v.lines.map(g => g.visible).concat([v.gt.visible]);")
    assert visible == [False, True, True]
