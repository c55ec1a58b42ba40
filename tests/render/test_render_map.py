"""GaussianMap: insertion from depth, pruning, .ply round trip."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
from plyfile import PlyData

from egs_bench.errors import InputError
from egs_bench.geometry import Intrinsics
from egs_bench.render import GaussianMap
from egs_bench.render.ply import SH_C0, load_ply, save_ply


def _plane(h: int = 24, w: int = 32, z: float = 2.0
           ) -> tuple[np.ndarray, np.ndarray, Intrinsics]:
    intr = Intrinsics(40.0, 40.0, w / 2, h / 2, w, h)
    depth = np.full((h, w), z, np.float32)
    depth[:3] = 0.0  # invalid rows
    rgb = np.random.default_rng(0).random((h, w, 3)).astype(np.float32)
    return rgb, depth, intr


def _pose() -> np.ndarray:
    a = np.radians(20)
    T = np.eye(4)
    T[:3, :3] = [[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]]
    T[:3, 3] = [0.5, -0.2, 1.0]
    return T


def test_add_from_depth_full_resolution_geometry_colour_and_scale() -> None:
    rgb, depth, intr = _plane()
    T = _pose()
    m = GaussianMap.empty(torch.float64)
    n = m.add_from_depth(rgb, depth, intr, T, downsample=1, point_size=0.05, keyframe_id=3)
    assert n == len(m) == (depth > 0).sum()
    # back in the camera frame every point lies on the plane z = 2 at its pixel's ray
    pc = (m.means.numpy() - T[:3, 3]) @ T[:3, :3]
    np.testing.assert_allclose(pc[:, 2], 2.0, atol=1e-12)
    uv = intr.project(pc)
    np.testing.assert_allclose(uv - np.floor(uv), 0.5, atol=1e-9)  # through pixel centres
    iu, iv = np.floor(uv).astype(int).T
    np.testing.assert_allclose(m.colors.numpy(), rgb[iv, iu], atol=1e-6)
    # a regular grid with spacing z/f: each point's 3 nearest neighbours are at one spacing
    # (diagonals are farther), so sigma = sqrt(point_size) * spacing, isotropic
    spacing = 2.0 / 40.0
    inner = (iu > 0) & (iu < 31) & (iv > 3) & (iv < 23)
    np.testing.assert_allclose(m.scales.numpy()[inner], np.sqrt(0.05) * spacing, rtol=1e-9)
    assert torch.equal(m.rotations, torch.tensor([1.0, 0, 0, 0]).double().expand(n, 4))
    np.testing.assert_allclose(m.opacities.numpy(), 0.5)
    assert (m.keyframe_ids == 3).all()


def test_add_from_depth_downsampling_is_random_and_seeded() -> None:
    rgb, depth, intr = _plane()
    valid = int((depth > 0).sum())
    a, b, c = GaussianMap.empty(), GaussianMap.empty(), GaussianMap.empty()
    na = a.add_from_depth(rgb, depth, intr, np.eye(4), downsample=8,
                          generator=torch.Generator().manual_seed(1))
    b.add_from_depth(rgb, depth, intr, np.eye(4), downsample=8,
                     generator=torch.Generator().manual_seed(1))
    c.add_from_depth(rgb, depth, intr, np.eye(4), downsample=8,
                     generator=torch.Generator().manual_seed(2))
    assert na == int(np.ceil(valid / 8))
    assert torch.equal(a.means, b.means) and not torch.equal(a.means, c.means)
    assert a.add_from_depth(rgb, np.zeros_like(depth), intr, np.eye(4)) == 0


def test_add_from_depth_rejects_srgb_uint8_and_wrong_shapes() -> None:
    rgb, depth, intr = _plane()
    m = GaussianMap.empty()
    with pytest.raises(ValueError, match="linear"):
        m.add_from_depth((rgb * 255).astype(np.uint8), depth, intr, np.eye(4))
    with pytest.raises(ValueError, match="match"):
        m.add_from_depth(rgb[:-1], depth[:-1], intr, np.eye(4))


def test_rendering_the_inserted_map_reproduces_the_depth() -> None:
    rgb, depth, intr = _plane(z=3.0)
    m = GaussianMap.empty()
    m.add_from_depth(rgb, depth, intr, np.eye(4), downsample=1, point_size=1.0, opacity=0.99)
    out = m.render(torch.eye(4)[None], torch.tensor(intr.K, dtype=torch.float32)[None], 32, 24)
    solid = out.alpha[0] > 0.95
    assert solid[8:20, 6:26].all()
    torch.testing.assert_close(out.expected_depth[0][solid],
                               torch.full_like(out.expected_depth[0][solid], 3.0), atol=1e-4,
                               rtol=0)


def test_prune_removes_masked_gaussians() -> None:
    rgb, depth, intr = _plane()
    m = GaussianMap.empty()
    m.add_from_depth(rgb, depth, intr, np.eye(4), downsample=1)
    before = m.means.clone()
    mask = torch.zeros(len(m), dtype=torch.bool)
    mask[::3] = True
    assert m.prune(mask) == int(mask.sum())
    assert torch.equal(m.means, before[~mask]) and len(m.keyframe_ids) == len(m)
    with pytest.raises(ValueError, match="bool"):
        m.prune(torch.zeros(len(m)))


def test_ply_round_trip_and_standard_layout(tmp_path: Path) -> None:
    rgb, depth, intr = _plane()
    m = GaussianMap.empty()
    m.add_from_depth(rgb * 2.0, depth, intr, _pose(), downsample=2)  # HDR colours survive
    m.quats = torch.nn.functional.normalize(torch.randn(len(m), 4), dim=-1)
    m.opacity_logits = torch.randn(len(m))
    path = tmp_path / "map.ply"
    save_ply(m, path)
    back = load_ply(path)
    for name, t in m.parameters().items():
        torch.testing.assert_close(getattr(back, name), t, atol=2e-6, rtol=2e-6, msg=name)
    ply = PlyData.read(str(path))
    names = [p.name for p in ply["vertex"].properties]
    assert names[:9] == ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"]
    assert names[9:] == ["opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2",
                         "rot_3"]
    np.testing.assert_allclose(np.asarray(ply["vertex"]["f_dc_0"]),
                               (m.colors[:, 0].numpy() - 0.5) / SH_C0, rtol=1e-5, atol=1e-5)


def test_load_ply_errors_name_the_file(tmp_path: Path) -> None:
    bad = tmp_path / "bad.ply"
    bad.write_text("not a ply")
    with pytest.raises(InputError, match="bad.ply"):
        load_ply(bad)
    with pytest.raises(InputError, match="no such file"):
        load_ply(tmp_path / "missing.ply")
    from plyfile import PlyElement
    pts = np.zeros(3, dtype=[("x", "f4"), ("y", "f4"), ("z", "f4")])
    PlyData([PlyElement.describe(pts, "vertex")]).write(str(tmp_path / "points.ply"))
    with pytest.raises(InputError, match="missing properties"):
        load_ply(tmp_path / "points.ply")


def test_clone_and_to_are_detached_copies() -> None:
    rgb, depth, intr = _plane()
    m = GaussianMap.empty()
    m.add_from_depth(rgb, depth, intr, np.eye(4), downsample=4, keyframe_id=2)
    m.requires_grad_()
    c = m.to(dtype=torch.float64)
    assert c.means.dtype == torch.float64 and not c.means.requires_grad
    assert c.keyframe_ids.dtype == torch.int64 and (c.keyframe_ids == 2).all()
    d = m.clone()
    d.means.add_(1.0)
    assert not torch.equal(d.means, m.means.detach())
