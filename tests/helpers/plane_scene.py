"""Test scene shared by several test files: a textured plane seen by a translating camera.

(A uniquely named module: ``from conftest import ...`` is ambiguous when several conftest.py
files are collected.)"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import numpy as np

    from egs_bench.datasets.pipeline import LatentFrame


class PlaneSource:
    """Test scene: a textured fronto-parallel plane at z = ``distance`` seen by a camera that
    translates along x at ``speed_mps``. Implements the pipeline's ``LatentSource`` protocol."""

    def __init__(self, width: int = 64, height: int = 48, speed_mps: float = 0.5,
                 distance: float = 2.0, gain: float = 1.5) -> None:
        import cv2
        import numpy as np
        from skimage import data

        from egs_bench.color import srgb_to_linear
        from egs_bench.geometry import Intrinsics

        self.intrinsics = Intrinsics(0.9 * width, 0.9 * width, width / 2, height / 2, width,
                                     height)
        tex = cv2.resize(data.astronaut(), (256, 256), interpolation=cv2.INTER_AREA)
        self.texture = (srgb_to_linear(tex / 255.0) * gain).astype(np.float32)
        self.texels_per_m = 128.0
        self.speed = speed_mps
        self.distance = distance

    def pose(self, t_us: int) -> np.ndarray:
        import numpy as np

        pose = np.eye(4)
        pose[0, 3] = self.speed * t_us * 1e-6
        return pose

    def render(self, t_us: int) -> LatentFrame:
        import cv2
        import numpy as np

        from egs_bench.datasets.pipeline import LatentFrame

        cam = self.intrinsics
        pose = self.pose(t_us)
        u = (np.arange(cam.width) + 0.5 - cam.cx) / cam.fx * self.distance + pose[0, 3]
        v = (np.arange(cam.height) + 0.5 - cam.cy) / cam.fy * self.distance
        map_x, map_y = np.meshgrid(u * self.texels_per_m + 128.0, v * self.texels_per_m + 128.0)
        rgb = cv2.remap(self.texture, map_x.astype(np.float32), map_y.astype(np.float32),
                        cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP)
        depth = np.full((cam.height, cam.width), self.distance, dtype=np.float32)
        return LatentFrame(rgb=rgb.astype(np.float32), depth=depth, pose=pose)


def make_plane_sequence(out: Path, frames: int = 4, **kwargs: Any) -> Path:
    """Generate a tiny canonical sequence of the :class:`PlaneSource` scene (30 fps, 15 ms)."""
    import numpy as np

    from egs_bench.datasets.pipeline import generate_sequence

    source = PlaneSource(**kwargs)
    t_end = 20_000 + np.arange(frames, dtype=np.int64) * 33_333
    return generate_sequence(source, t_end - 15_000, t_end, out, progress=False,
                             meta_extra={"source": "tests.PlaneSource"})
