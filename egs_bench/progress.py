"""The progress display of every long loop (sequence generation, SLAM runs, imports, exports,
evaluation), fitted to where it is shown.

On a terminal it is a tqdm bar redrawn in place. Anywhere else (a log file, CI, a pipe) a bar's
``\\r`` redraws pile up (a 24-frame run wrote 255 of them, 26 KB), so there it is an occasional
plain line instead: one each time another tenth of the work is done, or after
:data:`LOG_EVERY_S` seconds without one, and one at the end. Values shown next to the count
that are not finite (a loss that is NaN on a map's first frame) are left out, not printed as
``nan``.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from types import TracebackType
from typing import IO, Any, TypeVar

T = TypeVar("T")

#: the longest silence, in seconds, between two log lines of a running loop
LOG_EVERY_S = 30.0
#: a log line each time this fraction of the work more is done
LOG_STEP = 0.1


def _shown(value: Any) -> str | None:
    """A postfix value as text; None for a non-finite number (left out)."""
    if isinstance(value, bool):
        return str(value)
    if isinstance(value, float):
        return f"{value:.4g}" if math.isfinite(value) else None
    return str(value)


def postfix_text(values: dict[str, Any]) -> str:
    """``"loss=0.0123, gaussians=512"``: the finite values, in the given order."""
    shown = ((k, _shown(v)) for k, v in values.items())
    return ", ".join(f"{k}={text}" for k, text in shown if text is not None)


class ProgressBar:
    """A progress display for ``total`` steps: a tqdm bar on a terminal, log lines elsewhere,
    nothing when disabled. Use as a context manager or call :meth:`close`.

    Args:
        total: number of steps.
        desc: what is being done (``"generating office"``).
        unit: one step's name (``"frame"``).
        enabled: False shows nothing at all (``--quiet``).
        file: where it is shown (default ``sys.stderr``); a terminal when ``file.isatty()``.
        clock: seconds of a monotonic clock.
    """

    def __init__(self, total: int, desc: str, unit: str = "it", enabled: bool = True,
                 file: IO[str] | None = None,
                 clock: Callable[[], float] = time.perf_counter) -> None:
        self.total = int(total)
        self.n = 0
        self._desc, self._unit, self._enabled = desc, unit, enabled
        self._file = file if file is not None else sys.stderr
        self._clock = clock
        self._postfix = ""
        self._closed = False
        self._tqdm: Any = None
        self._start = clock()
        self._last_line_t = self._start
        self._last_line_step = -1  # the tenth of the work the last log line reported
        self._unreported = False  # something changed since the last log line
        if enabled and _is_terminal(self._file):
            from tqdm import tqdm

            self._tqdm = tqdm(total=self.total, desc=desc, unit=unit, file=self._file)

    def update(self, n: int = 1) -> None:
        """``n`` more steps are done."""
        self.n += n
        if self._tqdm is not None:
            self._tqdm.update(n)
        else:
            self._maybe_log()

    def set_postfix(self, **values: Any) -> None:
        """Values shown after the count (non-finite numbers are left out)."""
        self.set_postfix_str(postfix_text(values))

    def set_postfix_str(self, text: str) -> None:
        """A text shown after the count (e.g. a long phase's own progress)."""
        self._postfix = text
        if self._tqdm is not None:
            self._tqdm.set_postfix_str(text)
        else:
            self._maybe_log()

    def close(self) -> None:
        """Ends the display: the bar's last redraw, or a final log line (unless the last line
        already said all there is)."""
        if self._closed:
            return
        self._closed = True
        if self._tqdm is not None:
            self._tqdm.close()
        elif self._enabled and self._unreported:
            self._log()

    def __enter__(self) -> ProgressBar:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()

    # ---------------------------------------------------------------------------- log lines
    def _step(self, n: int) -> int:
        """The tenths of the work that ``n`` steps make (the last one only when all is done)."""
        if self.total <= 0:
            return 0
        return min(int(n / self.total / LOG_STEP + 1e-9), int(round(1 / LOG_STEP)))

    def _maybe_log(self) -> None:
        if not self._enabled or self._closed:
            return
        self._unreported = True
        now = self._clock()
        if (self._step(self.n) > self._last_line_step
                or now - self._last_line_t >= LOG_EVERY_S):
            self._log(now)

    def _log(self, now: float | None = None) -> None:
        now = self._clock() if now is None else now
        percent = f" ({100 * self.n / self.total:.0f} %)" if self.total > 0 else ""
        units = self._unit if self.total == 1 else f"{self._unit}s"
        line = (f"{self._desc}: {self.n}/{self.total} {units}{percent}, "
                f"{now - self._start:.0f} s")
        if self._postfix:
            line += f", {self._postfix}"
        print(line, file=self._file, flush=True)
        self._last_line_t = now
        self._last_line_step = self._step(self.n)
        self._unreported = False


def tracked(items: Sequence[T], desc: str, unit: str = "it", enabled: bool = True) -> Iterator[T]:
    """The items of ``items``, with a :class:`ProgressBar` counting them."""
    with ProgressBar(len(items), desc, unit=unit, enabled=enabled) as bar:
        for item in items:
            yield item
            bar.update()


def _is_terminal(file: IO[str]) -> bool:
    try:
        return bool(file.isatty())
    except (AttributeError, ValueError):  # no isatty, or a closed file
        return False


def say_compiling(what: str, file: IO[str] | None = None) -> None:
    """One honest line before a step that may compile numba kernels for minutes on a cold
    cache (``egs-bench warm-up`` compiles them ahead)."""
    print(f"{what}: compiling numba kernels (once; `egs-bench warm-up` does it ahead)…",
          file=file if file is not None else sys.stderr, flush=True)
