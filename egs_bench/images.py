"""Image files: the one module that reads and writes them (OpenCV codecs).

* LDR images: 8-bit sRGB, returned and taken as uint8 [H, W, 3] in RGB order (OpenCV's BGR is
  converted here and nowhere else). Grey and palette images are expanded to RGB, alpha is
  dropped; 16-bit or float colour images are refused rather than silently truncated.
* Depth PNGs: single-channel uint16 [H, W] (the scale to metres is the caller's business).
* :func:`image_header` and :func:`image_size` read only the header (with Pillow: OpenCV has no
  header-only read), so opening a sequence can check every image's size without decoding it.

Every reader raises :class:`~egs_bench.errors.InputError` naming the file; writers are atomic
(:func:`egs_bench.fileio.atomic_path`) and raise ``OSError`` when the encoder fails.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from egs_bench.errors import InputError
from egs_bench.fileio import atomic_path


def _decode(path: Path) -> np.ndarray:
    if not path.is_file():
        raise InputError(path, "image not found")
    data = np.fromfile(path, dtype=np.uint8)
    image = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data.size else None
    if image is None:
        raise InputError(path, "cannot read image (not a PNG/JPEG/BMP/TIFF file, or corrupt)")
    return image


def read_ldr_image(path: str | Path) -> np.ndarray:
    """Read an 8-bit image file as uint8 [H, W, 3] RGB (grey replicated, alpha dropped).

    Raises:
        InputError: missing file, undecodable data, or not an 8-bit grey/RGB(A) image.
    """
    path = Path(path)
    image = _decode(path)
    if image.dtype != np.uint8:
        raise InputError(path, f"expected an 8-bit image, found {image.dtype} samples")
    if image.ndim == 2:
        return np.ascontiguousarray(np.repeat(image[:, :, None], 3, axis=2))
    if image.ndim != 3 or image.shape[2] not in (3, 4):
        raise InputError(path, f"expected a grey or RGB image, found shape {image.shape}")
    return np.ascontiguousarray(image[:, :, 2::-1])


def write_ldr_image(path: str | Path, image: np.ndarray, jpeg_quality: int = 95,
                    jpeg_chroma_444: bool = False) -> Path:
    """Write uint8 [H, W, 3] RGB as a PNG (or a JPEG, by the suffix), atomically.

    ``jpeg_chroma_444`` keeps full-resolution colour in a JPEG (no 4:2:0 subsampling).
    """
    image = np.asarray(image)
    if image.dtype != np.uint8 or image.ndim != 3 or image.shape[2] != 3:
        raise ValueError(f"LDR image must be uint8 [H, W, 3], got {image.dtype} {image.shape}")
    params: list[int] = []
    if Path(path).suffix.lower() in (".jpg", ".jpeg"):
        params = [cv2.IMWRITE_JPEG_QUALITY, int(jpeg_quality)]
        if jpeg_chroma_444:
            params += [cv2.IMWRITE_JPEG_SAMPLING_FACTOR, cv2.IMWRITE_JPEG_SAMPLING_FACTOR_444]
    return _encode(Path(path), np.ascontiguousarray(image[:, :, ::-1]), params)


def read_depth_png(path: str | Path) -> np.ndarray:
    """Read a single-channel 16-bit PNG as uint16 [H, W].

    Raises:
        InputError: missing, undecodable, or not single-channel uint16.
    """
    path = Path(path)
    raw = _decode(path)
    if raw.dtype != np.uint16 or raw.ndim != 2:
        raise InputError(path, f"depth PNG must be single-channel uint16, got {raw.dtype} "
                               f"with shape {raw.shape}")
    return raw


def write_depth_png(path: str | Path, raw: np.ndarray) -> Path:
    """Write uint16 [H, W] as a 16-bit PNG, atomically."""
    raw = np.asarray(raw)
    if raw.dtype != np.uint16 or raw.ndim != 2:
        raise ValueError(f"depth PNG must be uint16 [H, W], got {raw.dtype} {raw.shape}")
    return _encode(Path(path), raw, [])


def _encode(path: Path, pixels: np.ndarray, params: list[int]) -> Path:
    suffix = path.suffix.lower() or ".png"
    ok, encoded = cv2.imencode(suffix, pixels, params)
    if not ok:
        raise OSError(f"could not encode {path.name} as {suffix}")
    with atomic_path(path) as tmp:
        tmp.write_bytes(encoded.tobytes())
    return path


def image_header(path: str | Path) -> tuple[int, int, str]:
    """``(width, height, mode)`` from the file header, without decoding the pixels; ``mode`` is
    Pillow's name of the pixel format (``"RGB"``, ``"L"``, ``"I;16"``, ...).

    Raises:
        InputError: missing or unreadable file.
    """
    from PIL import Image

    path = Path(path)
    try:
        with Image.open(path) as img:
            return img.size[0], img.size[1], img.mode
    except FileNotFoundError:
        raise InputError(path, "image not found") from None
    except Exception as exc:  # Pillow raises many kinds for bad files
        raise InputError(path, f"unreadable image ({exc})") from None


def image_size(path: str | Path) -> tuple[int, int]:
    """``(width, height)`` from the file header (see :func:`image_header`)."""
    width, height, _ = image_header(path)
    return width, height
