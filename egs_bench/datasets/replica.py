"""Reader and writer for one scene in the NICE-SLAM Replica layout.

Layout (one folder per scene)::

    <scene>/results/frame000000.jpg   8-bit sRGB colour (``.png`` accepted too)
    <scene>/results/depth000000.png   16-bit depth, metres = value / depth_scale (0 = invalid)
    <scene>/traj.txt                  one camera-to-world 4x4 matrix per line (16 numbers)
    [<scene>/cam_params.json]         optional, also looked up in the parent folder

Defaults when no ``cam_params.json`` exists: ``1200 x 680``, ``fx = fy = 600``,
``cx = 599.5``, ``cy = 339.5``, ``depth_scale = 6553.5`` (NICE-SLAM ``configs/Replica``).

**Pixel convention.** Replica/NICE-SLAM intrinsics put the centre of pixel ``u`` at the integer
``u`` (the image centre of a 1200-wide image is ``599.5``). egs-bench uses gsplat's convention
where that centre is at ``u + 0.5`` (docs/design.md §2). The reader therefore returns
``cx_ours = cx + 0.5`` and ``cy_ours = cy + 0.5`` (``600, 340`` by default); the writer
subtracts the 0.5 again, so a read/write round trip is exact.

``cam_params.json`` follows the file shipped with the NICE-SLAM Replica download::

    {"camera": {"w": 1200, "h": 680, "fx": 600.0, "fy": 600.0,
                "cx": 599.5, "cy": 339.5, "scale": 6553.5}}

(the keys may also sit at the top level).
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any, Literal

import cv2
import numpy as np

from egs_bench.errors import InputError
from egs_bench.fileio import atomic_dir, read_text, write_text_atomic
from egs_bench.geometry import Intrinsics
from egs_bench.images import (
    image_header,
    read_depth_png,
    read_ldr_image,
    write_depth_png,
    write_ldr_image,
)

REPLICA_DEPTH_SCALE = 6553.5
# NICE-SLAM configs/Replica/replica.yaml, in Replica's own (pixel centre at integer) convention.
REPLICA_DEFAULT_CAMERA = {
    "w": 1200, "h": 680, "fx": 600.0, "fy": 600.0, "cx": 599.5, "cy": 339.5,
    "scale": REPLICA_DEPTH_SCALE,
}
CAM_PARAMS_NAME = "cam_params.json"
# Rotation blocks in traj.txt are printed with limited precision; beyond this they are not poses.
_ORTHONORMAL_TOL = 1e-3

# Pillow modes of the 8-bit images read_ldr_image expands to RGB (alpha dropped)
_COLOUR_MODES = ("RGB", "L", "RGBA", "P")

_RGB_RE = re.compile(r"^frame(\d+)\.(jpg|jpeg|png)$", re.IGNORECASE)
_DEPTH_RE = re.compile(r"^depth(\d+)\.png$", re.IGNORECASE)


@dataclass(frozen=True)
class ReplicaScene:
    """An opened, validated RGB-D + pose scene. Frames are read lazily.

    The Replica reader below makes one; :mod:`egs_bench.datasets.rgbd_layouts` makes the same
    object from a TUM RGB-D folder or a generic image/depth/trajectory layout, so the
    EventReplica generator reads every layout through this one interface.

    Attributes:
        path: the scene folder (for the generic layout: the colour image folder).
        rgb_paths: colour image per frame, in frame order.
        depth_paths: depth image per frame.
        poses: camera-to-world poses ``T_wc``, [N, 4, 4] float64 (rotations re-orthonormalised).
        intrinsics: pinhole intrinsics in egs-bench's convention (pixel centre at ``u + 0.5``).
        depth_scale: PNG value per metre.
        cam_params_path: the camera file used (``cam_params.json``, an intrinsics yaml), or None
            for built-in defaults.
        distortion: OpenCV ``k1 k2 p1 p2 [k3]`` of the colour camera (the depth maps are
            registered to it); empty for an undistorted pinhole. Frames are undistorted to
            ``intrinsics`` on reading.
        layout: ``"replica"``, ``"tum-rgbd"`` or ``"generic"``.
        timestamps_s: the layout's own time stamp of each frame [N] in seconds, or None (the
            Replica layout has none).
        record: how the layout was read (association statistics, camera source), for
            ``meta.yaml``.
    """

    path: Path
    rgb_paths: tuple[Path, ...]
    depth_paths: tuple[Path, ...]
    poses: np.ndarray
    intrinsics: Intrinsics
    depth_scale: float
    cam_params_path: Path | None
    distortion: tuple[float, ...] = ()
    layout: str = "replica"
    timestamps_s: np.ndarray | None = None
    record: dict[str, Any] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.rgb_paths)

    @property
    def name(self) -> str:
        return self.path.name

    def rgb(self, index: int) -> np.ndarray:
        """Colour frame ``index`` as uint8 sRGB [H, W, 3] (RGB order)."""
        path = self.rgb_paths[index]
        img = read_ldr_image(path)
        self._check_size(path, img)
        if self.distortion:
            map_x, map_y = _undistort_maps(self.intrinsics, self.distortion)
            img = cv2.remap(img, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        return img

    def depth(self, index: int) -> np.ndarray:
        """Depth frame ``index`` in metres, float32 [H, W] (0 = invalid)."""
        path = self.depth_paths[index]
        raw = read_depth_png(path)
        self._check_size(path, raw)
        if self.distortion:
            # nearest neighbour: blending depths across an edge invents points on no surface;
            # pixels mapped from outside the image become 0 (invalid)
            map_x, map_y = _undistort_maps(self.intrinsics, self.distortion)
            raw = cv2.remap(raw, map_x, map_y, cv2.INTER_NEAREST,
                            borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        return (raw.astype(np.float32) / np.float32(self.depth_scale)).astype(np.float32)

    def _check_size(self, path: Path, img: np.ndarray) -> None:
        h, w = img.shape[:2]
        if (w, h) != (self.intrinsics.width, self.intrinsics.height):
            raise InputError(
                path, f"image is {w}x{h}, expected {self.intrinsics.width}x{self.intrinsics.height}"
            )


def read_replica(
    scene_dir: str | Path, *, cam_params: str | Path | None = None, check_image_headers: bool = True
) -> ReplicaScene:
    """Open and validate a scene in the NICE-SLAM Replica layout.

    Args:
        scene_dir: the scene folder (holding ``results/`` and ``traj.txt``).
        cam_params: explicit ``cam_params.json``; by default ``<scene>/cam_params.json`` or
            ``<scene>/../cam_params.json`` if present, else the Replica defaults.
        check_image_headers: read every image header to check its size and type on open (fast:
            headers only); frames are also checked when loaded.

    Raises:
        InputError: naming the file, for a missing folder or file, frame numbers that are not
            0..N-1, colour/depth/pose count mismatches, unparsable or non-finite ``traj.txt``
            lines, matrices that are not rigid transforms, bad ``cam_params.json``, or images of
            the wrong size or type.
    """
    root = Path(scene_dir)
    if not root.is_dir():
        raise InputError(root, "scene folder does not exist")
    results = root / "results"
    if not results.is_dir():
        raise InputError(results, "missing 'results' folder (NICE-SLAM Replica layout expected)")

    intrinsics, depth_scale, cam_path = _read_camera(root, cam_params)

    rgb = _numbered_files(results, _RGB_RE, "colour frames frameNNNNNN.jpg")
    depth = _numbered_files(results, _DEPTH_RE, "depth frames depthNNNNNN.png")
    if len(rgb) != len(depth):
        raise InputError(
            results, f"{len(rgb)} colour frames but {len(depth)} depth frames"
        )
    poses = read_replica_trajectory(root / "traj.txt")
    if len(poses) != len(rgb):
        raise InputError(
            root / "traj.txt", f"{len(poses)} poses but {len(rgb)} frames in {results}"
        )
    scene = ReplicaScene(
        path=root,
        rgb_paths=tuple(rgb),
        depth_paths=tuple(depth),
        poses=poses,
        intrinsics=intrinsics,
        depth_scale=depth_scale,
        cam_params_path=cam_path,
    )
    if check_image_headers:
        check_headers(scene)
    return scene


def read_replica_trajectory(path: str | Path) -> np.ndarray:
    """Read ``traj.txt``: one row-major camera-to-world 4x4 matrix per non-empty line.

    Returns:
        Poses [N, 4, 4] float64; rotation blocks are projected onto SO(3) (SVD) because the
        file's limited print precision leaves them slightly non-orthonormal.

    Raises:
        InputError: missing file, a line without exactly 16 numbers, non-finite values, a last
            row other than ``0 0 0 1``, or a rotation block that is not a rotation.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "missing trajectory file (16 numbers per line, camera-to-world)")
    poses = []
    for line_no, line in enumerate(read_text(path).splitlines(), start=1):
        text = line.strip()
        if not text or text.startswith("#"):
            continue
        fields = text.split()
        if len(fields) != 16:
            raise InputError(path, f"line {line_no}: expected 16 numbers, found {len(fields)}")
        try:
            values = np.array([float(f) for f in fields], dtype=np.float64)
        except ValueError:
            raise InputError(path, f"line {line_no}: not a number in {text[:80]!r}") from None
        if not np.all(np.isfinite(values)):
            raise InputError(path, f"line {line_no}: non-finite value (NaN or inf)")
        mat = values.reshape(4, 4)
        if not np.allclose(mat[3], [0.0, 0.0, 0.0, 1.0], atol=1e-6):
            raise InputError(path, f"line {line_no}: last matrix row is {mat[3]}, not 0 0 0 1")
        rot = mat[:3, :3]
        err = float(np.abs(rot.T @ rot - np.eye(3)).max())
        if err > _ORTHONORMAL_TOL or np.linalg.det(rot) <= 0:
            raise InputError(
                path, f"line {line_no}: the 3x3 block is not a rotation (|R^T R - I| = {err:.2g}, "
                f"det = {np.linalg.det(rot):.3g})"
            )
        u, _, vt = np.linalg.svd(rot)
        mat[:3, :3] = u @ vt
        poses.append(mat)
    if not poses:
        raise InputError(path, "trajectory file holds no poses")
    return np.stack(poses)


