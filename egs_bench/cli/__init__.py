"""The ``egs-bench`` command. Thin: parses arguments and calls library functions.

Each area registers its commands on :data:`egs_bench.cli.app.app` from its own module.
"""

from __future__ import annotations

import importlib
import os
import sys

from rich.console import Console
from rich.text import Text

from egs_bench.caches import ENV_NUMBA, check_numba_cache_dir, numba_cache_dir
from egs_bench.cli.app import OPTIONS, app, err
from egs_bench.errors import (
    EXIT_DATA,
    EXIT_INTERNAL,
    EXIT_OK,
    EgsBenchError,
    Interrupted,
    interruption_in,
)
from egs_bench.fileio import DISK_FULL, is_disk_full
from egs_bench.interrupts import received_interruption, signals_interrupt

_COMMAND_MODULES = (
    "data_cmds",
    "synthetic_cmds",
    "eventreplica_cmds",
    "eval_cmds",
    "render_cmds",
    "slam_cmds",
    "config_cmds",
    "interop_cmds",
    "recording_cmds",
    "experiment_cmds",
    "setup_cmds",
    "report_cmds",
)


def prepare_process_environment() -> None:
    """Set, for this process and its children, what torch and numba read when they load.

    Called by :func:`main` before any command imports them (importing this module sets
    nothing): OpenMP threads that sleep when idle (``OMP_WAIT_POLICY=PASSIVE`` unless set),
    as torch's and numba's pools otherwise spin-wait and steal each other's cores (measured 4x
    slower rendering on 2 cores); and numba's kernel cache at the location of
    :func:`egs_bench.caches.numba_cache_dir`, where ``make setup``'s warm-up put the kernels.
    """
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
    os.environ[ENV_NUMBA] = str(numba_cache_dir())


def _register_commands() -> None:
    for name in _COMMAND_MODULES:
        importlib.import_module(f"egs_bench.cli.{name}")


def main(argv: list[str] | None = None) -> int:
    """Entry point of the console script; returns the process exit code.

    Exit codes: 0 success, 2 usage error (bad option or value, refused output path),
    3 data error (a file is missing, malformed or cannot be written), 70 internal error (a bug;
    ``--debug`` shows the traceback), 130 / 143 / 129 interrupted by SIGINT / SIGTERM / SIGHUP.
    """
    prepare_process_environment()
    _register_commands()
    try:
        check_numba_cache_dir()
        with signals_interrupt():
            app(args=argv, prog_name="egs-bench", standalone_mode=True)
    except SystemExit as exc:
        # usage errors arrive as ConfigError (cli/app.py); typer turns Ctrl-C into exit 130; a
        # signal we raised as Interrupted is found in the exception chain, and one whose
        # exception was swallowed (see egs_bench.interrupts) is still recorded
        interrupted = interruption_in(exc) or received_interruption()
        if interrupted is not None:
            return _report_interruption(err, interrupted)
        return int(exc.code or 0) if not isinstance(exc.code, str) else 1
    except EgsBenchError as exc:
        if OPTIONS.debug:
            raise
        _error_line(err, "error:", str(exc))
        return exc.exit_code
    except KeyboardInterrupt as exc:
        return _report_interruption(err, exc)
    except OSError as exc:
        # a file-system failure (disk full, permission, vanished file) outside our own checks
        if OPTIONS.debug:
            raise
        if is_disk_full(exc):
            return _disk_full(err, exc)
        if exc.filename is None:
            return _internal(err, exc)
        _error_line(err, "error:", f"{exc.filename}: {exc.strerror or exc}")
        return EXIT_DATA
    except Exception as exc:  # last-resort one-line report; --debug shows all
        if (interrupted := interruption_in(exc)) is not None:  # e.g. raised inside numba
            return _report_interruption(err, interrupted)
        if OPTIONS.debug:
            raise
        if is_disk_full(exc):  # wrapped by a library (HDF5, an encoder)
            return _disk_full(err, exc)
        return _internal(err, exc)
    if (interrupted := received_interruption()) is not None:
        return _report_interruption(err, interrupted)
    return EXIT_OK


def _error_line(err: Console, label: str, message: str) -> None:
    """``label message`` as one line, the label in bold red; the message is printed as it is
    (it names the user's paths and values, which are never read as rich markup)."""
    err.print(Text.assemble((label, "bold red"), " ", message))


def _report_interruption(err: Console, exc: KeyboardInterrupt) -> int:
    """One line and the exit code 128 + signal (130 for a plain Ctrl-C)."""
    err.print(str(exc) if isinstance(exc, Interrupted) else "interrupted")
    return exc.exit_code if isinstance(exc, Interrupted) else 130


def _disk_full(err: Console, exc: BaseException) -> int:
    """A full disk is the environment's fault, not a bug: one line naming the file when the
    error has one (writers of egs-bench raise UnwritableOutputError, which names it)."""
    names = [e.filename for e in (exc, exc.__cause__, exc.__context__)
             if isinstance(e, OSError) and e.filename is not None]
    _error_line(err, "error:", f"{names[0]}: {DISK_FULL}" if names else DISK_FULL)
    return EXIT_DATA


def _internal(err: Console, exc: BaseException) -> int:
    _error_line(err, "internal error:", f"{type(exc).__name__}: {exc} "
                "(a bug in egs-bench; run with --debug for the traceback)")
    return EXIT_INTERNAL


def run() -> None:
    """Console-script wrapper around :func:`main`."""
    sys.exit(main())


if __name__ == "__main__":
    run()
