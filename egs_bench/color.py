"""Colour: the sRGB transfer functions, BT.601 luma, 8-bit quantisation, the camera response.

The one place these are written; every module (generators, SLAM losses and CRFs, renders,
evaluation) uses them. Conventions (docs/design.md §2):

* LDR images on disk are 8-bit sRGB; all physics (blur averaging, events, the SLAM's scene
  radiance) is in linear intensity.
* sRGB: the exact piecewise IEC 61966-2-1 curves, inputs clipped to [0, 1].
* Luma: BT.601 weights on *linear* RGB, ``B = 0.299 R + 0.587 G + 0.114 B``.
* Quantisation to 8 bits: ``round(255 * clip(x, 0, 1))`` with ties to even (numpy's and torch's
  ``round``), everywhere: generated frames, SLAM renders, demo images.

The functions accept numpy arrays or torch tensors and return the same kind; numpy results keep
a floating input's dtype (float32 stays float32), integer input becomes float32. Torch is
imported only when a tensor is passed.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Any, Literal, overload

import numpy as np

from egs_bench.errors import ConfigError

if TYPE_CHECKING:
    import torch

LUMA_BT601 = (0.299, 0.587, 0.114)
# IEC 61966-2-1 break points: encoded 0.04045 <-> linear 0.0031308
_SRGB_LINEAR_BREAK = 0.0031308
_SRGB_ENCODED_BREAK = 0.04045


def _is_tensor(x: object) -> bool:
    return type(x).__module__.split(".")[0] == "torch"


def _float_array(x: Any) -> np.ndarray:
    arr = np.asarray(x)
    return arr if arr.dtype.kind == "f" else arr.astype(np.float32)


@overload
def srgb_to_linear(encoded: np.ndarray) -> np.ndarray: ...
@overload
def srgb_to_linear(encoded: torch.Tensor) -> torch.Tensor: ...
def srgb_to_linear(encoded: Any) -> Any:
    """sRGB EOTF: encoded values in [0, 1] (clipped) -> linear intensity in [0, 1]."""
    if _is_tensor(encoded):
        import torch

        s = encoded.clamp(0.0, 1.0)
        return torch.where(s <= _SRGB_ENCODED_BREAK, s / 12.92, ((s + 0.055) / 1.055) ** 2.4)
    s = np.clip(_float_array(encoded), 0.0, 1.0)
    return np.where(s <= _SRGB_ENCODED_BREAK, s / 12.92, ((s + 0.055) / 1.055) ** 2.4)


@overload
def linear_to_srgb(linear: np.ndarray) -> np.ndarray: ...
@overload
def linear_to_srgb(linear: torch.Tensor) -> torch.Tensor: ...
def linear_to_srgb(linear: Any) -> Any:
    """Inverse sRGB EOTF: linear intensity (clipped to [0, 1]) -> encoded values in [0, 1].

    For tensors the power branch is evaluated at ``max(x, 1e-12)``, so its gradient stays finite
    where ``torch.where`` does not select it (x = 0).
    """
    if _is_tensor(linear):
        import torch

        x = linear.clamp(0.0, 1.0)
        return torch.where(x <= _SRGB_LINEAR_BREAK, x * 12.92,
                           1.055 * x.clamp_min(1e-12) ** (1 / 2.4) - 0.055)
    x = np.clip(_float_array(linear), 0.0, 1.0)
    return np.where(x <= _SRGB_LINEAR_BREAK, x * 12.92, 1.055 * x ** (1 / 2.4) - 0.055)


@overload
def luma(rgb_linear: np.ndarray) -> np.ndarray: ...
@overload
def luma(rgb_linear: torch.Tensor) -> torch.Tensor: ...
def luma(rgb_linear: Any) -> Any:
    """BT.601 luma of linear RGB: [..., 3] -> [...] (float dtype of the input)."""
    if _is_tensor(rgb_linear):
        import torch

        w = torch.tensor(LUMA_BT601, dtype=rgb_linear.dtype, device=rgb_linear.device)
        return rgb_linear @ w
    rgb = _float_array(rgb_linear)
    return rgb @ np.asarray(LUMA_BT601, dtype=rgb.dtype)


@overload
def to_uint8(values: np.ndarray) -> np.ndarray: ...
@overload
def to_uint8(values: torch.Tensor) -> torch.Tensor: ...
def to_uint8(values: Any) -> Any:
    """Quantise values in [0, 1] (clipped) to 8 bits: ``round(255 x)``, ties to even."""
    if _is_tensor(values):
        import torch

        return torch.round(values.clamp(0.0, 1.0) * 255.0).to(torch.uint8)
    return np.round(np.clip(_float_array(values), 0.0, 1.0) * 255.0).astype(np.uint8)


def from_uint8(image: np.ndarray) -> np.ndarray:
    """8-bit values -> float32 in [0, 1] (``x / 255``)."""
    return np.asarray(image).astype(np.float32) / np.float32(255.0)


def linear_to_srgb8(linear: np.ndarray) -> np.ndarray:
    """Linear RGB [..., 3] -> 8-bit sRGB (clipped at 1, the display convention of renders)."""
    return to_uint8(linear_to_srgb(np.asarray(linear)))


@dataclass(frozen=True)
class LdrResponse:
    """The camera response of a sequence: linear radiance -> 8-bit LDR,
    ``round(255 * encode(clip(gain * radiance, 0, 1)))``. Recorded in ``meta.yaml`` (``crf``).

    (The SLAM's *estimate* of a response is a different object: :mod:`egs_bench.slam.crf`.)

    Attributes:
        kind: ``"srgb"`` (exact sRGB encoding) or ``"gamma"`` (``x ** (1 / gamma)``).
        gain: exposure gain applied before clipping; > 1 saturates bright parts.
        gamma: exponent for ``kind="gamma"``.
    """

    kind: Literal["srgb", "gamma"] = "srgb"
    gain: float = 1.0
    gamma: float = 2.2

    def __post_init__(self) -> None:
        if self.kind not in ("srgb", "gamma"):
            raise ConfigError(f"camera response kind must be 'srgb' or 'gamma', not {self.kind!r}")
        if not self.gain > 0 or not self.gamma > 0:
            raise ConfigError("camera response gain and gamma must be positive")

    def to_float(self, radiance: np.ndarray) -> np.ndarray:
        """Radiance [..., 3] (linear, >= 0) -> LDR in [0, 1] before quantisation (float32)."""
        x = np.clip(np.asarray(radiance, dtype=np.float32) * self.gain, 0.0, 1.0)
        if self.kind == "srgb":
            return linear_to_srgb(x)
        return (x ** (1.0 / self.gamma)).astype(np.float32)

    def to_ldr(self, radiance: np.ndarray) -> np.ndarray:
        """Radiance [..., 3] -> uint8 LDR (:func:`to_uint8`)."""
        return to_uint8(self.to_float(radiance))

    def inverse(self, ldr: np.ndarray) -> np.ndarray:
        """uint8 or [0,1] LDR -> linear radiance (exact where not saturated), float32."""
        x = from_uint8(ldr) if np.asarray(ldr).dtype == np.uint8 \
            else np.asarray(ldr, dtype=np.float32)
        lin = srgb_to_linear(x) if self.kind == "srgb" else x ** np.float32(self.gamma)
        return (lin / np.float32(self.gain)).astype(np.float32)

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["description"] = (
            "LDR = round(255 * encode(clip(gain * radiance, 0, 1))), "
            + ("encode = sRGB (IEC 61966-2-1)" if self.kind == "srgb" else f"x^(1/{self.gamma})")
        )
        return out

    @staticmethod
    def from_dict(data: dict[str, Any]) -> LdrResponse:
        return LdrResponse(
            kind=data.get("kind", "srgb"),  # checked by __post_init__
            gain=float(data.get("gain", 1.0)),
            gamma=float(data.get("gamma", 2.2)),
        )
