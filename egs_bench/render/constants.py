"""The per-pixel compositing rule shared by every backend (docs/design.md §5), in one place.

For each pixel, Gaussians are visited in increasing camera depth ``z``:

* ``power = -0.5 * (a dx^2 + c dy^2) - b dx dy`` with ``(a, b, c)`` the conic (inverse of the
  dilated 2-D covariance ``Sigma_2d + EPS2D * I``) and ``(dx, dy)`` = pixel centre - 2-D mean;
  skip when ``power > 0``;
* ``alpha = min(ALPHA_MAX, opacity * exp(power))``; skip when ``alpha < ALPHA_MIN``;
* stop (this Gaussian excluded) when ``T * (1 - alpha) < T_MIN``;
* otherwise ``rgb += alpha T c``, ``depth += alpha T z``, ``T *= 1 - alpha``.

Gaussians with camera ``z <= near_plane`` or ``z >= far_plane`` are culled. The values are those
of the original 3DGS / MonoGS CUDA rasteriser. gsplat (the CUDA backend) hard-codes
``ALPHA_MAX = 0.999`` and stops on ``<=`` instead of ``<``; see ``gsplat_backend``.
"""

from __future__ import annotations

TILE_SIZE: int = 16
"""Tiles are ``TILE_SIZE x TILE_SIZE`` pixels (CPU kernels; also passed to gsplat)."""

ALPHA_MAX: float = 0.99
"""Upper clamp of a single Gaussian's alpha (keeps ``1 - alpha`` invertible in the backward)."""

ALPHA_MIN: float = 1.0 / 255.0
"""Alphas below this are skipped (they are not composited at all)."""

T_MIN: float = 1e-4
"""Compositing stops before the transmittance would drop below this."""

EPS2D: float = 0.3
"""Screen-space dilation (px^2) added to the diagonal of every 2-D covariance."""

FOV_CLAMP: float = 0.3
"""The perspective Jacobian is evaluated at ``x/z`` clamped to the image extent plus this
fraction of the half field of view on each side (gsplat's form of the 3DGS 1.3 x FOV clamp)."""

NEAR_PLANE: float = 0.01
"""Default near plane (metres), as gsplat. MonoGS culls at 0.2 m: pass ``near_plane=0.2``."""

FAR_PLANE: float = 1e10
"""Default far plane (metres)."""

TOUCH_T: float = 0.5
"""A Gaussian is *visible* in a camera (MonoGS's "touched") if it contributed to some pixel and
the transmittance right after it was still above this."""
