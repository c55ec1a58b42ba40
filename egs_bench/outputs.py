"""What an output path may be: the ``--overwrite`` rules every writing command follows.

:func:`prepare_output` is called once per user-named output before anything is written:

* a path that does not exist is fine if its folder can be created and written;
* an existing path needs ``overwrite``, and ``overwrite`` replaces only an output of the same
  kind that egs-bench wrote: a PNG by a PNG, a figure (PNG, PDF or SVG) by a figure, a PLY by a
  PLY, a text file by a text file, an ATE/RPE results file (``--save_results``) by one, a
  sequence folder (``meta.yaml`` with ``generator.name: egs-bench`` and nothing but sequence
  files) by a sequence folder, a run folder (``run.yaml`` written by egs-bench) by a run folder;
  an empty folder counts as free for folder outputs;
* never, even with ``overwrite``: an input of the command, a folder containing one or an
  existing file (PNG, PLY, text) inside an input folder, the current directory or one of its
  parents, the home directory or one of its parents, ``/``.

The checks are made on resolved paths (symbolic links and ``..`` followed).
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable
from pathlib import Path
from typing import Literal

import yaml

from egs_bench.errors import OutputError, UnwritableOutputError

OutputKind = Literal["png", "figure", "ply", "text", "results", "sequence", "run"]

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_SEQUENCE_ENTRIES = {"meta.yaml", "frames.csv", "events.h5", "groundtruth.txt",
                     "groundtruth_dense.txt"}
_SEQUENCE_IMAGE_DIRS = {"rgb", "depth", "sharp"}
_FRAME_FILE = re.compile(r"^\d{6,}\.(png|npy)$")


def _describe(kind: OutputKind) -> str:
    return {"png": "a PNG image", "figure": "a PNG, PDF or SVG figure", "ply": "a PLY file",
            "text": "a text file",
            "results": "an ATE/RPE results file written by egs-bench",
            "sequence": "a sequence folder written by egs-bench",
            "run": "a run folder written by egs-bench"}[kind]


def _resolve(path: Path) -> Path:
    return Path(os.path.abspath(path)).resolve()


def shareable_path(path: str | Path, out: str | Path) -> str:
    """``path`` as an output meant to be sent on (a sequence's ``meta.yaml``) records it:
    relative to the output folder ``out`` when it lies below ``out``'s parent
    (``../replica/room0``), else by its name alone; never this machine's absolute path."""
    p, base = _resolve(Path(path)), _resolve(Path(out))
    try:
        p.relative_to(base.parent)
    except ValueError:
        return p.name
    return os.path.relpath(p, base)


def _protected(out: Path) -> str | None:
    """Why ``out`` may never be replaced, or None."""
    cwd = _resolve(Path.cwd())
    home = _resolve(Path.home())
    if out == Path(out.anchor):
        return "is the file-system root"
    if out == cwd or out in cwd.parents:
        return "is the current directory or one of its parents"
    if out == home or out in home.parents:
        return "is the home directory or one of its parents"
    return None


def _check_not_input(out: Path, inputs: Iterable[str | Path | None], shown: Path,
                     replacing: bool) -> None:
    for item in inputs:
        if item is None:
            continue
        inp = _resolve(Path(item))
        if out == inp:
            raise OutputError(shown, "is an input of this command; refusing to write over it")
        if out in inp.parents:
            raise OutputError(shown, f"contains the input {item}; refusing to replace it")
        if replacing and inp in out.parents:
            raise OutputError(shown, f"is inside the input {item}; refusing to replace it")


# Files that may precede a run in its folder: the run lock (left by an earlier run) and what a
# launcher writes before starting the run (the sweep worker's record and log,
# :mod:`egs_bench.experiments.worker`).
RUN_PRELUDE_FILES = frozenset({".lock", "sweep.json", "worker.log"})


def _is_empty(folder: Path) -> bool:
    """No entries other than :data:`RUN_PRELUDE_FILES`."""
    return all(entry.name in RUN_PRELUDE_FILES and entry.is_file()
               for entry in folder.iterdir())


def _check_writable_location(path: Path) -> None:
    """The nearest existing ancestor must be a writable folder."""
    probe = path.parent
    while not probe.exists():
        if probe == probe.parent:
            break
        probe = probe.parent
    if not probe.is_dir():
        raise UnwritableOutputError(path, f"{probe} is a file, not a folder")
    if not os.access(probe, os.W_OK | os.X_OK):
        raise UnwritableOutputError(path, f"cannot write into {probe} (permission denied)")


def is_egs_sequence_folder(path: Path) -> tuple[bool, str]:
    """Whether ``path`` is a sequence folder that egs-bench wrote and that holds nothing else.

    Returns ``(ok, why_not)``.
    """
    meta_file = path / "meta.yaml"
    try:
        meta = yaml.safe_load(meta_file.read_bytes().decode("utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError):
        return False, "has no readable meta.yaml"
    generator = meta.get("generator") if isinstance(meta, dict) else None
    if isinstance(generator, dict):
        generator = generator.get("name")
    # generators write {name: egs-bench, version}; importers a text "egs-bench <command>"
    if not isinstance(generator, str) or generator.split()[:1] != ["egs-bench"]:
        return False, "meta.yaml does not say it was generated by egs-bench"
    foreign = []
    for entry in path.iterdir():
        if entry.name in _SEQUENCE_ENTRIES and entry.is_file():
            continue
        if entry.name in _SEQUENCE_IMAGE_DIRS and entry.is_dir():
            foreign += [f"{entry.name}/{f.name}" for f in entry.iterdir()
                        if not (_FRAME_FILE.match(f.name) and f.is_file())]
            continue
        foreign.append(entry.name)
    if foreign:
        shown = ", ".join(sorted(foreign)[:3]) + (", ..." if len(foreign) > 3 else "")
        return False, f"also holds files egs-bench did not write ({shown})"
    return True, ""


def _is_egs_run_folder(path: Path) -> tuple[bool, str]:
    run_file = path / "run.yaml"
    try:
        info = yaml.safe_load(run_file.read_bytes().decode("utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError):
        return False, "has no readable run.yaml"
    if not isinstance(info, dict) or "egs_bench_version" not in info:
        return False, "run.yaml was not written by egs-bench"
    return True, ""


def _same_kind(path: Path, kind: OutputKind) -> tuple[bool, str]:
    if kind in ("sequence", "run"):
        if not path.is_dir():
            return False, "is a file"
        return is_egs_sequence_folder(path) if kind == "sequence" else _is_egs_run_folder(path)
    if not path.is_file():
        return False, "is a folder" if path.is_dir() else "is not a regular file"
    if kind == "results":
        return _is_results_file(path), "is not an ATE/RPE results file written by egs-bench"
    with path.open("rb") as handle:
        head = handle.read(4096)
    if kind == "png":
        return head.startswith(_PNG_SIGNATURE), "is not a PNG image"
    if kind == "ply":
        return head.startswith(b"ply"), "is not a PLY file"
    if kind == "figure":
        is_figure = head.startswith((_PNG_SIGNATURE, b"%PDF")) or (
            b"<svg" in head and head.lstrip().startswith((b"<?xml", b"<svg")))
        return is_figure, "is not a PNG, PDF or SVG figure"
    try:
        head.decode("utf-8")
        text_ok = b"\0" not in head
    except UnicodeDecodeError as exc:
        text_ok = exc.start > len(head) - 4  # a multi-byte character cut by the 4 KiB read
    return text_ok, "is not a text file"


def _is_results_file(path: Path) -> bool:
    """Whether ``path`` holds what ``ate``/``rpe --save_results`` write (a JSON object naming
    its metric and egs-bench among its tools): any other JSON file, such as a report's
    ``report.json``, is the user's or another command's."""
    import json

    try:
        data = json.loads(path.read_bytes())
    except (OSError, ValueError):
        return False
    tools = data.get("tools") if isinstance(data, dict) else None
    return (isinstance(tools, dict) and "egs_bench" in tools
            and data.get("metric") in ("ATE", "RPE"))


def check_never_replaced(path: str | Path, inputs: Iterable[str | Path | None] = (),
                         option: str = "--out") -> None:
    """The rules that hold for every output, whatever its kind: not an input, not a folder
    containing one, not the current or home directory or a parent of them, not ``/``.

    For writers that decide the same-kind question themselves (e.g. an export folder
    recognised by its manifest); :func:`prepare_output` applies these rules too.

    Raises:
        OutputError: naming the path and the rule.
    """
    shown = Path(path)
    out = _resolve(shown)
    _check_not_input(out, inputs, shown, replacing=False)
    if shown.exists():
        protected = _protected(out)
        if protected:
            raise OutputError(shown, f"{protected}; refusing to write over it (choose a new "
                                     f"{option})")


def prepare_output(path: str | Path, kind: OutputKind, *, overwrite: bool = False,
                   inputs: Iterable[str | Path | None] = (), option: str = "--out") -> Path:
    """Check that ``path`` may be written as an output of ``kind`` (rules in the module doc).

    Args:
        path: the output the user named.
        kind: what will be written there.
        overwrite: the user asked to replace an existing output (``--overwrite``).
        inputs: the command's inputs (files or folders); the output may be none of them and
            may not contain any of them.
        option: the option that named the output, for the messages.

    Returns:
        ``path`` as given.

    Raises:
        OutputError: the path exists and may not (or, without ``overwrite``, need not) be
            replaced; the message says why and what to do.
        UnwritableOutputError: the location cannot be written.
    """
    shown = Path(path)
    out = _resolve(shown)
    exists = shown.exists() or shown.is_symlink()
    # a file inside an input folder may be part of the input (a frame, a map): never replaced
    _check_not_input(out, inputs, shown,
                     replacing=exists and kind in ("png", "figure", "ply", "text", "results"))
    if exists:
        protected = _protected(out)
        if protected:
            raise OutputError(shown, f"{protected}; refusing to write a {kind} output over it "
                                     f"(choose a new {option})")
        if kind in ("sequence", "run") and shown.is_dir() and _is_empty(shown):
            exists = False  # an empty folder holds nothing to lose
    if not exists:
        _check_writable_location(out)
        return shown
    ok, why = _same_kind(shown, kind)
    if not overwrite:
        if ok:
            raise OutputError(shown, f"already exists; pass --overwrite to replace it or "
                                     f"choose another {option}")
        raise OutputError(shown, f"already exists and {why}; choose another {option}")
    if not ok:
        raise OutputError(shown, f"{why}: --overwrite only replaces {_describe(kind)}")
    if not os.access(out.parent, os.W_OK | os.X_OK):
        raise UnwritableOutputError(shown, f"cannot write into {out.parent} (permission denied)")
    return shown
