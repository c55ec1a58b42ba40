"""Analytic checks of the synthetic scenes' ray caster and textures."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from skimage import data as skdata

from egs_bench.datasets.synthetic.raycast import Renderer, stratified_offsets
from egs_bench.datasets.synthetic.scene import Box, Light, Material, Scene, Sphere, pack_scene
from egs_bench.datasets.synthetic.scenes import SCENES, build_scene
from egs_bench.datasets.synthetic.source import default_intrinsics
from egs_bench.datasets.synthetic.textures import (
    SURFACE_TEXTURES,
    load_texture,
    mip_pyramid,
)
from egs_bench.datasets.synthetic.trajectory import look_at
from egs_bench.geometry import Intrinsics, invert_pose

GREY = Material((0.5, 0.5, 0.5))


def _box_room(half: float = 10.0, **kwargs: Any) -> Scene:
    """A large empty cube room centred at the origin, plain walls, ambient light only."""
    walls = {f: GREY for f in ("x-", "x+", "y-", "y+", "floor", "ceiling")}
    return Scene(name="test", description="test room", lo=(-half, -half, -half),
                 hi=(half, half, half), walls=walls, camera_box=((-1, -1, -1), (1, 1, 1)),
                 target_box=((5, -1, -1), (6, 1, 1)), ambient=(1.0, 1.0, 1.0), **kwargs)


def _camera_looking_along_x(roll: float = 0.0) -> np.ndarray:
    """T_wc at the origin with the optical axis along world +x, rolled about it."""
    pose = look_at(np.zeros(3), np.array([1.0, 0.0, 0.0]))
    c, s = np.cos(roll), np.sin(roll)
    pose[:3, :3] = pose[:3, :3] @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    return pose


@pytest.mark.parametrize("roll", [0.0, 0.37])
def test_fronto_parallel_wall_has_exact_depth(roll: float) -> None:
    cam = Intrinsics(30.0, 30.0, 20.0, 15.0, 40, 30)
    renderer = Renderer(pack_scene(_box_room(half=4.0)), cam, supersample=2)
    _, depth = renderer.render(_camera_looking_along_x(roll))
    # The x+ wall is at x = 4 and the field of view is narrow enough to see only it.
    np.testing.assert_allclose(depth, 4.0, rtol=0, atol=1e-5)


def test_sphere_depth_and_silhouette_match_the_analytic_solution() -> None:
    cam = Intrinsics(40.0, 40.0, 24.3, 17.6, 48, 36)
    centre_cam = np.array([0.3, -0.2, 3.0])
    radius = 0.6
    pose = _camera_looking_along_x()
    centre_world = (pose @ np.append(centre_cam, 1.0))[:3]
    scene = _box_room(half=8.0, spheres=[Sphere(tuple(centre_world), radius, GREY)])
    _, depth = Renderer(pack_scene(scene), cam, supersample=1).render(pose)

    # Independent float64 solution of |t d - c|^2 = r^2 with d = ((u+.5-cx)/fx, (v+.5-cy)/fy, 1).
    v, u = np.mgrid[0:cam.height, 0:cam.width].astype(np.float64)
    d = np.stack([(u + 0.5 - cam.cx) / cam.fx, (v + 0.5 - cam.cy) / cam.fy, np.ones_like(u)], -1)
    dc = d @ centre_cam
    dd = (d * d).sum(-1)
    disc = dc**2 - dd * (centre_cam @ centre_cam - radius**2)
    hit = disc > 0
    t_sphere = (dc - np.sqrt(np.where(hit, disc, 0.0))) / dd

    margin = np.abs(disc) > 1e-3 * dd  # skip rays that graze the silhouette
    rendered_hit = depth < 7.0
    assert hit.sum() > 100
    np.testing.assert_array_equal(rendered_hit[margin], hit[margin])
    np.testing.assert_allclose(depth[hit & margin], t_sphere[hit & margin], atol=1e-5)
    np.testing.assert_allclose(depth[~hit & margin], 8.0, atol=1e-5)


def test_point_projects_to_the_pixel_of_the_gsplat_convention() -> None:
    """A sphere centred on the optical axis has a silhouette centred at (cx, cy), so with
    pixel centres at u + 0.5 its mask centroid lands at (cx, cy), not (cx - 0.5, cy - 0.5)."""
    cam = Intrinsics(60.0, 60.0, 20.3, 15.7, 40, 32)
    pose = _camera_looking_along_x()
    centre = (pose @ np.array([0.0, 0.0, 3.0, 1.0]))[:3]
    scene = _box_room(half=8.0, spheres=[Sphere(tuple(centre), 0.4, GREY)])
    _, depth = Renderer(pack_scene(scene), cam, supersample=1).render(pose)
    mask = depth < 7.0
    v, u = np.nonzero(mask)
    assert len(u) > 80
    assert abs((u + 0.5).mean() - cam.cx) < 0.1
    assert abs((v + 0.5).mean() - cam.cy) < 0.1

    # A general pose: the pixel containing the projection of a small sphere's centre sees it.
    eye, target = np.array([0.5, -1.0, 0.3]), np.array([4.0, 1.0, -0.5])
    pose = look_at(eye, target)
    point = np.array([3.2, 0.9, -0.1])
    scene = _box_room(half=8.0, spheres=[Sphere(tuple(point), 0.05, GREY)])
    _, depth = Renderer(pack_scene(scene), cam, supersample=1).render(pose)
    p_cam = (invert_pose(pose) @ np.append(point, 1.0))[:3]
    uv = cam.project(p_cam[None])[0]
    iu, iv = int(np.floor(uv[0])), int(np.floor(uv[1]))
    assert depth[iv, iu] < p_cam[2]  # the sphere's front, not the wall behind
    assert abs(depth[iv, iu] - p_cam[2]) < 0.05


def test_textures_are_linearised_and_mip_levels_are_box_means() -> None:
    tex = load_texture("astronaut", size=512)  # 512x512 original: no resampling
    srgb = skdata.astronaut()[100, 200].astype(np.float64) / 255.0
    expected = np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)
    np.testing.assert_allclose(tex[100, 200], expected, rtol=1e-5)
    assert tex.mean() < skdata.astronaut().mean() / 255.0  # decoding darkens mid-tones

    levels = mip_pyramid(tex)
    assert [lv.shape[0] for lv in levels] == [512 >> k for k in range(10)]
    np.testing.assert_allclose(levels[1][3, 5], tex[6:8, 10:12].reshape(4, 3).mean(0), rtol=1e-5)
    np.testing.assert_allclose(levels[-1][0, 0], tex.reshape(-1, 3).astype(np.float64).mean(0),
                               rtol=1e-5)

    for name in SURFACE_TEXTURES:
        assert load_texture(name, size=64).mean() == pytest.approx(1.0, rel=1e-3)


def test_supersampling_gives_edge_pixels_intermediate_values() -> None:
    cam = Intrinsics(30.0, 30.0, 20.0, 15.0, 40, 30)
    dark, bright = Material((0.1, 0.1, 0.1)), Material((0.9, 0.9, 0.9))
    # A bright board in front of the dark far wall; its vertical edge at y = 0 is slanted in
    # the image by rolling the camera, so no pixel boundary is aligned with it.
    walls = {f: dark for f in ("x-", "x+", "y-", "y+", "floor", "ceiling")}
    scene = Scene(name="edge", description="", lo=(-5, -5, -5), hi=(5, 5, 5), walls=walls,
                  camera_box=((-1, -1, -1), (1, 1, 1)), target_box=((3, -1, -1), (4, 1, 1)),
                  ambient=(1.0, 1.0, 1.0),
                  boxes=[Box((3.0, 2.6, 0.0), (0.1, 4.6, 6.0), bright)])
    pose = _camera_looking_along_x(roll=0.2)
    values = {}
    for ss in (1, 4):
        rgb, _ = Renderer(pack_scene(scene), cam, supersample=ss).render(pose)
        values[ss] = rgb[..., 0]
    lo, hi = 0.1 * 0.8, 0.9 * 0.8  # albedo * ambient * (0.8 + 0.2 n_z) with n_z = 0
    for ss, img in values.items():
        between = (img > lo + 0.02) & (img < hi - 0.02)
        if ss == 1:
            assert not between.any(), "a single sample per pixel cannot mix two surfaces"
        else:
            assert between.sum() >= cam.height - 2, "every row crossing the edge is mixed"
            # Mixed pixels lie on the edge: each row holds at most two of them.
            assert between.sum(axis=1).max() <= 2
    # Away from the edge both renders agree exactly (same surfaces, same flat shading).
    same = np.abs(values[1] - values[4]) < 1e-6
    assert same.mean() > 0.85


def test_stratified_offsets_fill_every_stratum_and_are_fixed() -> None:
    off = stratified_offsets(3, 4, 3, jitter=True, seed=1)
    assert off.shape == (3, 4, 9, 2)
    cells = np.floor(off * 3).astype(int)
    for pix in cells.reshape(-1, 9, 2):
        assert len({tuple(c) for c in pix}) == 9
    np.testing.assert_array_equal(off, stratified_offsets(3, 4, 3, jitter=True, seed=1))
    np.testing.assert_allclose(stratified_offsets(2, 2, 1), 0.5)


@pytest.mark.parametrize("name", list(SCENES))
def test_tile_culling_changes_nothing(name: str) -> None:
    scene = build_scene(name)
    cam = default_intrinsics(64, 40)
    packed = pack_scene(scene)
    pose = scene.anchor_pose()
    rgb_c, depth_c = Renderer(packed, cam, supersample=2, cull=True).render(pose)
    rgb_a, depth_a = Renderer(packed, cam, supersample=2, cull=False).render(pose)
    np.testing.assert_array_equal(depth_c, depth_a)
    np.testing.assert_array_equal(rgb_c, rgb_a)


@pytest.mark.parametrize("name", list(SCENES))
def test_scenes_have_hdr_highlights_with_detail_events_can_see(name: str) -> None:
    scene = build_scene(name)
    cam = default_intrinsics(96, 56)
    renderer = Renderer(pack_scene(scene), cam, supersample=2)
    luma_all, depth_all = [], []
    # The anchor view and a few views around the room.
    eye = np.mean(scene.camera_box, axis=0)
    centre = (np.asarray(scene.lo) + np.asarray(scene.hi)) / 2
    targets = [np.mean(scene.target_box, axis=0)] + [
        np.array([x, y, 1.2]) for x, y in
        [(scene.lo[0] + 0.3, centre[1]), (scene.hi[0] - 0.3, centre[1]),
         (centre[0], scene.lo[1] + 0.3), (centre[0], scene.hi[1] - 0.3)]
    ] + [np.array([eye[0] + 0.1, eye[1], scene.hi[2]])]
    for target in targets:
        rgb, depth = renderer.render(look_at(eye, target))
        assert np.isfinite(rgb).all() and (rgb >= 0).all()
        luma_all.append(rgb @ np.array([0.299, 0.587, 0.114]))
        depth_all.append(depth)
    luma = np.stack(luma_all)
    assert luma.max() > 2.0, "no HDR highlight above the LDR white point"
    assert np.median(luma) < 0.5
    saturated = luma > 1.05
    # Inside saturated regions log-brightness still varies (texture or falloff): the LDR frame
    # clips there while an event camera sees structure.
    assert np.log(luma[saturated]).std() > 0.05
    depth = np.stack(depth_all)
    diag = float(np.linalg.norm(np.subtract(scene.hi, scene.lo)))
    assert (depth > 0).all() and (depth < diag).all()


def test_point_light_falloff_and_cosine() -> None:
    """Radiance of a matte wall lit by one point light equals albedo * I cos / (d^2 + r^2)."""
    cam = Intrinsics(20.0, 20.0, 10.0, 8.0, 20, 16)
    albedo = 0.5
    walls = {f: Material((albedo,) * 3) for f in ("x-", "x+", "y-", "y+", "floor", "ceiling")}
    light = Light((1.0, 0.3, 0.2), (2.0, 2.0, 2.0), 0.1)
    scene = Scene(name="lit", description="", lo=(-3, -3, -3), hi=(3, 3, 3), walls=walls,
                  camera_box=((-1, -1, -1), (1, 1, 1)), target_box=((2, -1, -1), (3, 1, 1)),
                  ambient=(0.0, 0.0, 0.0), lights=[light])
    pose = _camera_looking_along_x()
    rgb, depth = Renderer(pack_scene(scene), cam, supersample=1).render(pose)
    points = (cam.backproject(depth).reshape(-1, 3) @ pose[:3, :3].T) + pose[:3, 3]
    to_light = np.asarray(light.position) - points
    d2 = (to_light**2).sum(1)
    cos = to_light[:, 0] * -1.0 / np.sqrt(d2)  # wall x = 3 has normal -x
    expected = albedo * 2.0 * np.clip(cos, 0, None) / (d2 + 0.1**2)
    np.testing.assert_allclose(rgb[..., 0].reshape(-1), expected, rtol=1e-4, atol=1e-6)
