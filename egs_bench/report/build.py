"""``egs-bench report``: build the whole report folder, atomically.

Layout of a report::

    <out>/index.html              overview: provenance, leaderboards, flagged runs, all runs
    <out>/sequences/<name>.html   one page per sequence
    <out>/runs/<name>.html        one page per run
    <out>/runs/<name>.view.js     its 3D view's data (the run's quantised map, poses, images)
    <out>/sequences/<name>.view.js  the sequence's 3D view of all trajectories
    <out>/assets/                 report.css, report.js, viewer.js (the 3D viewer, with its
                                  licences), PNGs named by content (shared)
    <out>/report.json             what wrote the report (recognises it for --overwrite)

The folder is built in a hidden staging folder next to ``<out>`` and renamed into place when
complete (:func:`egs_bench.fileio.atomic_dir`): a reader never sees half a report, and an
existing report is replaced only after the new one is complete.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from egs_bench import __version__
from egs_bench.errors import OutputError
from egs_bench.eval.grouping import settings_labels
from egs_bench.eval.leaderboard import DEFAULT_METRICS
from egs_bench.eval.protocols import get_protocol
from egs_bench.fileio import atomic_dir
from egs_bench.outputs import check_never_replaced
from egs_bench.report.assets import AssetStore
from egs_bench.report.collect import ReportData, collect_report
from egs_bench.report.overview import (
    axis_choices,
    leaderboard_table,
    provenance,
    runs_table,
    settings_columns,
)
from egs_bench.report.pages import relative_paths, render
from egs_bench.report.run_page import build_run_page
from egs_bench.report.sequence_page import SequencePage, build_sequence_page
from egs_bench.report.viewer import VIEW_SUFFIX, run_view, write_view_script

MANIFEST = "report.json"
GENERATOR = "egs-bench report"
#: Metrics of the leaderboards.
BOARD_METRICS = (*DEFAULT_METRICS, "fps")


@dataclass(frozen=True)
class ReportResult:
    """Where the report went and what it holds.

    Attributes:
        out: the report folder. index: its overview page.
        runs, sequences, flagged: counts of run pages, sequence pages and flagged runs.
        assets_written, assets_reused: distinct image files stored, and requests answered by a
            file already stored.
        size_bytes: total size of the report folder.
    """

    out: Path
    index: Path
    runs: int
    sequences: int
    flagged: int
    assets_written: int
    assets_reused: int
    size_bytes: int


def is_report_folder(path: Path) -> bool:
    """Whether ``path`` holds a report egs-bench wrote (its ``report.json`` says so)."""
    try:
        data = json.loads((path / MANIFEST).read_text())
    except (OSError, ValueError, UnicodeDecodeError):
        return False
    return isinstance(data, dict) and data.get("generator") == GENERATOR


def check_report_output(out: Path, source: Path, overwrite: bool,
                        option: str = "--output") -> None:
    """The ``--overwrite`` rules for a report folder: a new or empty folder is free; an
    existing report needs ``overwrite``; anything else is never replaced.

    Raises:
        OutputError: naming ``out`` and the rule (also for the rules of every output:
            :func:`egs_bench.outputs.check_never_replaced`).
    """
    check_never_replaced(out, inputs=[source], option=option)
    if not out.exists() and not out.is_symlink():
        return
    if out.is_symlink() or not out.is_dir():
        raise OutputError(out, f"exists and is not a folder; choose another {option}")
    if not any(out.iterdir()):
        return
    if not is_report_folder(out):
        raise OutputError(out, f"already exists and is not an egs-bench report (no {MANIFEST} "
                               f"written by {GENERATOR}); choose another {option}")
    if not overwrite:
        raise OutputError(out, f"already exists; pass --overwrite to replace it or choose "
                               f"another {option}")


def _folder_size(path: Path) -> int:
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file())


def _unique_pages(names: Sequence[str]) -> dict[str, str]:
    from egs_bench.eval.tables import slug

    pages: dict[str, str] = {}
    for name in names:
        base = slug(name)
        page, k = base, 2
        while page in pages.values():
            page, k = f"{base}-{k}", k + 1
        pages[name] = page
    return pages


def write_pages(data: ReportData, root: Path, final: Path,
                frames: Sequence[int] | None = None,
                say: Callable[[str], None] | None = None) -> AssetStore:
    """Write every page and asset of ``data`` into ``root`` (to be renamed to ``final``)."""
    from egs_bench.report.sources import RunSources

    store = AssetStore(root)
    store.copy_static()
    (root / "sequences").mkdir()
    (root / "runs").mkdir()
    protocol = data.protocols[0]
    sources = RunSources(protocol)
    runs = [r.result for r in data.runs]
    labels = settings_labels(runs)
    columns = settings_columns(data.runs)
    pages = _unique_pages(data.sequences)
    seq_pages: dict[str, SequencePage] = {}
    for name in data.sequences:
        if say:
            say(f"sequence {name}")
        seq_pages[name] = build_sequence_page(name, pages[name], data, sources, store, frames,
                                              final / "sequences")
    nav = [{"name": n, "page": p.page, "count": len(p.runs)} for n, p in seq_pages.items()]
    common = {"nav_sequences": nav, "protocol": protocol}
    baselines: dict = {}
    for i, record in enumerate(data.runs):
        if say and (i + 1) % 25 == 0:
            say(f"run pages: {i + 1}/{len(data.runs)}")
        seq = seq_pages.get(record.result.sequence or "")
        view = run_view(record, sources, store)
        script = f"{record.page}{VIEW_SUFFIX}" if view is not None else None
        if view is not None and script is not None:
            write_view_script(root / "runs" / script, view)
        page = build_run_page(record, sources, store, seq.frames if seq else [],
                              final / "runs", baselines)
        html = render("run.html", title=f"{record.result.rel}: egs-bench report", root="../",
                      run=page, seq_page=seq.page if seq else None, view_script=script,
                      **common)
        (root / "runs" / f"{record.page}.html").write_text(html, encoding="utf-8")
    for name, seq in seq_pages.items():
        if seq.view is not None:
            write_view_script(root / "sequences" / f"{seq.page}{VIEW_SUFFIX}", seq.view)
        only = ReportData(data.source, data.kind, data.protocols, data.boards, seq.runs)
        # the sequence page is the one users share: its messages name no local folder
        seq_dir = final / "sequences"
        table = runs_table(only, columns, labels)
        table.rows = [[dataclasses.replace(c, text=relative_paths(c.text, seq_dir),
                                           sort=relative_paths(c.sort, seq_dir)) for c in row]
                      for row in table.rows]
        seq.notes = [relative_paths(n, seq_dir) for n in seq.notes]
        html = render("sequence.html", title=f"{name}: egs-bench report", root="../", seq=seq,
                      runs=table, **common)
        (root / "sequences" / f"{seq.page}.html").write_text(html, encoding="utf-8")
    boards = [{"name": p, "description": get_protocol(p).description,
               "table": leaderboard_table(b, columns, labels), "notes": b.notes}
              for p, b in data.boards.items()]
    html = render("index.html", title=f"egs-bench report: {data.source.resolve().name}",
                  root="", provenance=provenance(data), axes=axis_choices(data, labels),
                  boards=boards, flagged=runs_table(data, columns, labels, flagged_only=True),
                  runs=runs_table(data, columns, labels), **common)
    (root / "index.html").write_text(html, encoding="utf-8")
    return store


def build_report(source: str | Path, out: str | Path, *, overwrite: bool = False,
                 protocols: list[str] | None = None, evaluate_missing: bool = True,
                 frames: Sequence[int] | None = None,
                 say: Callable[[str], None] | None = None) -> ReportResult:
    """Write the HTML report of the runs under ``source`` to the folder ``out``.

    Args:
        source: a run folder, a folder of run folders or a sweep's output folder.
        out: the report folder to create (see the module docstring for its layout).
        overwrite: replace an existing report at ``out`` (never anything else).
        protocols: leaderboards' protocols (default: those the runs were evaluated under).
        evaluate_missing: evaluate runs without metrics under the first protocol.
        frames: frames of the sequences' image strips (default: 3 evenly spaced frames every
            method rendered).
        say: progress messages (one line each), or ``None``.

    Raises:
        OutputError: ``out`` may not be written (see :func:`check_report_output`).
        InputError: ``source`` holds no run folder.
        ConfigError: an unknown protocol.
    """
    source, out = Path(source), Path(out)
    check_report_output(out, source, overwrite)
    data = collect_report(source, protocols, evaluate_missing, BOARD_METRICS)
    with atomic_dir(out, replace=overwrite) as tmp:
        tmp.mkdir()
        store = write_pages(data, tmp, out.resolve(), frames, say)
        manifest = {"generator": GENERATOR, "egs_bench_version": __version__,
                    "source": str(source.resolve()), "kind": data.kind,
                    "protocols": data.protocols, "runs": len(data.runs)}
        (tmp / MANIFEST).write_text(json.dumps(manifest, indent=1) + "\n", encoding="utf-8")
    return ReportResult(out, out / "index.html", len(data.runs), len(data.sequences),
                        sum(r.flagged for r in data.runs), store.written, store.reused,
                        _folder_size(out))


#: The folder a demo or a sweep writes its report into, under its own output folder.
SIDE_REPORT_DIR = "report"


def write_side_report(source: Path, out: Path, say: Callable[[str], None], *,
                      protocols: list[str] | None = None,
                      evaluate_missing: bool = False) -> ReportResult | None:
    """The report a demo or a sweep writes next to its runs: replaces an earlier report at
    ``out``, and never fails its caller: a problem (an existing folder that is not a report, a
    bad run) is one warning line through ``say`` and ``None``; the runs are untouched.
    Interruptions (Ctrl-C, SIGTERM) still propagate."""
    from egs_bench.errors import reraise_interruption

    try:
        result = build_report(source, out, overwrite=is_report_folder(out), protocols=protocols,
                              evaluate_missing=evaluate_missing)
    except Exception as exc:
        reraise_interruption(exc)
        say(f"warning: report not written ({type(exc).__name__}: {exc}); the runs are "
            f"unaffected, retry with `egs-bench report {source} -o {out} --overwrite`")
        return None
    say(f"report: {result.index} ({result.runs} runs, {result.flagged} flagged, "
        f"{result.size_bytes / 1e6:.1f} MB)")
    return result
