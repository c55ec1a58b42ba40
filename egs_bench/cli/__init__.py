"""The ``egs-bench`` command. Thin: parses arguments and calls library functions.

Each area registers its commands on :data:`egs_bench.cli.app.app` from its own module.
"""

from __future__ import annotations

import importlib
import os
import sys

# Before torch/numba load: their OpenMP pools otherwise spin-wait and steal each other's cores
# (measured 4x slower rendering on 2 cores), and compiled numba kernels are cached.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
os.environ.setdefault("NUMBA_CACHE_DIR",
                      os.path.join(os.path.expanduser("~"), ".cache", "egs_bench", "numba"))

from rich.console import Console

from egs_bench.cli.app import OPTIONS, app
from egs_bench.errors import EgsBenchError

_COMMAND_MODULES = (
    "data_cmds",
    "synthetic_cmds",
    "eventreplica_cmds",
    "eval_cmds",
    "render_cmds",
    "slam_cmds",
    "interop_cmds",
    "recording_cmds",
    "experiment_cmds",
)


def _register_commands() -> None:
    for name in _COMMAND_MODULES:
        importlib.import_module(f"egs_bench.cli.{name}")


def main(argv: list[str] | None = None) -> int:
    """Entry point of the console script; returns the process exit code."""
    _register_commands()
    err = Console(stderr=True, highlight=False, soft_wrap=True)
    try:
        app(args=argv, standalone_mode=True)
    except SystemExit as exc:
        return int(exc.code or 0) if not isinstance(exc.code, str) else 1
    except EgsBenchError as exc:
        if OPTIONS.debug:
            raise
        err.print(f"[bold red]error:[/] {exc}", markup=True)
        return 2
    except KeyboardInterrupt:
        err.print("interrupted")
        return 130
    except Exception as exc:  # noqa: BLE001 (last-resort one-line report; --debug shows all)
        if OPTIONS.debug:
            raise
        err.print(f"[bold red]internal error:[/] {type(exc).__name__}: {exc} "
                  "(run with --debug for the traceback)", markup=True)
        return 1
    return 0



def run() -> None:
    """Console-script wrapper around :func:`main`."""
    sys.exit(main())


if __name__ == "__main__":
    run()
