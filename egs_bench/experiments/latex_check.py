"""Compile LaTeX tables in a minimal document with pdflatex (a check that they build and fit).

pdflatex is an external program; where it is missing, :func:`pdflatex_available` is false and
callers skip the check.
"""

from __future__ import annotations

import shutil
import subprocess
from collections.abc import Sequence
from pathlib import Path

from egs_bench.errors import InputError
from egs_bench.fileio import write_text_atomic

PREAMBLE_PACKAGES = ("booktabs", "graphicx", "amssymb")


def pdflatex_available() -> bool:
    """Whether a ``pdflatex`` executable is on the PATH."""
    return shutil.which("pdflatex") is not None


def minimal_document(snippets: Sequence[str], twocolumn: bool = True) -> str:
    """A minimal article holding ``snippets`` (table floats) with the packages they need."""
    cls = r"\documentclass[10pt,twocolumn]{article}" if twocolumn else \
        r"\documentclass[10pt]{article}"
    lines = [cls, r"\usepackage[margin=2cm]{geometry}"]
    lines += [rf"\usepackage{{{p}}}" for p in PREAMBLE_PACKAGES]
    lines += [r"\begin{document}", *snippets, r"\end{document}", ""]
    return "\n".join(lines)


def compile_latex(snippets: Sequence[str], out_dir: str | Path, twocolumn: bool = True,
                  name: str = "tables", timeout_s: float = 120.0) -> str:
    """Write ``snippets`` into ``out_dir/<name>.tex`` and compile it with pdflatex.

    Returns:
        The pdflatex log (look for ``Overfull \\hbox`` to find tables wider than the page).

    Raises:
        InputError: pdflatex is missing or the document does not compile (the message quotes
            the first LaTeX error).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    tex = out / f"{name}.tex"
    write_text_atomic(tex, minimal_document(snippets, twocolumn))
    if not pdflatex_available():
        raise InputError(tex, "pdflatex is not installed; cannot compile")
    proc = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error", tex.name],
                          cwd=out, capture_output=True, text=True, timeout=timeout_s)
    log_path = out / f"{name}.log"
    log = log_path.read_text(errors="replace") if log_path.is_file() else proc.stdout
    if proc.returncode != 0:
        error = next((line for line in log.splitlines() if line.startswith("!")),
                     f"exit code {proc.returncode}")
        raise InputError(tex, f"pdflatex failed: {error}")
    return log
