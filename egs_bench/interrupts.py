"""Signals as interruptions: SIGINT, SIGTERM and SIGHUP raise :class:`~egs_bench.errors.Interrupted`
so that the clean-up written for Ctrl-C (run folders marked interrupted, staging folders
removed) also runs after a cluster's time limit or ``kill``.

Two ways a plain "raise in the handler" loses a signal, both seen in CI runs:

* Python runs a handler wherever the main thread happens to be. Inside a weakref callback or a
  ``__del__`` (garbage collection can run anywhere) an exception is printed as "Exception
  ignored" and dropped, and the process went on to finish and exit 0. So the first signal is
  also *recorded*; :func:`raise_if_interrupted` raises it again, and is called before any
  output is committed as complete (:func:`egs_bench.fileio.atomic_dir`,
  :meth:`egs_bench.runs.folder.RunFolder.mark_done`) and by the long loops (each frame, each
  mapping iteration).
* A second SIGTERM (``kill`` of a process group, then a sweep pool stopping its workers) landed
  in the ``except`` block that was recording the first one, and the run stayed "running". A
  repeat within :data:`REPEAT_GRACE_S` of the raised one is therefore ignored: the clean-up it
  would abort is under way. A later repeat (the first one was swallowed, or the user insists)
  raises again.

A signal can also land before any clean-up is in place: a run folder's status reads "running"
from the moment it is written, a few calls before the run's ``failure_guard`` is entered, and a
``kill`` sent as soon as that status appeared landed there (seen in one of six tries). Code that
leaves such state registers a callback with :func:`call_on_interrupt`; the outermost block runs
it when it ends after a signal.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

from egs_bench.errors import Interrupted

#: Seconds after a raised interruption during which the same process ignores further signals
#: (clean-up takes well under a second: a status file, a staging folder).
REPEAT_GRACE_S = 5.0

#: The signals handled: Ctrl-C, a cluster's time limit / ``kill``, a closed terminal.
HANDLED_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)

_received: int | None = None  # the first signal of this process since the handlers went in
_last_raised_at: float = float("-inf")  # time.monotonic() of the last raise
_depth = 0  # nesting of :func:`signals_interrupt` (the CLI, then a sweep worker inside it)
_on_interrupt: list[Callable[[Interrupted], None]] = []


def call_on_interrupt(callback: Callable[[Interrupted], None]) -> None:
    """Have ``callback(interruption)`` called when an outermost :func:`signals_interrupt` block
    ends after a signal arrived in it (e.g. to mark what the process leaves half-done). It must
    not raise; an exception from it is dropped so the others still run."""
    if callback not in _on_interrupt:
        _on_interrupt.append(callback)


def _on_signal(signum: int, _frame: object) -> None:
    global _received, _last_raised_at
    now = time.monotonic()
    if _received is not None and now - _last_raised_at < REPEAT_GRACE_S:
        return
    if _received is None:
        _received = signum
    _last_raised_at = now
    raise Interrupted(signum)


def _quiet_unraisable(previous: Any) -> Any:
    """An ``sys.unraisablehook`` that does not print a swallowed :class:`Interrupted` (it is
    recorded and raised again at the next check) and passes anything else on."""
    def hook(unraisable: Any) -> None:
        if not isinstance(unraisable.exc_value, Interrupted):
            previous(unraisable)
    return hook


@contextmanager
def signals_interrupt(signals: tuple[signal.Signals, ...] = HANDLED_SIGNALS) -> Iterator[None]:
    """Within the block, ``signals`` raise :class:`Interrupted` (see the module docstring).

    Nested use keeps the outer block's record of a received signal; the outermost block starts
    with none. Outside the main thread (a test runner's thread) the handlers cannot be set and
    the block runs unchanged.
    """
    global _depth, _received, _last_raised_at
    if _depth == 0:
        _received, _last_raised_at = None, float("-inf")
    previous = {}
    for sig in signals:
        try:
            previous[sig] = signal.signal(sig, _on_signal)
        except ValueError:  # not the main thread
            pass
    previous_hook = sys.unraisablehook
    if previous:
        sys.unraisablehook = _quiet_unraisable(previous_hook)
    _depth += 1
    try:
        yield
    finally:
        _depth -= 1
        if _depth == 0 and _received is not None:
            interruption = Interrupted(_received)
            for callback in list(_on_interrupt):
                # clean-up must not hide the interruption or stop the other callbacks
                with contextlib.suppress(BaseException):
                    callback(interruption)
        sys.unraisablehook = previous_hook
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def received_interruption() -> Interrupted | None:
    """The interruption for the first signal received in the current (or, after it ended, the
    last) outermost :func:`signals_interrupt` block, even one whose exception was swallowed;
    ``None`` if none arrived."""
    return Interrupted(_received) if _received is not None else None


def raise_if_interrupted() -> None:
    """Raise :class:`Interrupted` if a signal arrived; call before committing an output as
    complete and once per iteration of long loops. Outside a :func:`signals_interrupt` block it
    does nothing (no handler recorded anything there)."""
    if _depth > 0 and _received is not None:
        raise Interrupted(_received)
