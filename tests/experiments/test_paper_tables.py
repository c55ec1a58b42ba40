"""Paper-layout tables: ablation rows found from configurations, check marks, mean +- std,
ranks, Markdown and LaTeX (compiled with pdflatex where installed), the CLI."""

import json
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from egs_bench.cli import main
from egs_bench.experiments.paper_tables import (
    build_tables,
    render_latex,
    render_markdown,
)
from egs_bench.runs.folder import RunFolder
from tests.helpers.cli import assert_cli_error

BASE_SLAM = {"event_tracking": True, "event_mapping": True, "crf": "learnable",
             "blur_model": True, "lambda_d": 0.1}
METHODS: dict[str, dict[str, Any]] = {
    "egs": {},
    "egs-no-event-tracking": {"event_tracking": False},
    "egs-no-event-mapping": {"event_mapping": False},
    "egs-no-events": {"event_tracking": False, "event_mapping": False},
    "egs-no-crf": {"crf": "identity"},
    # same flags as egs-no-events but other settings too: not part of the ablation
    "monogs": {"event_tracking": False, "event_mapping": False, "blur_model": False,
               "crf": "identity"},
}
ATE_CM = {"egs": 1.0, "egs-no-event-tracking": 3.0, "egs-no-event-mapping": 1.5,
          "egs-no-events": 4.0, "egs-no-crf": 1.2, "monogs": 5.0, "monogs-edi": 6.0}


def _runs(root: Path, methods: dict[str, dict[str, Any]] = METHODS,
          seqs: tuple[str, ...] = ("room0", "office1"), seeds: tuple[int, ...] = (0, 1)) -> Path:
    for m, changes in methods.items():
        for si, seq in enumerate(seqs):
            for seed in seeds:
                flat = {**BASE_SLAM, **changes}  # config.yaml's nested layout
                cfg = {"method": m, "preset": "cpu", "seed": seed, "frames": 40,
                       "slam": {"method": {k: v for k, v in flat.items() if k != "lambda_d"},
                                "loss": {"lambda_d": flat["lambda_d"]}}}
                run = RunFolder.create(root / seq / m / f"seed{seed}", method=m,
                                       sequence_name=seq, sequence_path=None,
                                       groundtruth=root / "gt.txt", config=cfg)
                run.mark_done()
                ate = (ATE_CM[m] + 0.1 * si + 0.02 * seed) / 100
                run.metrics_path.write_text(json.dumps({
                    "protocol": {"name": "egs"}, "ate": {"rmse_m": ate},
                    "rendering": {"psnr_db": 30 - ATE_CM[m] + seed * 0.1, "ssim": 0.9,
                                  "lpips": 0.1 + 0.01 * ATE_CM[m]},
                    "speed": {"fps": 1.0, "render_fps": 100.0 + ATE_CM[m]}}))
    return root


def _rows(md: str) -> list[list[str]]:
    lines = [line for line in md.splitlines() if line.startswith("|")][2:]
    return [[c.strip() for c in line.split("|")[1:-1]] for line in lines]


def test_ablation_rows_come_from_the_configurations(tmp_path: Path) -> None:
    made, skipped = build_tables(_runs(tmp_path / "runs"), evaluate_missing=False)
    assert set(made) == {"ate", "rendering", "ablation_events", "ablation_crf"}
    assert skipped == ["edi: not made (needs monogs-edi runs)"]
    rows = _rows(render_markdown(made["ablation_events"]))
    # (tracking, mapping) in the paper's order; monogs is not an ablation row
    assert [r[:2] for r in rows] == [["✗", "✗"], ["✗", "✓"], ["✓", "✗"], ["✓", "✓"]]
    ate_office1 = [r[2] for r in rows]  # sequences sorted: office1 first
    std = 100 * np.std([0.0110, 0.0112], ddof=1)
    assert ate_office1 == ["4.11 ± 0.01", "3.11 ± 0.01", "<u>1.61</u> ± 0.01",
                           f"**1.11** ± {std:.2f}"]
    crf = _rows(render_markdown(made["ablation_crf"]))
    assert [r[0] for r in crf] == ["w/o CRF (egs-no-crf)", "w CRF (ours)"]
    assert crf[1][1].startswith("**1.11**") and crf[0][1].startswith("<u>1.31</u>")


