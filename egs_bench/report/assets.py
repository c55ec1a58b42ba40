"""The report's shared files: downscaled images and figures named by their content.

Every image or figure a page shows is stored once under ``<report>/assets/`` as
``<sha256 prefix>.png``: the observed frame and the sharp ground truth shown on every run page
of a sequence, or two runs' identical renders, take the space of one file. Images are
downscaled (area average) to at most :data:`THUMB_WIDTH` pixels wide before they are hashed and
written, so a report's size grows with the number of distinct pictures, not with the sequences'
resolution.
"""

from __future__ import annotations

import hashlib
import os
import shutil
from collections.abc import Callable
from importlib import resources
from pathlib import Path

import numpy as np

from egs_bench.images import write_ldr_image

ASSETS_DIR = "assets"
#: Widest stored frame thumbnail, pixels.
THUMB_WIDTH = 320
#: Widest stored image strip, pixels (a page shows it at most 1200 px wide).
STRIP_WIDTH = 2000
#: The page style, its script and the 3D viewer (three.js + Spark, built from
#: ``viewer_src/``) with its licences, copied from the package next to the images.
STATIC_FILES = ("report.css", "report.js", "viewer.js", "viewer.LICENSE-three.txt",
                "viewer.LICENSE-spark.txt", "viewer.LICENSE-fflate.txt")
_HASH_CHARS = 16


def downscale(image: np.ndarray, max_width: int) -> np.ndarray:
    """``image`` (uint8 [H, W, 3]) shrunk by area averaging to at most ``max_width`` pixels wide,
    aspect ratio kept; returned as it is when already narrow enough."""
    import cv2

    h, w = image.shape[:2]
    if w <= max_width:
        return image
    size = (max_width, max(1, round(h * max_width / w)))
    return cv2.resize(np.ascontiguousarray(image), size, interpolation=cv2.INTER_AREA)


class AssetStore:
    """Content-addressed files under ``<root>/assets``; paths returned relative to ``root``.

    Attributes:
        root: the report folder being built.
        written: number of distinct files stored.
        reused: number of requests answered by a file already stored.
    """

    def __init__(self, root: Path) -> None:
        self.root = root
        self.dir = root / ASSETS_DIR
        self.dir.mkdir(parents=True, exist_ok=True)
        self.written = 0
        self.reused = 0
        self._tmp = 0

    def _name(self, digest: str) -> Path:
        return self.dir / f"{digest[:_HASH_CHARS]}.png"

    def _rel(self, path: Path) -> str:
        return f"{ASSETS_DIR}/{path.name}"

    def image(self, image: np.ndarray, max_width: int = THUMB_WIDTH) -> str:
        """Store ``image`` (uint8 [H, W, 3] sRGB) downscaled to ``max_width``; returns its path."""
        small = np.ascontiguousarray(downscale(image, max_width))
        digest = hashlib.sha256(repr(small.shape).encode() + small.tobytes()).hexdigest()
        path = self._name(digest)
        if path.exists():
            self.reused += 1
        else:
            write_ldr_image(path, small)
            self.written += 1
        return self._rel(path)

    def figure(self, draw: Callable[[Path], Path], max_width: int | None = None) -> str:
        """Store the PNG ``draw(path)`` writes at ``path``, downscaled to ``max_width`` pixels
        when wider; returns the stored file's path."""
        from egs_bench.images import read_ldr_image

        self._tmp += 1
        tmp = self.dir / f".figure-{self._tmp}.png"
        draw(tmp)
        if max_width is not None:
            pixels = read_ldr_image(tmp)
            if pixels.shape[1] > max_width:
                write_ldr_image(tmp, downscale(pixels, max_width))
        digest = hashlib.sha256(tmp.read_bytes()).hexdigest()
        path = self._name(digest)
        if path.exists():
            tmp.unlink()
            self.reused += 1
        else:
            os.replace(tmp, path)
            self.written += 1
        return self._rel(path)

    def copy_static(self) -> None:
        """Copy the style sheet and the sort/filter script into the assets folder."""
        package = resources.files("egs_bench.report") / "static"
        for name in STATIC_FILES:
            with resources.as_file(package / name) as src:
                shutil.copyfile(src, self.dir / name)
