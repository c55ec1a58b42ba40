"""A small synthetic RGB-D view (room corner with textured walls and a sphere) turned into a
Gaussian map and rendered: the render example of docs/guide/other-systems.md and a quick
visual check."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch

from egs_bench.color import linear_to_srgb8, to_uint8
from egs_bench.geometry import Intrinsics
from egs_bench.images import write_ldr_image
from egs_bench.render.gaussian_map import GaussianMap


def synthetic_rgbd(width: int = 224, height: int = 128) -> tuple[np.ndarray, np.ndarray,
                                                                   Intrinsics]:
    """Ray-cast a box room (floor, back and side walls, checker/stripe textures) with a sphere,
    seen from the origin looking down +z (OpenCV axes).

    Returns: linear RGB [H, W, 3] float32 in [0, 1], depth [H, W] float32 metres, intrinsics.
    """
    intr = Intrinsics(0.8 * width, 0.8 * width, width / 2, height / 2, width, height)
    v, u = np.mgrid[0:height, 0:width].astype(np.float64)
    d = np.stack([(u + 0.5 - intr.cx) / intr.fx, (v + 0.5 - intr.cy) / intr.fy,
                  np.ones_like(u)], -1)  # ray directions with z = 1
    best = np.full((height, width), np.inf)
    rgb = np.zeros((height, width, 3))

    def plane(axis: int, value: float, colour_fn: Callable[[np.ndarray], np.ndarray]) -> None:
        with np.errstate(divide="ignore", invalid="ignore"):
            t = value / d[..., axis]
        hit = (t > 0) & (t < best)
        p = d * t[..., None]
        best[hit] = t[hit]
        rgb[hit] = colour_fn(p[hit])

    def checker(p: np.ndarray, a: int, b: int, c0: tuple[float, float, float],
                c1: tuple[float, float, float]) -> np.ndarray:
        k = (np.floor(p[:, a] * 2) + np.floor(p[:, b] * 2)) % 2
        return np.where(k[:, None] > 0, np.array(c0), np.array(c1))

    plane(2, 4.0, lambda p: checker(p, 0, 1, (0.75, 0.7, 0.6), (0.25, 0.3, 0.45)))  # back
    plane(1, 1.0, lambda p: checker(p, 0, 2, (0.8, 0.8, 0.8), (0.1, 0.1, 0.1)))  # floor
    plane(0, -2.0, lambda p: np.where(((p[:, 1] * 3) % 1 < 0.5)[:, None],
                                      np.array((0.7, 0.2, 0.2)), np.array((0.9, 0.8, 0.3))))
    plane(0, 2.0, lambda p: np.tile(np.array((0.2, 0.6, 0.3)), (p.shape[0], 1)))  # right wall
    # sphere of radius 0.6 at (0.3, 0.3, 2.5), shaded by a light from the upper left
    centre, radius = np.array([0.3, 0.3, 2.5]), 0.6
    b = (d * centre).sum(-1)
    dd = (d * d).sum(-1)
    disc = b * b - dd * (centre @ centre - radius**2)
    t = np.where(disc > 0, (b - np.sqrt(np.maximum(disc, 0))) / dd, np.inf)
    hit = (t > 0) & (t < best)
    n = (d[hit] * t[hit, None] - centre) / radius
    shade = 0.25 + 0.75 * np.clip(n @ np.array([-0.5, -0.6, -0.6]), 0, 1)
    rgb[hit] = shade[:, None] * np.array([0.2, 0.45, 0.9])
    best[hit] = t[hit]
    depth = np.where(np.isfinite(best), best, 0.0)  # t is z because ray z = 1
    return rgb.astype(np.float32), depth.astype(np.float32), intr


def render_demo(out_png: str | Path, width: int = 224, height: int = 128, downsample: int = 2,
                seed: int = 0) -> GaussianMap:
    """Build a map from :func:`synthetic_rgbd` (one view, ``add_from_depth``), render it from the
    same pose and from a pose moved 0.3 m right and turned 8 degrees, and save
    ``[input | render | depth | novel view]`` as an 8-bit sRGB PNG. Returns the map."""
    from egs_bench.render.rasterize import rasterize

    rgb, depth, intr = synthetic_rgbd(width, height)
    gmap = GaussianMap.empty()
    gmap.add_from_depth(rgb, depth, intr, np.eye(4), downsample=downsample, point_size=0.5,
                        opacity=0.9, generator=torch.Generator().manual_seed(seed))
    a = np.radians(8.0)
    T_wc = np.eye(4)
    T_wc[:3, :3] = [[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]]
    T_wc[0, 3] = 0.3
    viewmats = torch.tensor(np.stack([np.eye(4), np.linalg.inv(T_wc)]), dtype=torch.float32)
    Ks = torch.tensor(intr.K, dtype=torch.float32).expand(2, 3, 3)
    with torch.no_grad():
        out = rasterize(gmap.means, gmap.quats, gmap.scales, gmap.opacities, gmap.colors,
                        viewmats, Ks, width, height)

    import matplotlib

    dep = out.expected_depth[0].numpy()
    cmap = matplotlib.colormaps["viridis"]
    dep_rgb = to_uint8(cmap(np.clip(dep / max(depth.max(), 1e-6), 0, 1))[..., :3])
    dep_rgb[out.alpha[0].numpy() < 0.5] = 0
    gap = np.full((height, 4, 3), 255, np.uint8)
    panel = np.concatenate([linear_to_srgb8(rgb), gap, linear_to_srgb8(out.rgb[0].numpy()), gap,
                            dep_rgb, gap, linear_to_srgb8(out.rgb[1].numpy())], axis=1)
    write_ldr_image(out_png, panel)
    return gmap


def frame_map(gmap: GaussianMap, width: int, height: int) -> tuple[np.ndarray, Intrinsics]:
    """A camera-to-world pose [4,4] and intrinsics that show the whole map: axes aligned with the
    world, placed behind the map's bounding box on -z, 60 degree horizontal field of view."""
    pts = gmap.means.detach().cpu().double().numpy()
    if pts.shape[0] == 0:
        lo = hi = np.zeros(3)
    else:
        lo, hi = np.percentile(pts, 1, axis=0), np.percentile(pts, 99, axis=0)
    centre, half = (lo + hi) / 2, max(float(np.max(hi - lo)) / 2, 1e-3)
    f = 0.5 * width / np.tan(np.radians(30))
    pose = np.eye(4)
    pose[:3, 3] = [centre[0], centre[1], lo[2] - 1.2 * half / np.tan(np.radians(30))]
    return pose, Intrinsics(f, f, width / 2, height / 2, width, height)


def render_map_png(
    gmap: GaussianMap,
    out_png: str | Path,
    T_wc: np.ndarray | None = None,
    intrinsics: Intrinsics | None = None,
    width: int = 640,
    height: int = 480,
    backend: str = "auto",
) -> None:
    """Render ``gmap`` from camera-to-world pose ``T_wc`` [4,4] (default: :func:`frame_map`)
    and save it as an 8-bit sRGB PNG (linear colours are sRGB-encoded, clipped at 1)."""
    from egs_bench.render.rasterize import rasterize

    pose, intr = frame_map(gmap, width, height)
    pose = pose if T_wc is None else np.asarray(T_wc, dtype=np.float64)
    intr = intr if intrinsics is None else intrinsics
    view = torch.tensor(np.linalg.inv(pose)[None], dtype=gmap.dtype)
    K = torch.tensor(intr.K[None], dtype=gmap.dtype)
    with torch.no_grad():
        out = rasterize(gmap.means, gmap.quats, gmap.scales, gmap.opacities, gmap.colors, view,
                        K, intr.width, intr.height, backend=backend)  # type: ignore[arg-type]
    write_ldr_image(out_png, linear_to_srgb8(out.rgb[0].cpu().numpy()))