def test_ate_and_rendering_layouts(tmp_path: Path) -> None:
    made, _ = build_tables(_runs(tmp_path / "runs"), evaluate_missing=False)
    ate = render_markdown(made["ate"])
    rows = _rows(ate)
    assert [r[0] for r in rows] == ["office1", "room0", "Avg."]
    header = next(line for line in ate.splitlines() if line.startswith("| Scenes"))
    assert "egs ATE [cm] ↓" in header and "monogs ATE [cm] ↓" in header
    assert sum("**" in c for c in rows[2]) == 1  # one best per row
    assert "Mean ± std over 2 runs" in ate
    rendering = _rows(render_markdown(made["rendering"]))
    assert rendering[0][:2] == ["egs", "PSNR [dB] ↑"] and rendering[1][0] == ""
    assert len(rendering) == 6 * 3
    egs_psnr = rendering[0][2]
    assert egs_psnr.startswith("**29.05**")  # best PSNR of the column among methods
    assert rendering[0][-1] == "<u>101.0</u>" or rendering[0][-1].startswith("101.0")
    best_fps = max(range(0, 18, 3), key=lambda i: float(rendering[i][-1].strip("*<u/>")))
    assert rendering[best_fps][-1].startswith("**")  # render FPS: higher is better


def test_edi_table_when_monogs_edi_runs_exist(tmp_path: Path) -> None:
    methods = {"monogs": METHODS["monogs"], "monogs-edi": METHODS["monogs"], "egs": {}}
    made, _ = build_tables(_runs(tmp_path / "runs", methods, seqs=("room0",)),
                           evaluate_missing=False, tables=["edi"])
    rows = _rows(render_markdown(made["edi"]))
    assert [r[0] for r in rows] == ["monogs", "monogs-edi", "egs"]
    assert rows[2][1].startswith("**1.01**")
    tex = render_latex(made["edi"], "tab:edi")
    assert r"\label{tab:edi}" in tex and r"\midrule" in tex


@pytest.mark.skipif(shutil.which("pdflatex") is None, reason="pdflatex not installed")
def test_paper_tables_cli_compiles_with_pdflatex(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                                 ) -> None:
    sweep = tmp_path / "sweep"
    _runs(sweep / "runs", seqs=("room0", "room1", "office1"))
    assert main(["paper-tables", str(sweep), "--check"]) == 0
    out = capsys.readouterr()
    assert "pdflatex: compiled; 0 overfull box(es)" in out.err + out.out
    tables = sweep / "tables"
    names = sorted(p.name for p in tables.glob("*.tex"))
    assert names == ["ablation_crf.tex", "ablation_events.tex", "ate.tex", "rendering.tex",
                     "tables.tex"]
    events = (tables / "ablation_events.tex").read_text()
    assert r"$\checkmark$ & $\times$" in events and r"\label{tab:ablation_events}" in events
    assert r"\begin{table*}" in events  # 3 sequences x 4 metrics: page-wide, shrunk to fit
    # existing tables are never replaced without --overwrite
    code = main(["paper-tables", str(sweep)])
    assert_cli_error(code, capsys.readouterr().err, 2, "already exists")
    assert main(["paper-tables", str(sweep), "--overwrite", "--width", "natural"]) == 0


def test_an_unknown_protocol_is_refused_not_tabulated_empty(tmp_path: Path,
                                                            capsys: pytest.CaptureFixture[str]
                                                            ) -> None:
    """An unknown --protocol used to give empty tables and exit 0 (every run "not evaluated");
    it is one line naming the known protocols, and nothing is written."""
    sweep = tmp_path / "sweep"
    _runs(sweep / "runs", seqs=("room0",))
    for command in (["paper-tables", str(sweep), "--protocol", "tum"],
                    ["leaderboard", str(sweep / "runs"), "--protocol", "tum"],
                    ["regress", str(sweep / "runs"), str(sweep / "runs"), "--protocol", "tum"]):
        assert_cli_error(main(command), capsys.readouterr().err, 2, "--protocol",
                         "'tum' is not one of 'egs', 'monogs'")
    assert not (sweep / "tables").exists()
