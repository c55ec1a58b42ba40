"""Running ``egs-bench`` inside the test process, and checking the one-line error it reports."""

from __future__ import annotations

from pathlib import Path

import pytest

from egs_bench.cli import main
from egs_bench.errors import EXIT_INTERNAL


def run_cli(capsys: pytest.CaptureFixture[str], *argv: str | Path) -> tuple[int, str, str]:
    """``egs-bench *argv`` through :func:`egs_bench.cli.main`, which maps exceptions to exit
    codes and one-line messages as the console script does (typer's ``CliRunner`` does not: it
    turns any exception into exit code 1). Returns (exit code, stdout, stderr)."""
    code = main([str(a) for a in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def assert_cli_error(code: int, err: str, expected_code: int, *fragments: str | Path) -> str:
    """Assert that a command failed with ``expected_code`` (``egs_bench.errors``: 2 usage, 3 data,
    70 internal) and reported it as one ``error: ...`` line (``internal error: ...`` for 70),
    the last of stderr, holding every fragment: the file or option it names, the problem.
    Progress bars may come before it; a traceback or a second error line may not. Returns the
    line."""
    assert fragments, "name the file or option the message must hold"
    assert code == expected_code, f"exit code {code}, expected {expected_code}; stderr:\n{err}"
    *before, line = err.rstrip("\n").split("\n")
    label = "internal error: " if expected_code == EXIT_INTERNAL else "error: "
    assert line.startswith(label), f"the last line of stderr is not {label!r}:\n{err}"
    assert "Traceback" not in err, err
    assert not [b for b in before if b.startswith(("error:", "internal error:"))], err
    missing = [str(f) for f in fragments if str(f) not in line]
    assert not missing, f"{missing} not in {line!r}"
    return line
