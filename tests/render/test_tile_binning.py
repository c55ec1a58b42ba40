"""Tile binning of the CPU backend against a NumPy statement of its contract: each tile lists
the Gaussians whose pixel box touches it, ordered by a stable sort of the depths (ties keep
the Gaussian id order), for short lists (insertion sort) and long ones (radix sort) alike."""

from __future__ import annotations

import numpy as np
import pytest

from egs_bench.render import numba_kernels as nk


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_depth_order_keys_order_as_the_floats(dtype: type) -> None:
    rng = np.random.default_rng(0)
    values: np.ndarray = np.concatenate([
        rng.normal(0, 10, 500), rng.uniform(0.2, 8.0, 500), np.repeat([1.5, -2.0], 20),
        [0.0, -0.0, 1e-40, -1e-40, np.inf, -np.inf, np.finfo(dtype).max, -np.finfo(dtype).max],
    ]).astype(dtype)
    keys = nk.depth_order_keys(values)
    assert keys.dtype == (np.uint32 if dtype == np.float32 else np.uint64)
    assert np.array_equal(np.argsort(keys, kind="stable"), np.argsort(values, kind="stable"))


def _expected_lists(mean2d: np.ndarray, ext: np.ndarray, depth: np.ndarray, width: int,
                    height: int) -> list[list[int]]:
    """Per camera tile ``k * T + t``: the ids whose box of pixel centres within
    ``mean +- ext`` meets the tile, in the order of a stable sort of all depths."""
    tile = nk.TILE
    tx_n, ty_n = -(-width // tile), -(-height // tile)
    lists: list[list[int]] = []
    for k in range(depth.shape[0]):
        per_tile: list[list[int]] = [[] for _ in range(tx_n * ty_n)]
        for g in np.argsort(depth[k], kind="stable"):
            (mx, my), (rx, ry) = mean2d[k, g], ext[k, g]
            if not rx > 0:
                continue
            u0, u1 = max(np.ceil(mx - rx - 0.5), 0), min(np.floor(mx + rx - 0.5), width - 1)
            v0, v1 = max(np.ceil(my - ry - 0.5), 0), min(np.floor(my + ry - 0.5), height - 1)
            if u0 > u1 or v0 > v1:
                continue
            for ty in range(int(v0) // tile, int(v1) // tile + 1):
                for tx in range(int(u0) // tile, int(u1) // tile + 1):
                    per_tile[ty * tx_n + tx].append(int(g))
        lists.extend(per_tile)
    return lists


@pytest.mark.parametrize("depth_dtype", [np.float32, np.float64])
def test_bin_tiles_lists_follow_a_stable_depth_sort(depth_dtype: type) -> None:
    rng = np.random.default_rng(1)
    n, width, height = 3000, 64, 48
    # quarter-pixel positions and radii: the boxes are exact in float32 and float64 alike
    mean2d = np.round(rng.uniform(-10, 74, (2, n, 2)) * 4) / 4
    ext = np.round(rng.uniform(0.25, 12, (2, n, 2)) * 4) / 4
    ext[1, 60:] = -1.0  # camera 1 sees 60 Gaussians: short lists, insertion-sorted
    ext[0, ::7] = -1.0  # culled
    # few distinct depths: many ties, which must keep the id order; half of them a unit in the
    # last place apart, so every radix digit decides some order
    ulp = np.spacing(depth_dtype(2.0))
    levels = np.concatenate([np.linspace(0.5, 6.0, 20, dtype=depth_dtype),
                             depth_dtype(2.0) + ulp * np.arange(20, dtype=depth_dtype)])
    depth = rng.choice(levels, (2, n))
    isect, offsets = nk.bin_tiles(mean2d, ext, nk.depth_order_keys(depth), width, height)
    expected = _expected_lists(mean2d, ext, depth, width, height)
    got = [isect[offsets[i]:offsets[i + 1]].tolist() for i in range(len(offsets) - 1)]
    lengths = [len(x) for x in expected]
    assert max(lengths) > 4 * nk.SMALL_TILE and 1 < min(x for x in lengths if x) <= nk.SMALL_TILE
    assert got == expected
