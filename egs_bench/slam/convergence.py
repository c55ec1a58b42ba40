"""When tracking may stop before its iteration budget (``tracking.convergence``).

MonoGS stops when the largest pose step falls below an absolute threshold
(``budget.converged_threshold``). Adam's steps stay near the learning rate until the gradient
changes sign, so at MonoGS's rates that threshold is never reached and every frame runs its
whole budget. The rules here are relative, so that they mean the same at both budgets:

* ``relative-step``: the largest pose step has stayed below ``tolerance`` x the largest step
  of this frame for ``patience`` iterations in a row (Adam's steps shrink once the gradient's
  sign flips from one iteration to the next, i.e. around the optimum);
* ``plateau``: the best loss of the last ``patience`` iterations improved on the best before
  them by at most ``tolerance`` x its value.

``fixed`` keeps the budget (only the absolute threshold stops early). The same
:class:`ConvergenceTest` runs inside the tracker and, replayed over recorded traces, in
``benchmarks/tracking_convergence.py``.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np

ConvergenceRule = Literal["fixed", "relative-step", "plateau"]


class ConvergenceTest:
    """Fed one iteration at a time; says when the frame has converged under ``rule``.

    Args:
        rule: see the module docstring.
        tolerance: the relative step (``relative-step``) or relative loss improvement
            (``plateau``) below which an iteration counts as converged.
        patience: how many iterations the condition must hold / the window of the plateau.
    """

    def __init__(self, rule: ConvergenceRule, tolerance: float, patience: int) -> None:
        self.rule, self.tolerance, self.patience = rule, tolerance, patience
        self.largest_step = 0.0
        self.quiet = 0
        self.best: list[float] = []  # running best loss after each iteration

    def update(self, loss: float, step_norm: float) -> bool:
        """Record one iteration (its loss and largest twist step); True when tracking may
        stop after it."""
        if self.rule == "relative-step":
            self.largest_step = max(self.largest_step, step_norm)
            if step_norm < self.tolerance * self.largest_step:
                self.quiet += 1
            else:
                self.quiet = 0
            return self.quiet >= self.patience
        if self.rule == "plateau":
            best = min(loss, self.best[-1]) if self.best else loss
            self.best.append(best)
            if len(self.best) <= self.patience or not math.isfinite(best):
                return False
            before = self.best[-1 - self.patience]
            return before - best <= self.tolerance * abs(best)
        return False


def stop_iteration(losses: np.ndarray, step_norms: np.ndarray, rule: ConvergenceRule,
                   tolerance: float, patience: int, budget: int) -> int:
    """The number of iterations a frame would have run under ``rule``, replayed over its
    recorded per-iteration ``losses`` and ``step_norms`` [n] (``budget`` if it never
    triggers within them)."""
    test = ConvergenceTest(rule, tolerance, patience)
    for i, (loss, step) in enumerate(zip(losses, step_norms, strict=True)):
        if test.update(float(loss), float(step)):
            return i + 1
    return min(budget, len(losses)) if len(losses) else budget
