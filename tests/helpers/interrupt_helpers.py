"""How a signal looks when it arrives while numba runs: the handler's exception becomes the
cause of ``SystemError: CPUDispatcher(...) returned a result with an exception set`` (seen when
a sweep was stopped mid-run)."""

from __future__ import annotations

import signal

from egs_bench.errors import Interrupted


def raise_sigterm_as_numba_does(*_args: object, **_kwargs: object) -> None:
    """Raise a SIGTERM's :class:`Interrupted` wrapped the way numba wraps it (accepts and
    ignores any arguments, to stand in for any function)."""
    try:
        raise Interrupted(signal.SIGTERM)
    except Interrupted as exc:
        raise SystemError("CPUDispatcher(<function bin_tiles at 0x7f>) returned a result with "
                          "an exception set") from exc
