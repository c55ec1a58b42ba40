"""Output-path checks of the experiments commands: never replace a folder with a file, never
replace an existing file unless the user asked (``--overwrite``)."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

from egs_bench.errors import InputError


def check_file_target(path: str | Path, overwrite: bool = True) -> Path:
    """Raise :class:`InputError` when ``path`` is a folder, or an existing file and not
    ``overwrite``; return it as a ``Path``."""
    path = Path(path)
    if path.is_dir():
        raise InputError(path, "is a folder; expected a file name")
    if path.exists() and not overwrite:
        raise InputError(path, "already exists (pass --overwrite to replace it)")
    return path


def check_file_targets(paths: Iterable[Path], overwrite: bool) -> None:
    """:func:`check_file_target` for every path, before anything is written."""
    for p in paths:
        check_file_target(p, overwrite)
