"""The report without a browser: what is collected (flagged runs and their reasons, a corrupt
metrics.json, provenance), the configuration diff against the method's preset, shared assets,
the pages' content, the output rules and the command on a run folder and a runs root."""

from __future__ import annotations

import json
import re
import shutil
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
import yaml

from egs_bench.cli import main
from egs_bench.datasets.sequence import Sequence
from egs_bench.errors import OutputError
from egs_bench.report import build_report, is_report_folder, write_side_report
from egs_bench.report.assets import AssetStore
from egs_bench.report.collect import collect_report
from egs_bench.report.config_diff import config_rows, preset_baseline
from egs_bench.report.overview import provenance
from egs_bench.runs.folder import RunFolder
from tests.helpers.sweep_fixtures import BAD, GOOD, GOOD_PATH, make_sequence


@pytest.fixture(scope="module")
def runs_root(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """good x 2 seeds, bad x 2 seeds on one sequence, a failed run, a corrupt metrics.json."""
    root = tmp_path_factory.mktemp("report")
    seq = Sequence.open(make_sequence(root / "data", "sa", 8, 0))
    runs = root / "runs"
    for method in (GOOD, BAD):
        for seed in (0, 1):
            method.run(seq, runs / "sa" / method.name / f"seed{seed}", seed=seed)
    failed = RunFolder.create(runs / "sa" / "good" / "seed2", method="good",
                              sequence_name="sa", sequence_path=seq.path,
                              config={"method": "good", "preset": "paper", "seed": 2,
                                      "device": "cpu", "frames": 8,
                                      "fake": {"noise_m": 0.01}})
    with pytest.raises(RuntimeError), failed.failure_guard():
        raise RuntimeError("injected crash at frame 4")
    BAD.run(seq, runs / "sa" / "bad" / "seed3", seed=3)
    (runs / "sa" / "bad" / "seed3" / "metrics.json").write_text("{not json")
    return runs


class _Page(HTMLParser):
    """Tables (id -> rows of cell texts), image sources and links of one page."""

    def __init__(self, path: Path) -> None:
        super().__init__()
        self.tables: dict[str, list[list[str]]] = {}
        self.images: list[str] = []
        self.links: list[str] = []
        self._table: str | None = None
        self._cell: list[str] | None = None
        self.feed(path.read_text())

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = dict(attrs)
        if tag == "table":
            self._table = a.get("id") or ""
            self.tables[self._table] = []
        elif tag == "tr" and self._table is not None:
            self.tables[self._table].append([])
        elif tag in ("td", "th") and self._table is not None:
            self._cell = []
        elif tag == "img" and "src" in a:  # the 3D view's panel gets its sources from its script
            self.images.append(a["src"] or "")
        elif tag == "a":
            self.links.append(a["href"] or "")

    def handle_endtag(self, tag: str) -> None:
        if tag in ("td", "th") and self._cell is not None and self._table is not None:
            self.tables[self._table][-1].append("".join(self._cell).strip())
            self._cell = None
        elif tag == "table":
            self._table = None

    def handle_data(self, data: str) -> None:
        if self._cell is not None:
            self._cell.append(data)


def test_collect_flags_failed_and_corrupt_runs_without_crashing(runs_root: Path) -> None:
    data = collect_report(runs_root)
    by_rel = {r.result.rel: r for r in data.runs}
    assert len(by_rel) == 6
    failed = by_rel["sa/good/seed2"]
    assert failed.flagged and failed.result.status == "failed"
    assert "injected crash at frame 4" in (failed.result.reason or "")
    corrupt = by_rel["sa/bad/seed3"]
    assert corrupt.flagged and corrupt.result.status == "broken"
    assert "metrics.json" in (corrupt.result.reason or "")
    assert not by_rel["sa/good/seed0"].flagged
    assert data.kind == "runs" and data.protocols == ["egs"]
    # the failed run's seed and the corrupt run do not enter the means
    board = data.boards["egs"]
    good = next(r for r in board.rows if r.method == "good")
    assert board.cells[(good, "sa")].stats["ate"].n == 2


def test_overview_lists_rows_flags_and_reasons(runs_root: Path, tmp_path: Path) -> None:
    result = build_report(runs_root, tmp_path / "rep")
    assert result.runs == 6 and result.flagged == 2 and result.sequences == 1
    page = _Page(result.index)
    board = page.tables["leaderboard-egs"]
    assert [row[0] for row in board[1:]] == ["bad", "good"]
    heads = board[0]
    ate = heads.index("sa ATE [cm] ↓")
    # good's noise is a third of bad's: its ATE is lower, and it is the bold one
    good_ate = float(board[2][ate].split(" ± ")[0])
    bad_ate = float(board[1][ate].split(" ± ")[0])
    assert good_ate < bad_ate
    assert re.search(r"<td[^>]*class=\"best num\"[^>]*><b>" + re.escape(board[2][ate]),
                     result.index.read_text())
    flagged = {row[0]: row for row in page.tables["flagged"][1:]}
    assert set(flagged) == {"sa/good/seed2", "sa/bad/seed3"}
    assert flagged["sa/good/seed2"][4] == "failed"
    assert "injected crash at frame 4" in flagged["sa/good/seed2"][5]
    assert "metrics.json" in flagged["sa/bad/seed3"][5]
    assert len(page.tables["runs"]) == 1 + 6
    for src in page.images:
        assert (result.out / src).is_file()
    for name in ("assets/report.css", "assets/report.js"):
        assert (result.out / name).is_file()
    assert is_report_folder(result.out)


def test_sequence_and_run_pages(runs_root: Path, tmp_path: Path) -> None:
    result = build_report(runs_root, tmp_path / "rep", frames=[2, 5])
    seq_page = _Page(result.out / "sequences" / "sa.html")
    # top view, per axis, ATE over time, PSNR over time, the image strip
    assert len(seq_page.images) == 5
    text = (result.out / "sequences" / "sa.html").read_text()
    assert "Image strip (frames 2, 5)" in text
    assert "48x32" in text  # the sequence's facts (resolution)
    # a shared report names no local folder: the sequence's path is relative to its page
    data_root = str(runs_root.parent.resolve())
    for page_file in (result.out / "sequences").iterdir():
        assert data_root not in page_file.read_text(), page_file
    rel = re.search(r"<dt>path</dt><dd>([^<]+)</dd>", text)
    assert rel is not None
    assert (result.out / "sequences" / rel.group(1)).resolve() == \
        (runs_root.parent / "data" / "sa").resolve()
    run_html = result.out / "runs" / "sa-good-seed0.html"
    page = _Page(run_html)
    # two plots, then per frame: observed, render, sharp GT
    assert len(page.images) == 2 + 2 * 3
    for src in page.images:
        assert (run_html.parent / src).resolve().is_file()
    targets = {(run_html.parent / href).resolve() for href in page.links
               if not href.endswith(".html")}
    run_dir = (runs_root / "sa" / "good" / "seed0").resolve()
    assert {run_dir / n for n in ("run.yaml", "config.yaml", "metrics.json", "trajectory.txt",
                                  "timing.json")} <= targets
    failed = (result.out / "runs" / "sa-good-seed2.html").read_text()
    assert re.search(r'class="flag" id="status">failed: .*injected crash at frame 4', failed)


def test_observed_and_sharp_thumbnails_are_shared_between_runs(runs_root: Path,
                                                               tmp_path: Path) -> None:
    result = build_report(runs_root, tmp_path / "rep", frames=[3])
    good = _Page(result.out / "runs" / "sa-good-seed0.html").images[-3:]
    bad = _Page(result.out / "runs" / "sa-bad-seed1.html").images[-3:]
    assert good[0] == bad[0] and good[2] == bad[2]  # observed, sharp GT: one file each
    assert good[1] != bad[1]  # the renders differ
    assert result.assets_reused > 0


def test_asset_store_downscales_and_dedups(tmp_path: Path) -> None:
    from egs_bench.images import read_ldr_image

    store = AssetStore(tmp_path)
    img = np.random.default_rng(0).integers(0, 255, (200, 640, 3), dtype=np.uint8)
    a = store.image(img, max_width=320)
    b = store.image(img.copy(), max_width=320)
    c = store.image(img[::-1].copy(), max_width=320)
    assert a == b != c
    assert store.written == 2 and store.reused == 1
    assert read_ldr_image(tmp_path / a).shape == (100, 320, 3)


def test_config_diff_highlights_only_what_differs_from_the_preset() -> None:
    from egs_bench.slam.methods import BUILTIN

    base = preset_baseline("egs", "cpu", {})
    assert base is not None
    changed = BUILTIN["egs"].with_options({"lambda_d": 0.05}).config("cpu")
    config = {"method": "egs", "preset": "cpu", "seed": 0, "slam": changed.to_dict()}
    rows = {r.key: r for r in config_rows(config, base)}
    assert [k for k, r in rows.items() if r.changed] == ["slam.loss.lambda_d"]
    assert rows["slam.loss.lambda_d"].value == 0.05
    assert rows["slam.loss.lambda_d"].preset == base["slam.loss.lambda_d"] != 0.05
    assert rows["seed"].compared is False
    # monogs' own settings are its preset, not changes; another preset's budget is a change
    monogs = {"slam": BUILTIN["monogs"].config("cpu").to_dict()}
    assert not any(r.changed for r in config_rows(monogs, preset_baseline("monogs", "cpu",
                                                                           {})))
    assert any(r.changed and r.key.startswith("slam.budget.")
               for r in config_rows(monogs, preset_baseline("monogs", "paper", {})))
    assert preset_baseline("good", "cpu", {}) is None  # not a built-in method


def test_run_page_marks_changed_config_rows(tmp_path: Path) -> None:
    """A run folder whose config.yaml changes one value of egs's cpu preset."""
    from egs_bench.slam.methods import BUILTIN

    seq = Sequence.open(make_sequence(tmp_path / "data", "sb", 6, 0))
    run = GOOD.run(seq, tmp_path / "runs" / "one")
    config = {"method": "egs", "preset": "cpu", "seed": 0, "device": "cpu", "frames": 6,
              "slam": BUILTIN["egs"].with_options({"tracking_iters": 7}).config(
                  "cpu").to_dict()}
    (run.path / "config.yaml").write_text(yaml.safe_dump(config))
    info = yaml.safe_load((run.path / "run.yaml").read_text())
    info["method"] = "egs"
    (run.path / "run.yaml").write_text(yaml.safe_dump(info))
    result = build_report(run.path, tmp_path / "rep")  # a single run folder
    html = next((result.out / "runs").glob("*.html")).read_text()
    changed = re.findall(r'<tr class="changed"><td>([^<]+)</td><td>([^<]+)</td>', html)
    assert changed == [("slam.budget.tracking_iters", "7")]
    assert "differ from egs&#39;s cpu preset" in html


def test_provenance_names_revision_machine_preset_and_seeds(runs_root: Path) -> None:
    data = collect_report(runs_root)
    items = dict(provenance(data))
    info = yaml.safe_load((runs_root / "sa/good/seed0/run.yaml").read_text())
    status = json.loads((runs_root / "sa/good/seed0/status.json").read_text())
    commit = (info.get("code") or {}).get("commit")
    assert (commit[:12] if commit else "not recorded") in items["Code revision (runs)"]
    assert status["host"] in items["Machine"]
    assert items["Preset"] == "paper"
    assert items["Seeds"] == "0, 1, 2, 3"
    assert items["Protocols"] == "egs"


def test_output_rules(runs_root: Path, tmp_path: Path) -> None:
    other = tmp_path / "mine"
    other.mkdir()
    (other / "notes.txt").write_text("keep me")
    with pytest.raises(OutputError, match="not an egs-bench report"):
        build_report(runs_root, other, overwrite=True)
    assert (other / "notes.txt").read_text() == "keep me"
    out = tmp_path / "rep"
    build_report(runs_root, out)
    with pytest.raises(OutputError, match="--overwrite"):
        build_report(runs_root, out)
    (out / "index.html").write_text("old")
    build_report(runs_root, out, overwrite=True)
    assert (out / "index.html").read_text() != "old"
    with pytest.raises(OutputError, match="input"):
        build_report(runs_root, runs_root, overwrite=True)
    # no staging folders left next to the report
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine", "rep"]


def test_side_report_warns_in_one_line_and_keeps_the_folder(runs_root: Path,
                                                             tmp_path: Path) -> None:
    other = tmp_path / "report"
    other.mkdir()
    (other / "notes.txt").write_text("keep me")
    said: list[str] = []
    assert write_side_report(runs_root, other, said.append) is None
    assert len(said) == 1 and said[0].startswith("warning: report not written")
    assert "\n" not in said[0]
    assert (other / "notes.txt").read_text() == "keep me"


def test_cli_on_a_run_folder_and_a_runs_root(runs_root: Path, tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["report", str(runs_root / "sa/bad/seed0"), "-o", str(tmp_path / "one")]) == 0
    assert len(list((tmp_path / "one" / "runs").glob("*.html"))) == 1
    assert main(["report", str(runs_root), "-o", str(tmp_path / "all"), "--no-eval"]) == 0
    assert "6 runs (2 flagged)" in capsys.readouterr().out
    assert main(["report", str(runs_root), "-o", str(tmp_path / "all")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error:") and "--overwrite" in err and "\n" not in err
    assert main(["report", str(tmp_path / "nothing"), "-o", str(tmp_path / "x")]) == 3
    assert main(["report", str(runs_root), "-o", str(tmp_path / "y"), "--frames", "a"]) == 2


def test_a_settings_axis_is_its_own_column_and_filter(tmp_path: Path) -> None:
    """Two settings of one method (as a sweep's ``settings`` makes them), two seeds each."""
    seq = Sequence.open(make_sequence(tmp_path / "data", "sc", 6, 0))
    for value in (0.05, 0.1):
        for seed in (0, 1):
            run = GOOD.run(seq, tmp_path / "runs" / f"d{value}" / f"seed{seed}", seed=seed)
            config = yaml.safe_load((run.path / "config.yaml").read_text())
            config["slam"] = {"loss": {"lambda_d": value}}
            (run.path / "config.yaml").write_text(yaml.safe_dump(config))
    result = build_report(tmp_path / "runs", tmp_path / "rep")
    page = _Page(result.index)
    board = page.tables["leaderboard-egs"]
    assert board[0][:2] == ["Method", "loss.lambda_d"]
    assert sorted(row[1] for row in board[1:]) == ["0.05", "0.1"]
    runs = page.tables["runs"]
    column = runs[0].index("loss.lambda_d")
    assert sorted(row[column] for row in runs[1:]) == ["0.05", "0.05", "0.1", "0.1"]
    html = result.index.read_text()
    assert re.search(r'<select data-axis="settings">.*lambda_d=0\.05.*lambda_d=0\.1', html)
    assert 'data-settings="loss.lambda_d=0.1"' in html


def test_demo_writes_its_report_and_a_foreign_folder_only_warns(tmp_path: Path) -> None:
    from egs_bench.demo import run_demo

    seq = make_sequence(tmp_path / "data", "sd", 6, 0)
    said: list[str] = []
    result = run_demo(tmp_path / "demo", sequence=str(seq), methods=(GOOD_PATH,),
                      say=said.append, progress=False)
    assert result.report is not None and result.report.runs == 1
    assert is_report_folder(tmp_path / "demo" / "report")
    again = run_demo(tmp_path / "demo", sequence=str(seq), methods=(GOOD_PATH,),
                     say=said.append, progress=False)
    assert again.report is not None  # its own earlier report is replaced
    foreign = tmp_path / "demo2" / "report"
    foreign.mkdir(parents=True)
    (foreign / "notes.txt").write_text("keep me")
    said.clear()
    third = run_demo(tmp_path / "demo2", sequence=str(seq), methods=(GOOD_PATH,),
                     say=said.append, progress=False)
    assert third.report is None and third.runs  # the runs are there, the report is not
    assert [s for s in said if s.startswith("warning: report not written")]
    assert (foreign / "notes.txt").read_text() == "keep me"


def test_run_page_plots_the_map_size_over_time(runs_root: Path, tmp_path: Path) -> None:
    """A run whose ``slam_stats.json`` has the map's size per frame (as the built-in SLAM
    runner writes it) gets a map-size plot; one without it does not."""
    root = tmp_path / "runs"
    shutil.copytree(runs_root / "sa" / "good" / "seed0", root / "sa" / "good" / "seed0")
    shutil.copytree(runs_root / "sa" / "good" / "seed1", root / "sa" / "good" / "seed1")
    (root / "sa" / "good" / "seed0" / "slam_stats.json").write_text(json.dumps(
        {"frames": 3, "gaussians": 130, "gaussians_per_frame": [100, 120, 130],
         "divergences": [], "tracking_iterations": [0, 20, 20]}))
    result = build_report(root, tmp_path / "rep")
    with_sizes = (result.out / "runs" / "sa-good-seed0.html").read_text()
    without = (result.out / "runs" / "sa-good-seed1.html").read_text()
    assert "Map size over time" in with_sizes and "Map size over time" not in without
    assert len(_Page(result.out / "runs" / "sa-good-seed0.html").images) == \
        len(_Page(result.out / "runs" / "sa-good-seed1.html").images) + 1


def test_run_page_shows_the_work_and_the_timing_split(runs_root: Path, tmp_path: Path) -> None:
    """A run with slam_stats.json's ``work`` and timing.json's compile / frame-0 split shows
    both on its page (the counts as ``egs-bench info`` prints them)."""
    from egs_bench.runs.summary import work_lines

    root = tmp_path / "runs"
    run = root / "sa" / "good" / "seed0"
    shutil.copytree(runs_root / "sa" / "good" / "seed0", run)
    counts = {"calls": 40, "cameras": 160, "pixels": 1_146_880, "isects": 10,
              "blends_fwd": 12_345_678, "blends_bwd": 12_000_000}
    work = {"per_frame_after_init": counts, "by_phase": {"tracking": counts}}
    (run / "slam_stats.json").write_text(json.dumps(
        {"frames": 3, "gaussians": 130, "divergences": [], "tracking_iterations": [0, 20, 20],
         "work": work}))
    (run / "timing.json").write_text(json.dumps(
        {"total_wall_s": 6.0, "per_frame_s": [4.0, 1.0, 1.0], "render_fps": 30.0,
         "compile_s": 12.5}))
    result = build_report(root, tmp_path / "rep")
    page = (result.out / "runs" / "sa-good-seed0.html").read_text()
    for label, text in work_lines(work).items():
        assert label in page and text in page
    assert "12.35 M blends forward" in page
    assert "12.5" in page and "FPS after frame 0" in page and "map initialisation" in page