def export_replica_layout(
    rgb_list: Sequence[np.ndarray],
    depth_list: Sequence[np.ndarray],
    poses: np.ndarray | Sequence[np.ndarray],
    out_dir: str | Path,
    *,
    intrinsics: Intrinsics | None = None,
    depth_scale: float = REPLICA_DEPTH_SCALE,
    image_format: Literal["jpg", "png"] = "jpg",
    jpeg_quality: int = 95,
    overwrite: bool = False,
    jpeg_chroma_444: bool = False,
) -> Path:
    """Write an RGB-D + pose sequence in the NICE-SLAM Replica layout (atomically).

    Args:
        rgb_list: N uint8 sRGB images [H, W, 3] (RGB order).
        depth_list: N depth maps [H, W] in metres (0 = invalid; NaN not allowed).
        poses: N camera-to-world poses [4, 4].
        out_dir: the scene folder to create; an existing one is replaced only with
            ``overwrite``.
        intrinsics: egs-bench-convention intrinsics; if given, a ``cam_params.json`` is written
            (converted to Replica's convention, ``cx - 0.5``). If None, the images must match
            the Replica defaults that a reader will assume.
        depth_scale: PNG value per metre (Replica: 6553.5, so depths up to 10 m).
        image_format: ``"jpg"`` (as NICE-SLAM) or ``"png"`` (lossless, for exact tests).
        jpeg_quality: JPEG quality 1..100.
        overwrite: replace an existing ``out_dir``.
        jpeg_chroma_444: keep full-resolution colour (no 4:2:0 chroma subsampling).

    Returns:
        ``out_dir``.
    """
    out_dir = Path(out_dir)
    poses = np.asarray(poses, dtype=np.float64)
    n = len(rgb_list)
    if len(depth_list) != n or len(poses) != n:
        raise ValueError(f"{n} colour, {len(depth_list)} depth and {len(poses)} pose entries")
    if image_format not in ("jpg", "png"):
        raise ValueError("image_format must be 'jpg' or 'png'")
    with atomic_dir(out_dir, replace=overwrite) as tmp:
        results = tmp / "results"
        results.mkdir(parents=True)
        for i, (rgb, depth) in enumerate(zip(rgb_list, depth_list, strict=True)):
            rgb = np.asarray(rgb)
            depth = np.asarray(depth, dtype=np.float64)
            if rgb.dtype != np.uint8 or rgb.ndim != 3 or rgb.shape[2] != 3:
                raise ValueError(f"frame {i}: colour must be uint8 [H, W, 3]")
            if not np.all(np.isfinite(depth)) or depth.min() < 0:
                raise ValueError(f"frame {i}: depth must be finite and >= 0")
            raw = np.round(depth * depth_scale)
            if raw.max() > 65535:
                raise ValueError(f"frame {i}: depth {depth.max():.3f} m overflows 16 bits")
            write_ldr_image(results / f"frame{i:06d}.{image_format}", rgb, jpeg_quality,
                            jpeg_chroma_444)
            write_depth_png(results / f"depth{i:06d}.png", raw.astype(np.uint16))
        lines = [" ".join(f"{v:.17g}" for v in pose.reshape(-1)) for pose in poses]
        (tmp / "traj.txt").write_text("\n".join(lines) + "\n")
        if intrinsics is not None:
            cam = {
                "camera": {
                    "w": int(intrinsics.width), "h": int(intrinsics.height),
                    "fx": float(intrinsics.fx), "fy": float(intrinsics.fy),
                    "cx": float(intrinsics.cx) - 0.5, "cy": float(intrinsics.cy) - 0.5,
                    "scale": float(depth_scale),
                }
            }
            write_text_atomic(tmp / CAM_PARAMS_NAME, json.dumps(cam, indent=2) + "\n")
    return out_dir


