"""Exceptions, sorted by who made the mistake, and the exit codes the CLI maps them to.

* :class:`ConfigError`: the user gave an option or configuration value that cannot work
  (exit code 2, like a command-line usage error).
* :class:`OutputError`: the output path the user chose may not be written: it exists and
  ``--overwrite`` was not given, or it is of another kind, the input, a parent of the input, the
  current directory or the home directory (exit code 2).
* :class:`InputError`: a file or folder given to egs-bench is missing, malformed or inconsistent,
  or an output location cannot be written (exit code 3).
* Anything else (``ValueError``, ``TypeError``, ...) raised inside the library is a programming
  error, e.g. a tensor of the wrong shape passed by calling code; the CLI reports it as an
  internal error (exit code 70).
* :class:`Interrupted`: SIGINT or SIGTERM arrived (exit code 128 + signal number).
"""

from __future__ import annotations

import signal
from pathlib import Path

#: exit codes of the ``egs-bench`` command (documented in docs/guide/running.md, "Guarantees")
EXIT_OK = 0
EXIT_USAGE = 2
EXIT_DATA = 3
EXIT_INTERNAL = 70  # EX_SOFTWARE of sysexits.h


class EgsBenchError(Exception):
    """Base class for errors a user can act on; the CLI prints one line and exits with
    :attr:`exit_code`."""

    exit_code: int = EXIT_DATA


class PathError(EgsBenchError):
    """An error about one file or folder; the message names it first:
    ``"<path>: <what is wrong>"``."""

    def __init__(self, path: str | Path, problem: str) -> None:
        self.path = Path(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")


class InputError(PathError):
    """A file or folder given to egs-bench is missing, malformed or inconsistent."""

    exit_code = EXIT_DATA


class ConfigError(EgsBenchError):
    """An option or configuration value is invalid (a user mistake, never a data problem)."""

    exit_code = EXIT_USAGE


class OutputError(PathError):
    """An output path may not be written (exists, wrong kind, is the input, in use...)."""

    exit_code = EXIT_USAGE


class UnwritableOutputError(OutputError):
    """An output location cannot be written (read-only folder, not a folder, no space)."""

    exit_code = EXIT_DATA


class Interrupted(KeyboardInterrupt):  # a KeyboardInterrupt, named like one
    """SIGINT or SIGTERM arrived. Subclasses ``KeyboardInterrupt`` so that code which cleans up
    after Ctrl-C (temporary folders, run folders marked interrupted) does the same after a
    cluster's SIGTERM."""

    def __init__(self, signum: int = signal.SIGINT) -> None:
        self.signum = int(signum)
        super().__init__(f"interrupted by {signal.Signals(self.signum).name}")

    @property
    def exit_code(self) -> int:
        return 128 + self.signum


def interruption_in(exc: BaseException | None) -> KeyboardInterrupt | None:
    """The Ctrl-C / SIGTERM behind ``exc``, if any (``exc`` itself or its cause/context chain).

    A signal handler's exception that arrives while a numba kernel runs surfaces as
    ``SystemError: CPUDispatcher(...) returned a result with an exception set`` with the
    interruption as its cause (seen when a sweep was stopped mid-run); typer wraps Ctrl-C in
    ``SystemExit``. Both must still count as an interruption, not as a failure or a bug.
    """
    seen: set[int] = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


def reraise_interruption(exc: BaseException) -> None:
    """Raise the Ctrl-C / SIGTERM behind ``exc`` if there is one (see :func:`interruption_in`);
    for ``except Exception`` blocks that record a failure and go on, which must not record a
    signal that surfaced inside numba as a failure."""
    if (interrupt := interruption_in(exc)) is not None:
        raise interrupt from None


def interruption_reason(exc: KeyboardInterrupt) -> str:
    """The one-line reason a run records for an interruption."""
    return str(exc) or "interrupted by SIGINT (Ctrl-C)"
