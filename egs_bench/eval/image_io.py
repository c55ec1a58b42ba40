"""Reading 8-bit LDR images (renders, references) with a clear error for bad files."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from egs_bench.errors import InputError


def read_ldr_image(path: str | Path) -> np.ndarray:
    """Read an 8-bit image file as uint8 [H, W, 3] (grey is replicated, alpha dropped).

    Raises:
        InputError: missing file, undecodable data, or not 8-bit grey/RGB(A).
    """
    from PIL import Image, UnidentifiedImageError

    path = Path(path)
    if not path.is_file():
        raise InputError(path, "image not found")
    try:
        with Image.open(path) as im:
            mode = im.mode
            if mode not in ("L", "RGB", "RGBA", "P"):
                raise InputError(path, f"expected an 8-bit grey or RGB image, found mode {mode}")
            img = np.asarray(im.convert("RGB"))
    except (UnidentifiedImageError, OSError, ValueError) as exc:
        raise InputError(path, f"cannot read image ({exc})") from None
    return np.ascontiguousarray(img)