# --- helpers -----------------------------------------------------------------------------------


@lru_cache(maxsize=4)
def _undistort_maps(intrinsics: Intrinsics, distortion: tuple[float, ...]
                    ) -> tuple[np.ndarray, np.ndarray]:
    """``cv2.remap`` maps [H, W] float32 that undistort an image of ``intrinsics`` (same K out).

    OpenCV puts pixel centres at integer coordinates, so K is shifted by 0.5 from egs-bench's
    convention (docs/design.md §2) in both directions and the maps index source pixels directly.
    """
    k = intrinsics.K.copy()
    k[0, 2] -= 0.5
    k[1, 2] -= 0.5
    size = (intrinsics.width, intrinsics.height)
    map_x, map_y = cv2.initUndistortRectifyMap(
        k, np.asarray(distortion, dtype=np.float64), None, k, size, cv2.CV_32FC1)
    return map_x, map_y


def _read_camera(
    root: Path, explicit: str | Path | None
) -> tuple[Intrinsics, float, Path | None]:
    """Intrinsics (egs-bench convention), depth scale and the file they came from."""
    path: Path | None
    if explicit is not None:
        path = Path(explicit)
        if not path.is_file():
            raise InputError(path, "camera parameter file does not exist")
    else:
        path = next((p for p in (root / CAM_PARAMS_NAME, root.parent / CAM_PARAMS_NAME)
                     if p.is_file()), None)
    cam = dict(REPLICA_DEFAULT_CAMERA)
    if path is not None:
        try:
            data = json.loads(path.read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise InputError(path, f"not valid JSON ({exc})") from None
        block = data.get("camera", data) if isinstance(data, dict) else None
        if not isinstance(block, dict):
            raise InputError(path, "expected a JSON object with camera parameters")
        for key in cam:
            if key in block:
                value = block[key]
                if isinstance(value, bool) or not isinstance(value, int | float) or not (
                    math.isfinite(value) and value > 0
                ):
                    raise InputError(path, f"'{key}' must be a positive finite number, "
                                           f"got {value!r}")
                cam[key] = value
        for key in ("w", "h"):
            if float(cam[key]) != int(cam[key]):
                raise InputError(path, f"'{key}' must be an integer, got {cam[key]!r}")
    intr = Intrinsics(
        fx=float(cam["fx"]), fy=float(cam["fy"]),
        cx=float(cam["cx"]) + 0.5, cy=float(cam["cy"]) + 0.5,  # Replica -> gsplat convention
        width=int(cam["w"]), height=int(cam["h"]),
    )
    return intr, float(cam["scale"]), path


def _numbered_files(folder: Path, pattern: re.Pattern[str], what: str) -> list[Path]:
    """Files matching ``pattern`` numbered exactly 0..N-1, in order."""
    found: dict[int, Path] = {}
    for entry in folder.iterdir():
        m = pattern.match(entry.name)
        if m is None:
            continue
        idx = int(m.group(1))
        if idx in found:
            raise InputError(entry, f"duplicate frame number {idx} (also {found[idx].name})")
        found[idx] = entry
    if not found:
        raise InputError(folder, f"no {what}")
    missing = sorted(set(range(len(found))) - set(found))
    if missing:
        raise InputError(
            folder, f"{what}: numbering must run 0..{len(found) - 1} without gaps; "
            f"missing number {missing[0]} (highest is {max(found)})"
        )
    return [found[i] for i in range(len(found))]


def check_headers(scene: ReplicaScene) -> None:
    """Check every image's size (against ``scene.intrinsics``) and pixel type from its header.

    Raises:
        InputError: naming the first image of the wrong size or type.
    """
    want = (scene.intrinsics.width, scene.intrinsics.height)
    for kind, paths in (("colour", scene.rgb_paths), ("depth", scene.depth_paths)):
        for path in paths:
            width, height, mode = image_header(path)
            size = (width, height)
            if size != want:
                raise InputError(
                    path, f"{kind} image is {size[0]}x{size[1]}, expected {want[0]}x{want[1]}"
                    + ("" if scene.cam_params_path is None
                       else f" (from {scene.cam_params_path})")
                )
            if kind == "depth" and mode not in ("I;16", "I;16B", "I;16L", "I"):
                raise InputError(path, f"depth must be a 16-bit one-channel PNG, got mode {mode}")
            if kind == "colour" and mode not in _COLOUR_MODES:
                raise InputError(path, f"colour image has unsupported mode {mode}")
