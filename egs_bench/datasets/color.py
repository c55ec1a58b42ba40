"""Colour transforms: exact sRGB encode/decode, BT.601 luma, and the camera response to LDR.

All physics in egs-bench (blur averaging, events, the SLAM's scene radiance) happens in linear
intensity; LDR images on disk are 8-bit sRGB (DESIGN §2).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from egs_bench.errors import ConfigError

LUMA_BT601 = (0.299, 0.587, 0.114)


def srgb_to_linear(srgb: np.ndarray) -> np.ndarray:
    """sRGB EOTF (IEC 61966-2-1): encoded values in [0, 1] -> linear intensity in [0, 1]."""
    srgb = np.asarray(srgb, dtype=np.float32)
    return np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4).astype(
        np.float32
    )


def linear_to_srgb(linear: np.ndarray) -> np.ndarray:
    """Inverse sRGB EOTF: linear intensity in [0, 1] -> encoded values in [0, 1] (clipped)."""
    lin = np.clip(np.asarray(linear, dtype=np.float32), 0.0, 1.0)
    return np.where(lin <= 0.0031308, lin * 12.92, 1.055 * lin ** (1 / 2.4) - 0.055).astype(
        np.float32
    )


def luma(rgb_linear: np.ndarray) -> np.ndarray:
    """BT.601 luma of linear RGB: [..., 3] -> [...] (dtype of the input, float)."""
    rgb = np.asarray(rgb_linear)
    return rgb @ np.asarray(LUMA_BT601, dtype=rgb.dtype if rgb.dtype.kind == "f" else np.float64)


@dataclass(frozen=True)
class CameraResponse:
    """Maps linear radiance to 8-bit LDR: ``encode(clip(gain * radiance, 0, 1))``, quantised.

    Attributes:
        kind: ``"srgb"`` (exact sRGB encoding) or ``"gamma"`` (``x ** (1 / gamma)``).
        gain: exposure gain applied before clipping; > 1 saturates bright parts.
        gamma: exponent for ``kind="gamma"``.
    """

    kind: str = "srgb"
    gain: float = 1.0
    gamma: float = 2.2

    def __post_init__(self) -> None:
        if self.kind not in ("srgb", "gamma"):
            raise ConfigError(f"camera response kind must be 'srgb' or 'gamma', not {self.kind!r}")
        if not self.gain > 0 or not self.gamma > 0:
            raise ConfigError("camera response gain and gamma must be positive")

    def to_float(self, radiance: np.ndarray) -> np.ndarray:
        """Radiance [..., 3] (linear, >= 0) -> LDR in [0, 1] before quantisation."""
        x = np.clip(np.asarray(radiance, dtype=np.float32) * self.gain, 0.0, 1.0)
        if self.kind == "srgb":
            return linear_to_srgb(x)
        return (x ** (1.0 / self.gamma)).astype(np.float32)

    def to_ldr(self, radiance: np.ndarray) -> np.ndarray:
        """Radiance [..., 3] -> uint8 LDR (round to nearest)."""
        return np.round(self.to_float(radiance) * 255.0).astype(np.uint8)

    def inverse(self, ldr: np.ndarray) -> np.ndarray:
        """uint8 or [0,1] LDR -> linear radiance (exact where not saturated)."""
        x = np.asarray(ldr, dtype=np.float32)
        if np.asarray(ldr).dtype == np.uint8:
            x = x / 255.0
        lin = srgb_to_linear(x) if self.kind == "srgb" else x**self.gamma
        return (lin / self.gain).astype(np.float32)

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["description"] = (
            "LDR = round(255 * encode(clip(gain * radiance, 0, 1))), "
            + ("encode = sRGB (IEC 61966-2-1)" if self.kind == "srgb" else f"x^(1/{self.gamma})")
        )
        return out

    @staticmethod
    def from_dict(data: dict[str, Any]) -> CameraResponse:
        return CameraResponse(
            kind=str(data.get("kind", "srgb")),
            gain=float(data.get("gain", 1.0)),
            gamma=float(data.get("gamma", 2.2)),
        )
