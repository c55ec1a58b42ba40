"""Which code produced a result: the git commit of the egs_bench checkout a process runs from.

The package version alone does not identify the code: every commit of a development checkout
reports the same ``__version__``, and two runs of one sweep can straddle a change (a benchmark
table whose rows came from different commits could not say which row ran which). Run folders
therefore record the commit and whether tracked files differed from it.

Asked of ``git`` itself (``rev-parse`` and ``status``) rather than by reading ``.git``: worktrees,
packed refs and submodules all change where ``HEAD`` lives, and git already resolves them.
"""

from __future__ import annotations

import functools
import subprocess
from pathlib import Path

PACKAGE_ROOT = Path(__file__).resolve().parent
_GIT_TIMEOUT_S = 10.0


def _git(root: Path, *args: str) -> str | None:
    """stdout of ``git -C root args`` (stripped), or None when git is missing, fails or hangs."""
    try:
        proc = subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True,
                              timeout=_GIT_TIMEOUT_S, stdin=subprocess.DEVNULL)
    except (OSError, subprocess.SubprocessError):
        return None
    return proc.stdout.strip() if proc.returncode == 0 else None


def code_revision(package_root: Path = PACKAGE_ROOT) -> dict[str, str | bool] | None:
    """The commit of the git checkout holding ``package_root``.

    Returns:
        ``{"commit": <40 hex digits>, "modified": <tracked files differ from it>}``, or None
        when the package is not inside a git work tree (an installed wheel) or git is absent.
        Untracked files do not count as modifications (run outputs and caches live in the
        checkout).
    """
    return _code_revision_cached(Path(package_root).resolve())


@functools.lru_cache(maxsize=8)
def _code_revision_cached(package_root: Path) -> dict[str, str | bool] | None:
    # Cached: one process writes many run folders from the same code; the first call's answer
    # stands for the process (a checkout edited later does not change what it imported).
    commit = _git(package_root, "rev-parse", "--verify", "HEAD")  # fails outside a checkout
    if commit is None:
        return None
    # status covers the whole work tree from any folder inside it
    status = _git(package_root, "status", "--porcelain", "--untracked-files=no")
    if status is None:
        return None
    return {"commit": commit, "modified": bool(status)}
