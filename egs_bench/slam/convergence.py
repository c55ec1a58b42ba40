"""When tracking may stop before its iteration budget (``tracking.convergence``).

MonoGS stops when the largest pose step falls below an absolute threshold
(``budget.converged_threshold``). Adam's steps stay near the learning rate until the gradient
changes sign, so at MonoGS's rates that threshold is never reached and every frame runs its
whole budget. The rules here are relative, so that they mean the same at both budgets:

* ``relative-step``: the largest pose step has stayed below ``tolerance`` x the largest step
  of this frame for ``patience`` iterations in a row (Adam's steps shrink once the gradient's
  sign flips from one iteration to the next, i.e. around the optimum);
* ``plateau``: the best loss of the last ``patience`` iterations improved on the best before
  them by at most ``tolerance`` x its value;
* ``net-motion``: over the last ``patience`` iterations ``T_tau`` got less than ``tolerance``
  of the way its steps went (the twist from the pose ``patience`` steps ago, against the sum of
  the step twists since): the steps go back and forth around an optimum, where a pose still
  moving towards one keeps going (a frame whose prediction is far off, such as frame 1 without
  a velocity, keeps its whole budget).

``fixed`` keeps the budget (only the absolute threshold stops early). The same
:class:`ConvergenceTest` runs inside the tracker and, replayed over recorded traces, in
``benchmarks/tracking_convergence.py``.
"""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np

from egs_bench.geometry.lie import so3_log
from egs_bench.slam.config import ConvergenceConfig, ConvergenceRule

__all__ = ["ConvergenceRule", "ConvergenceTest", "stop_iteration"]


class ConvergenceTest:
    """Fed one iteration at a time; says when the frame has converged under ``rule``.

    Args:
        rule: see the module docstring.
        tolerance: the relative step (``relative-step``) or relative loss improvement
            (``plateau``) below which an iteration counts as converged.
        patience: how many iterations the condition must hold / the window of the plateau.
    """

    #: the settings it reads (``tracking.convergence*``; :meth:`from_config`)
    Config: ClassVar[type[ConvergenceConfig]] = ConvergenceConfig

    def __init__(self, rule: ConvergenceRule, tolerance: float, patience: int) -> None:
        self.rule, self.tolerance, self.patience = rule, tolerance, patience
        self.largest_step = 0.0
        self.quiet = 0
        self.best: list[float] = []  # running best loss after each iteration
        self.poses: list[np.ndarray] = []  # T_tau after each iteration (net-motion)
        self.path: list[float] = []  # |twist| of each iteration's T_tau step

    @classmethod
    def from_config(cls, config: ConvergenceConfig) -> ConvergenceTest:
        """The test a frame runs under ``config`` (the ``tracking`` group, or any
        :class:`~egs_bench.slam.config.ConvergenceConfig`)."""
        return cls(config.convergence, config.convergence_tolerance,
                   config.convergence_patience)

    def update(self, loss: float, step_norm: float, pose1_cw: np.ndarray | None = None) -> bool:
        """Record one iteration: its loss, its largest twist step and (``net-motion``) the
        world-to-camera ``T_tau`` [4, 4] after it; True when tracking may stop after it."""
        if self.rule == "net-motion":
            if pose1_cw is None:
                raise ValueError("the net-motion rule needs the pose after each iteration")
            if self.poses:
                self.path.append(_twist_norm(pose1_cw, self.poses[-1]))
            self.poses.append(pose1_cw)
            if len(self.poses) <= self.patience:
                return False
            travelled = sum(self.path[-self.patience:])
            net = _twist_norm(pose1_cw, self.poses[-1 - self.patience])
            return travelled > 0 and net < self.tolerance * travelled
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


def _twist_norm(a_cw: np.ndarray, b_cw: np.ndarray) -> float:
    """``|(t, log R)|`` of the relative pose ``a b^-1`` (metres and radians, as the steps)."""
    rel = a_cw @ np.linalg.inv(b_cw)
    return float(np.linalg.norm(np.r_[rel[:3, 3], so3_log(rel[:3, :3])]))


def stop_iteration(losses: np.ndarray, step_norms: np.ndarray, poses1_cw: np.ndarray,
                   rule: ConvergenceRule, tolerance: float, patience: int, budget: int) -> int:
    """The number of iterations a frame would have run under ``rule``, replayed over its
    recorded per-iteration ``losses``, ``step_norms`` [n] and ``poses1_cw`` [n, 4, 4]
    (``budget`` if it never triggers within them)."""
    test = ConvergenceTest(rule, tolerance, patience)
    for i, (loss, step) in enumerate(zip(losses, step_norms, strict=True)):
        if test.update(float(loss), float(step), poses1_cw[i]):
            return i + 1
    return min(budget, len(losses)) if len(losses) else budget
