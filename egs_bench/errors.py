"""Exceptions that the CLI reports as one clear line (no traceback unless ``--debug``)."""

from __future__ import annotations

from pathlib import Path


class EgsBenchError(Exception):
    """Base class for errors a user can act on (bad input, missing data, bad options)."""


class InputError(EgsBenchError):
    """A file or folder given to egs-bench is missing, malformed or inconsistent.

    The message always names the offending path first: ``"<path>: <what is wrong>"``.
    """

    def __init__(self, path: str | Path, problem: str) -> None:
        self.path = Path(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")


class ConfigError(EgsBenchError):
    """An option or configuration value is invalid."""
