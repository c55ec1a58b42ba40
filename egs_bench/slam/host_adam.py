"""Adam on a small float64 parameter vector on the host (poses and exposures of the SLAM).

The pose twists and exposure scalars a SLAM iteration optimises are a dozen numbers; keeping
them on the host lets their update run as a few numpy operations instead of device kernels,
and their gradients arrive with the one device-to-host copy per iteration that the SLAM makes
anyway. The update is ``torch.optim.Adam``'s (no weight decay, no amsgrad) with a learning rate
per element and an optional exponential decay (``torch.optim.lr_scheduler.ExponentialLR``),
tested equal to them.
"""

from __future__ import annotations

import numpy as np


class HostAdam:
    """Adam over a vector of ``n`` parameters with per-element learning rates.

    Args:
        lr: learning rates [n].
        gamma: the learning rates are multiplied by ``gamma`` after every step.
        betas, eps: as ``torch.optim.Adam``.
    """

    def __init__(self, lr: np.ndarray, gamma: float = 1.0,
                 betas: tuple[float, float] = (0.9, 0.999), eps: float = 1e-8) -> None:
        self.lr = np.array(lr, dtype=np.float64)
        self.gamma = float(gamma)
        self.beta1, self.beta2 = betas
        self.eps = float(eps)
        self.m = np.zeros_like(self.lr)
        self.v = np.zeros_like(self.lr)
        self.steps = 0

    def step(self, grad: np.ndarray) -> np.ndarray:
        """The parameter change [n] for gradient ``grad`` [n] (add it to the parameters)."""
        g = np.asarray(grad, dtype=np.float64)
        self.steps += 1
        self.m = self.beta1 * self.m + (1 - self.beta1) * g
        self.v = self.beta2 * self.v + (1 - self.beta2) * g * g
        bias1 = 1 - self.beta1 ** self.steps
        bias2_sqrt = np.sqrt(1 - self.beta2 ** self.steps)
        delta = -(self.lr / bias1) * self.m / (np.sqrt(self.v) / bias2_sqrt + self.eps)
        self.lr = self.lr * self.gamma
        return delta

    def skip(self, n: int) -> None:
        """Advance the learning-rate decay by ``n`` steps without an update (iterations a
        schedule leaves out)."""
        self.lr = self.lr * self.gamma ** n
