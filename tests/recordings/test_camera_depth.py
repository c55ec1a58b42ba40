"""Camera models (OpenCV distortion), undistortion of images and events, depth reprojection
and image warping, against analytic scenes."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from egs_bench.geometry import Intrinsics
from egs_bench.recordings import CameraModel, reproject_depth, warp_to_depth_camera

RADTAN = CameraModel(160, 120, 150.0, 148.0, 79.3, 60.2, "radtan", (-0.28, 0.09, 1e-3, -5e-4))
EQUI = CameraModel(160, 120, 120.0, 121.0, 80.1, 59.4, "equidistant", (-0.05, 0.02, -0.01, 0.003))


@pytest.mark.parametrize("cam", [RADTAN, EQUI], ids=["radtan", "equidistant"])
def test_undistort_inverts_projection(cam: CameraModel) -> None:
    rng = np.random.default_rng(0)
    pts = np.column_stack([rng.uniform(-0.4, 0.4, 200), rng.uniform(-0.3, 0.3, 200),
                           rng.uniform(1, 3, 200)])
    uv = cam.project(pts)
    np.testing.assert_allclose(cam.undistort_points(uv), pts[:, :2] / pts[:, 2:], atol=1e-9)


def test_camera_model_rejects_bad_coefficients() -> None:
    with pytest.raises(ValueError, match="radtan distortion needs 4, 5 or 8"):
        CameraModel(10, 10, 5, 5, 5, 5, "radtan", (0.1, 0.2, 0.3))
    with pytest.raises(ValueError, match="unknown distortion model"):
        CameraModel(10, 10, 5, 5, 5, 5, "kannala", (0.1,))
    assert CameraModel(10, 10, 5, 5, 5, 5, "plumb_bob", ()).model == "none"


@pytest.mark.parametrize("cam", [RADTAN, EQUI], ids=["radtan", "equidistant"])
def test_undistorted_image_matches_pinhole_rendering(cam: CameraModel) -> None:
    """A smooth pattern painted on the normalised image plane through the lens model comes out
    of the undistortion as the same pattern seen by the pinhole camera."""
    def pattern(xn: np.ndarray, yn: np.ndarray) -> np.ndarray:
        return 128 + 100 * np.sin(9 * xn) * np.cos(7 * yn)

    rays = cam.pixel_rays()
    distorted = pattern(rays[..., 0], rays[..., 1]).astype(np.float32)
    out = cam.undistort_image(distorted)
    pin = cam.pinhole()
    v, u = np.mgrid[0 : cam.height, 0 : cam.width]
    expected = pattern((u + 0.5 - pin.cx) / pin.fx, (v + 0.5 - pin.cy) / pin.fy)
    inner = np.zeros_like(out, dtype=bool)
    inner[10:-10, 10:-10] = True  # the remapped border samples outside the sensor
    assert np.abs(out - expected)[inner].max() < 1.5  # bilinear sampling of a smooth pattern


@pytest.mark.parametrize("cam", [RADTAN, EQUI], ids=["radtan", "equidistant"])
def test_event_lookup_moves_each_pixel_to_its_undistorted_pixel(cam: CameraModel) -> None:
    lut = cam.event_lookup()
    rays = cam.pixel_rays().reshape(-1, 2)
    pin = cam.pinhole()
    u = pin.fx * rays[:, 0] + pin.cx  # continuous coordinates, pixel u covers [u, u + 1)
    v = pin.fy * rays[:, 1] + pin.cy
    ok = lut >= 0
    assert ok.mean() > 0.7  # these strong barrel distortions push the corners outside K's view
    np.testing.assert_array_equal(lut[ok] % cam.width, np.floor(u[ok]).astype(int))
    np.testing.assert_array_equal(lut[ok] // cam.width, np.floor(v[ok]).astype(int))
    outside = (u < 0) | (u >= cam.width) | (v < 0) | (v >= cam.height)
    np.testing.assert_array_equal(~ok, outside)
    assert 0.5 < cam.event_coverage(lut) <= 1.0


def _plane_depth(intr: Intrinsics, n: np.ndarray, d: float) -> np.ndarray:
    """z-depth of the plane n . X = d seen through each pixel centre of a pinhole camera."""
    v, u = np.mgrid[0 : intr.height, 0 : intr.width].astype(np.float64)
    rx, ry = (u + 0.5 - intr.cx) / intr.fx, (v + 0.5 - intr.cy) / intr.fy
    return d / (n[0] * rx + n[1] * ry + n[2])


def test_reproject_depth_translation_of_frontal_plane_is_exact() -> None:
    """A plane z = 2 m stays at z = 2 m in a camera translated parallel to it."""
    src = CameraModel(96, 72, 70.0, 70.0, 47.5, 35.5)
    dst = Intrinsics(50.0, 50.0, 32.0, 24.0, 64, 48)
    depth = np.full((72, 96), 2.0, np.float32)
    T = np.eye(4)
    T[:3, 3] = [0.1, -0.05, 0.0]
    out = reproject_depth(depth, src.pixel_rays(), T, dst)
    assert (out[out > 0] == 2.0).all()
    assert (out > 0).mean() > 0.95  # the source is denser and wider: nearly every pixel is hit


def test_reproject_depth_tilted_plane_within_pixel_footprint() -> None:
    """Rotated + translated camera, distorted source: each output depth is the plane's depth
    somewhere inside that output pixel (the nearest-pixel splat), so it lies between the
    plane's depths at the pixel's corners."""
    src = CameraModel(120, 90, 80.0, 80.0, 59.5, 44.5, "radtan", (-0.2, 0.05, 0.0, 0.0))
    dst = Intrinsics(45.0, 45.0, 32.0, 24.0, 64, 48)
    T_dst_src = np.eye(4)
    T_dst_src[:3, :3] = Rotation.from_euler("xyz", [4, -6, 2], degrees=True).as_matrix()
    T_dst_src[:3, 3] = [0.08, 0.02, -0.03]
    n_src, d_src = np.array([0.1, -0.2, 1.0]), 2.5  # plane in the source frame
    rays = src.pixel_rays()
    depth_src = d_src / (n_src[0] * rays[..., 0] + n_src[1] * rays[..., 1] + n_src[2])
    out = reproject_depth(depth_src.astype(np.float32), rays, T_dst_src, dst)
    # the plane in the destination frame: n' = R n, d' = d + n' . t
    n_dst = T_dst_src[:3, :3] @ n_src
    d_dst = d_src + n_dst @ T_dst_src[:3, 3]
    corners = [_plane_depth(Intrinsics(dst.fx, dst.fy, dst.cx - du, dst.cy - dv, dst.width,
                                       dst.height), n_dst, d_dst)
               for du in (-0.5, 0.5) for dv in (-0.5, 0.5)]
    lo, hi = np.min(corners, axis=0), np.max(corners, axis=0)
    hit = out > 0
    assert hit.mean() > 0.9
    assert ((out[hit] >= lo[hit] - 1e-5) & (out[hit] <= hi[hit] + 1e-5)).all()
    # a wrong extrinsic is caught by the same bound
    wrong = reproject_depth(depth_src.astype(np.float32), rays, np.eye(4), dst)
    hit_w = wrong > 0
    assert not ((wrong[hit_w] >= lo[hit_w] - 1e-5) & (wrong[hit_w] <= hi[hit_w] + 1e-5)).all()


def test_reproject_depth_zbuffer_keeps_nearest_and_fills_nothing() -> None:
    src = CameraModel(40, 30, 30.0, 30.0, 19.5, 14.5)
    dst = Intrinsics(30.0, 30.0, 20.0, 15.0, 40, 30)
    depth = np.full((30, 40), 3.0, np.float32)
    depth[10:20, 15:25] = 1.0      # a near box in front of the wall
    depth[0, 0] = 0.0              # invalid pixels stay invalid
    depth[0, 1] = np.nan
    T = np.eye(4)
    T[0, 3] = -0.3                 # destination camera 0.3 m to the right
    out = reproject_depth(depth, src.pixel_rays(), T, dst)
    # the box moves by f * b / z = 9 px, the wall by 3 px: the box wins where both land
    assert (out[12:18, 8:14] == 1.0).all()
    # disocclusion behind the box's old place: nothing lands, nothing is filled
    assert (out[12:18, 19:22] == 0).all()
    assert out.dtype == np.float32 and out.shape == (30, 40)


def test_warp_to_depth_camera_samples_source_image() -> None:
    """A frame camera looking at a plane: warping its image into the depth camera reproduces
    the texture coordinates painted on the plane."""
    dst = Intrinsics(40.0, 40.0, 32.0, 24.0, 64, 48)
    src = CameraModel(100, 80, 60.0, 60.0, 49.5, 39.5, "radtan", (-0.1, 0.01, 0.0, 0.0))
    T_src_dst = np.eye(4)
    T_src_dst[:3, 3] = [-0.05, 0.0, 0.0]
    depth_dst = np.full((48, 64), 2.0, np.float32)
    depth_dst[:, :3] = 0.0  # unknown depth -> black
    # the source image shows the plane's world x coordinate (dst frame) as intensity
    rays = src.pixel_rays()
    x_src = rays[..., 0] * 2.0          # on the plane z = 2 in the source frame
    x_dst = x_src - T_src_dst[0, 3]
    image = np.clip(128 + 50 * x_dst, 0, 255).astype(np.uint8)
    warped, valid = warp_to_depth_camera(image, src, depth_dst, dst, T_src_dst)
    v, u = np.mgrid[0:48, 0:64]
    expected = 128 + 50 * (u + 0.5 - dst.cx) / dst.fx * 2.0
    assert not valid[:, :3].any() and (warped[:, :3] == 0).all()
    assert valid[:, 3:].mean() > 0.95
    assert np.abs(warped[valid].astype(float) - expected[valid]).max() <= 1.5
