"""Photographic textures from scikit-image's bundled images, linearised and mip-mapped.

Every texture is centre-cropped to a square, resized to ``TEXTURE_SIZE`` (a power of two) with
area averaging, converted from sRGB to linear intensity, and reduced into a mip pyramid by exact
2x2 box averages (the mean of linear radiance, which is what a sensor integrates). The ray
caster picks a pyramid level from each sample's footprint so that textures seen from far away
do not alias (aliasing would flicker under motion and fire spurious events).

Storage for numba: one flat ``float32 [T, 3]`` texel array, ``offsets [n_textures, n_levels]``
into it; level ``l`` is ``size >> l`` texels on a side.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np
from skimage import data as skdata

from egs_bench.color import srgb_to_linear

TEXTURE_SIZE = 512

# name -> loader of an sRGB uint8 image bundled with scikit-image (no download).
_SOURCES: dict[str, Callable[[], np.ndarray]] = {
    "brick": skdata.brick,
    "gravel": skdata.gravel,
    "grass": skdata.grass,
    "astronaut": skdata.astronaut,
    "coffee": skdata.coffee,
    "chelsea": skdata.chelsea,
    "rocket": skdata.rocket,
    "camera": skdata.camera,
    "moon": skdata.moon,
    "colorwheel": skdata.colorwheel,
    "hubble": skdata.hubble_deep_field,
    "ihc": skdata.immunohistochemistry,
    "page": skdata.page,
    "clock": skdata.clock,
    "coins": skdata.coins,
    "checkerboard": skdata.checkerboard,
}

# Crops (y0, y1, x0, x1) applied before squaring: the checkerboard's outer ring of squares has
# other grey levels, the inner 6x6 squares tile seamlessly.
_CROPS: dict[str, tuple[int, int, int, int]] = {"checkerboard": (25, 175, 25, 175)}

# Grey surface textures (tiled on walls and floors) are rescaled to a linear mean of 1 (a relative
# albedo modulation), so a material's colour is its mean albedo; photographs keep their values.
SURFACE_TEXTURES = frozenset({"brick", "gravel", "grass", "checkerboard"})


def available_textures() -> list[str]:
    """Names of the textures that scenes may use."""
    return sorted(_SOURCES)


def load_texture(name: str, size: int = TEXTURE_SIZE) -> np.ndarray:
    """One texture as linear RGB, float32 ``[size, size, 3]``.

    Photographs are linear values in ``[0, 1]``. Grey images are replicated to three channels
    (scenes tint them with a material colour); :data:`SURFACE_TEXTURES` are divided by their
    mean (so they modulate the material colour around 1).
    """
    if name not in _SOURCES:
        raise KeyError(f"unknown texture {name!r}; available: {', '.join(available_textures())}")
    img = np.asarray(_SOURCES[name]())
    if img.dtype == bool:
        img = img.astype(np.uint8) * 255
    if img.ndim == 2:
        img = np.repeat(img[:, :, None], 3, axis=2)
    img = img[:, :, :3]
    if name in _CROPS:
        y0, y1, x0, x1 = _CROPS[name]
        img = img[y0:y1, x0:x1]
    h, w = img.shape[:2]
    side = min(h, w)
    y0, x0 = (h - side) // 2, (w - side) // 2
    img = np.ascontiguousarray(img[y0 : y0 + side, x0 : x0 + side])
    interp = cv2.INTER_AREA if side >= size else cv2.INTER_CUBIC
    img = cv2.resize(img, (size, size), interpolation=interp)
    linear = srgb_to_linear(img.astype(np.float32) / 255.0)
    if name in SURFACE_TEXTURES:
        linear = linear / linear.mean()
    return linear.astype(np.float32)


def mip_pyramid(texture: np.ndarray) -> list[np.ndarray]:
    """Mip levels of a square power-of-two texture ``[S, S, 3]``: 2x2 box means down to 1x1."""
    size = texture.shape[0]
    if texture.shape[1] != size or size & (size - 1):
        raise ValueError(f"texture must be square with a power-of-two side, got {texture.shape}")
    levels = [texture.astype(np.float32)]
    while levels[-1].shape[0] > 1:
        t = levels[-1]
        s = t.shape[0] // 2
        levels.append(t.reshape(s, 2, s, 2, 3).mean(axis=(1, 3), dtype=np.float32))
    return levels


@dataclass(frozen=True)
class TextureBank:
    """Mip-mapped textures packed for the numba ray caster.

    Attributes:
        names: texture names; a material refers to a texture by its index here.
        texels: all levels of all textures, float32 ``[T, 3]`` linear RGB.
        offsets: start row in ``texels`` of texture ``i``, level ``l``: int64 ``[n, n_levels]``.
        size: side of level 0 in texels (power of two).
    """

    names: tuple[str, ...]
    texels: np.ndarray
    offsets: np.ndarray
    size: int

    @property
    def n_levels(self) -> int:
        return int(self.offsets.shape[1])

    def index(self, name: str) -> int:
        return self.names.index(name)

    def level(self, texture: int, level: int) -> np.ndarray:
        """View of one pyramid level as ``[s, s, 3]``."""
        s = self.size >> level
        start = int(self.offsets[texture, level])
        return self.texels[start : start + s * s].reshape(s, s, 3)


_CACHE: dict[tuple[tuple[str, ...], int], TextureBank] = {}


def build_texture_bank(names: tuple[str, ...] | list[str], size: int = TEXTURE_SIZE) -> TextureBank:
    """Load, linearise and mip-map the named textures (cached per process)."""
    key = (tuple(names), size)
    if key in _CACHE:
        return _CACHE[key]
    n_levels = int(np.log2(size)) + 1
    chunks: list[np.ndarray] = []
    offsets = np.zeros((len(names), n_levels), dtype=np.int64)
    cursor = 0
    for i, name in enumerate(names):
        for lvl, img in enumerate(mip_pyramid(load_texture(name, size))):
            offsets[i, lvl] = cursor
            chunks.append(img.reshape(-1, 3))
            cursor += img.shape[0] * img.shape[1]
    texels = (
        np.ascontiguousarray(np.concatenate(chunks), dtype=np.float32)
        if chunks
        else np.zeros((1, 3), np.float32)
    )
    if not chunks:
        offsets = np.zeros((0, n_levels), dtype=np.int64)
    bank = TextureBank(tuple(names), texels, offsets, size)
    _CACHE[key] = bank
    return bank
