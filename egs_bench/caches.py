"""Where egs-bench keeps what it computes once and reuses: compiled numba kernels and converted
LPIPS weights. The one rule every entry point follows (the CLI, the Makefile's warm-up, the
tests):

* ``$EGS_BENCH_CACHE`` names the egs-bench cache folder; without it the folder is
  ``<sys.prefix>/var/cache/egs_bench`` when Python runs inside a virtual environment whose
  prefix is writable (``make setup``'s ``.venv``, a user's own venv), else
  ``~/.cache/egs_bench``;
* ``$NUMBA_CACHE_DIR`` names numba's kernel cache; without it, ``<egs-bench cache>/numba``.

So ``make setup`` (which runs ``egs-bench warm-up`` from the venv) fills the very folder that
``.venv/bin/egs-bench`` typed by hand reads, and removing the venv removes its caches.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Mapping
from pathlib import Path

from egs_bench.errors import ConfigError

ENV_CACHE = "EGS_BENCH_CACHE"
ENV_NUMBA = "NUMBA_CACHE_DIR"


def _in_virtual_env() -> bool:
    return sys.prefix != getattr(sys, "base_prefix", sys.prefix)


def _writable_or_creatable(path: Path) -> bool:
    """Whether ``path`` is a writable folder or could be made as one (its nearest existing
    ancestor is a writable folder)."""
    probe = path
    while not probe.exists():
        if probe.parent == probe:
            return False
        probe = probe.parent
    return probe.is_dir() and os.access(probe, os.W_OK | os.X_OK)


def cache_root(environ: Mapping[str, str] | None = None) -> Path:
    """The egs-bench cache folder (see the module docstring for the rule).

    Args:
        environ: the environment to read (default ``os.environ``).
    """
    env = os.environ if environ is None else environ
    if env.get(ENV_CACHE):
        return Path(env[ENV_CACHE])
    if _in_virtual_env():
        in_venv = Path(sys.prefix) / "var" / "cache" / "egs_bench"
        if _writable_or_creatable(in_venv):
            return in_venv
    return Path.home() / ".cache" / "egs_bench"


def numba_cache_dir(environ: Mapping[str, str] | None = None) -> Path:
    """numba's kernel cache: ``$NUMBA_CACHE_DIR``, else ``<cache_root()>/numba``."""
    env = os.environ if environ is None else environ
    if env.get(ENV_NUMBA):
        return Path(env[ENV_NUMBA])
    return cache_root(env) / "numba"


def check_numba_cache_dir(environ: Mapping[str, str] | None = None) -> None:
    """Refuse a kernel cache numba cannot use: given one, numba silently falls back to writing
    into the installed package's ``__pycache__`` (or to compiling every time).

    Raises:
        ConfigError: ``NUMBA_CACHE_DIR`` (or the default) is not a folder, or cannot be created
            or written.
    """
    path = numba_cache_dir(environ)
    if path.exists() and not path.is_dir():
        raise ConfigError(f"{ENV_NUMBA}={path} is not a folder; point it at a folder (it "
                          "holds the compiled numba kernels) or unset it")
    if not _writable_or_creatable(path):
        raise ConfigError(f"{ENV_NUMBA}={path} cannot be created or written; point it at a "
                          "writable folder or unset it")
