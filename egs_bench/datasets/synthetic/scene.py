"""Scene description for the analytic ray caster: a room, boxes, spheres, cylinders, decals,
point lights, and packing into flat arrays for the numba kernels.

World frame: metres, ``z`` up, the floor at ``z = room.lo[2]``. Every planar face (the six
room faces and the six faces of each box) has a *face frame*: centre ``C``, unit normal ``N``
towards the viewer (into the room for room faces, outwards for boxes), unit ``U`` ("up" on the
face) and ``R = U x N`` ("right" as seen by a viewer facing the face), and half extents
``hw`` (along ``R``) and ``hh`` (along ``U``). Face coordinates of a point ``p`` are
``s = (p - C) . R + hw`` in ``[0, 2 hw]`` and ``r = (p - C) . U + hh`` in ``[0, 2 hh]``
(metres from the face's bottom-left corner as the viewer sees it). Decals are rectangles in
these coordinates, so pictures are never mirrored.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from egs_bench.datasets.synthetic.textures import TextureBank, build_texture_bank

Vec3 = tuple[float, float, float]

# Room face order; a face's normal points into the room.
ROOM_FACES = ("x-", "x+", "y-", "y+", "floor", "ceiling")
# Box face order (box-local axes); normals point out of the box.
BOX_FACES = ("x-", "x+", "y-", "y+", "bottom", "top")

# Object kinds in the packed object table (used for screen-tile culling).
OBJ_BOX, OBJ_SPHERE, OBJ_CYLINDER = 0, 1, 2


@dataclass(frozen=True)
class Material:
    """Surface appearance (all colours linear RGB).

    Attributes:
        color: diffuse albedo tint in [0, 1], multiplied by the texture (if any).
        texture: name of a texture from :mod:`textures`, or None for a plain colour.
        tile: metres per texture repeat; ``0`` stretches the texture once over the whole face
            (pictures, screens, windows).
        mix: texture contrast: albedo = color * ((1 - mix) + mix * texture).
        emission: emitted radiance added to the reflected light (HDR; > 1 saturates the LDR
            output), multiplied by the texture if there is one.
    """

    color: Vec3 = (0.7, 0.7, 0.7)
    texture: str | None = None
    tile: float = 1.0
    mix: float = 1.0
    emission: Vec3 = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Decal:
    """A textured rectangle on a face, in that face's ``(s, r)`` coordinates (metres).

    ``face`` is a room face name (``"x-"``, ..., ``"ceiling"``) or ``(box_index, box_face)``.
    Later decals cover earlier ones (use this for frames around pictures).
    """

    face: str | tuple[int, str]
    s0: float
    r0: float
    s1: float
    r1: float
    material: Material


@dataclass(frozen=True)
class Box:
    """Box with centre, full size ``(sx, sy, sz)`` and rotation ``yaw`` (rad) about ``z``.

    ``faces`` overrides the material of individual faces (keys from :data:`BOX_FACES`).
    """

    center: Vec3
    size: Vec3
    material: Material
    yaw: float = 0.0
    faces: dict[str, Material] = field(default_factory=dict)


@dataclass(frozen=True)
class Sphere:
    center: Vec3
    radius: float
    material: Material


@dataclass(frozen=True)
class Cylinder:
    """Vertical capped cylinder: axis at ``(x, y)``, from ``z0`` to ``z1``."""

    x: float
    y: float
    z0: float
    z1: float
    radius: float
    material: Material
    cap: Material | None = None


@dataclass(frozen=True)
class Light:
    """Point light: irradiance ``intensity * cos / (d^2 + radius^2)`` (no shadows)."""

    position: Vec3
    intensity: Vec3
    radius: float = 0.1


@dataclass
class Scene:
    """A complete procedural scene.

    Attributes:
        name: scene name.
        description: one line for ``list-scenes``.
        lo, hi: room interior corners (metres).
        walls: material per room face (keys from :data:`ROOM_FACES`).
        camera_box: ``(lo, hi)`` region the hand-held camera centre stays in (free of objects).
        target_box: ``(lo, hi)`` region the camera looks at.
        ambient: ambient irradiance (linear RGB), modulated by ``0.8 + 0.2 * n_z``.
    """

    name: str
    description: str
    lo: Vec3
    hi: Vec3
    walls: dict[str, Material]
    camera_box: tuple[Vec3, Vec3]
    target_box: tuple[Vec3, Vec3]
    ambient: Vec3 = (0.08, 0.08, 0.08)
    boxes: list[Box] = field(default_factory=list)
    spheres: list[Sphere] = field(default_factory=list)
    cylinders: list[Cylinder] = field(default_factory=list)
    decals: list[Decal] = field(default_factory=list)
    lights: list[Light] = field(default_factory=list)

    def anchor_pose(self) -> np.ndarray:
        """``T_wc`` [4, 4] at the camera box centre, looking at the target box centre."""
        from egs_bench.datasets.synthetic.trajectory import look_at

        eye = (np.asarray(self.camera_box[0]) + np.asarray(self.camera_box[1])) / 2
        target = (np.asarray(self.target_box[0]) + np.asarray(self.target_box[1])) / 2
        return look_at(eye, target)

    def object_bounds(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """Axis-aligned bounds ``(lo, hi)`` of every box, sphere and cylinder (world)."""
        out = []
        for b in self.boxes:
            c, s = np.cos(b.yaw), np.sin(b.yaw)
            half = np.asarray(b.size) / 2
            ext = np.array(
                [abs(c) * half[0] + abs(s) * half[1], abs(s) * half[0] + abs(c) * half[1], half[2]]
            )
            out.append((np.asarray(b.center) - ext, np.asarray(b.center) + ext))
        for sp in self.spheres:
            out.append((np.asarray(sp.center) - sp.radius, np.asarray(sp.center) + sp.radius))
        for cy in self.cylinders:
            out.append(
                (
                    np.array([cy.x - cy.radius, cy.y - cy.radius, cy.z0]),
                    np.array([cy.x + cy.radius, cy.y + cy.radius, cy.z1]),
                )
            )
        return out

    def free_space_violation(self, points: np.ndarray, clearance: float = 0.15) -> np.ndarray:
        """How far (metres, 0 = fine) points [N, 3] intrude into the room's walls or objects.

        A point violates when it is closer than ``clearance`` to a wall or inside an object's
        bounding box grown by ``clearance``; the value is the depth of that intrusion.
        """
        pts = np.atleast_2d(np.asarray(points, dtype=np.float64))
        lo = np.asarray(self.lo) + clearance
        hi = np.asarray(self.hi) - clearance
        wall = np.maximum(np.maximum(lo - pts, pts - hi), 0.0).max(axis=1)
        obj = np.zeros(len(pts))
        for blo, bhi in self.object_bounds():
            inside = np.minimum(pts - (blo - clearance), (bhi + clearance) - pts).min(axis=1)
            obj = np.maximum(obj, np.maximum(inside, 0.0))
        return np.maximum(wall, obj)


@dataclass(frozen=True)
class PackedScene:
    """Flat arrays consumed by :mod:`raycast` (see that module for the layouts)."""

    room: np.ndarray  # float64 [6]: lo xyz, hi xyz
    faces: np.ndarray  # float64 [F, 14]: C, N, U, R (3 each), hw, hh
    face_mat: np.ndarray  # int64 [F]
    decal_rect: np.ndarray  # float64 [D, 4]: s0, r0, s1, r1 (sorted by face)
    decal_mat: np.ndarray  # int64 [D]
    face_decal_start: np.ndarray  # int64 [F]
    face_decal_count: np.ndarray  # int64 [F]
    boxes: np.ndarray  # float64 [B, 8]: centre xyz, cos, sin, half xyz
    spheres: np.ndarray  # float64 [S, 4]: centre xyz, radius
    sphere_mat: np.ndarray  # int64 [S]
    cylinders: np.ndarray  # float64 [Y, 5]: x, y, z0, z1, radius
    cylinder_mat: np.ndarray  # int64 [Y, 2]: side, cap
    objects: np.ndarray  # int64 [O, 2]: kind, index
    object_bounds: np.ndarray  # float64 [O, 4]: bounding sphere centre xyz, radius
    mat_f: np.ndarray  # float64 [M, 8]: color rgb, emission rgb, tile, mix
    mat_tex: np.ndarray  # int64 [M]: texture index or -1
    lights: np.ndarray  # float64 [L, 7]: position, intensity rgb, radius
    ambient: np.ndarray  # float64 [3]
    textures: TextureBank


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _face_row(center: Sequence[float] | np.ndarray, normal: Sequence[float] | np.ndarray,
              up: Sequence[float] | np.ndarray, hw: float, hh: float) -> list[float]:
    n, u = _unit(np.asarray(normal, float)), _unit(np.asarray(up, float))
    r = np.cross(u, n)
    return [*center, *n, *u, *r, hw, hh]


def room_face_rows(lo: np.ndarray, hi: np.ndarray) -> list[list[float]]:
    """Face frames of the six room faces (normals into the room), order :data:`ROOM_FACES`."""
    c = (lo + hi) / 2
    h = (hi - lo) / 2
    ex, ey, ez = np.eye(3)
    return [
        _face_row([lo[0], c[1], c[2]], ex, ez, h[1], h[2]),
        _face_row([hi[0], c[1], c[2]], -ex, ez, h[1], h[2]),
        _face_row([c[0], lo[1], c[2]], ey, ez, h[0], h[2]),
        _face_row([c[0], hi[1], c[2]], -ey, ez, h[0], h[2]),
        _face_row([c[0], c[1], lo[2]], ez, ey, h[0], h[1]),
        _face_row([c[0], c[1], hi[2]], -ez, ey, h[0], h[1]),
    ]


def box_face_rows(box: Box) -> list[list[float]]:
    """Face frames of a box's six faces (outward normals), order :data:`BOX_FACES`."""
    cz, sz = np.cos(box.yaw), np.sin(box.yaw)
    ax = np.array([cz, sz, 0.0])
    ay = np.array([-sz, cz, 0.0])
    az = np.array([0.0, 0.0, 1.0])
    c = np.asarray(box.center, float)
    hx, hy, hz = (np.asarray(box.size, float) / 2).tolist()
    return [
        _face_row(c - hx * ax, -ax, az, hy, hz),
        _face_row(c + hx * ax, ax, az, hy, hz),
        _face_row(c - hy * ay, -ay, az, hx, hz),
        _face_row(c + hy * ay, ay, az, hx, hz),
        _face_row(c - hz * az, -az, ay, hx, hy),
        _face_row(c + hz * az, az, ay, hx, hy),
    ]


def pack_scene(scene: Scene) -> PackedScene:
    """Convert a :class:`Scene` to the flat arrays of :class:`PackedScene`."""
    materials: list[Material] = []
    mat_index: dict[Material, int] = {}

    def mid(m: Material) -> int:
        if m not in mat_index:
            mat_index[m] = len(materials)
            materials.append(m)
        return mat_index[m]

    lo, hi = np.asarray(scene.lo, float), np.asarray(scene.hi, float)
    if not (hi > lo).all():
        raise ValueError(f"scene {scene.name}: room hi must exceed lo")
    missing = set(ROOM_FACES) - set(scene.walls)
    if missing:
        raise ValueError(f"scene {scene.name}: no material for room faces {sorted(missing)}")
    face_rows = room_face_rows(lo, hi)
    face_mat = [mid(scene.walls[f]) for f in ROOM_FACES]
    for box in scene.boxes:
        face_rows += box_face_rows(box)
        face_mat += [mid(box.faces.get(f, box.material)) for f in BOX_FACES]

    def face_id(face: str | tuple[int, str]) -> int:
        if isinstance(face, str):
            return ROOM_FACES.index(face)
        bi, name = face
        return len(ROOM_FACES) + 6 * bi + BOX_FACES.index(name)

    decals = sorted(enumerate(scene.decals), key=lambda kv: (face_id(kv[1].face), kv[0]))
    n_faces = len(face_rows)
    start = np.zeros(n_faces, np.int64)
    count = np.zeros(n_faces, np.int64)
    for k, (_, d) in enumerate(decals):
        f = face_id(d.face)
        if count[f] == 0:
            start[f] = k
        count[f] += 1

    boxes = np.array(
        [[*b.center, np.cos(b.yaw), np.sin(b.yaw), *(np.asarray(b.size) / 2)] for b in scene.boxes],
        dtype=np.float64,
    ).reshape(-1, 8)
    spheres = np.array([[*s.center, s.radius] for s in scene.spheres], float).reshape(-1, 4)
    cylinders = np.array(
        [[c.x, c.y, c.z0, c.z1, c.radius] for c in scene.cylinders], float
    ).reshape(-1, 5)
    objects, bounds = [], []
    for i, b in enumerate(scene.boxes):
        objects.append((OBJ_BOX, i))
        bounds.append([*b.center, float(np.linalg.norm(np.asarray(b.size) / 2))])
    for i, s in enumerate(scene.spheres):
        objects.append((OBJ_SPHERE, i))
        bounds.append([*s.center, s.radius])
    for i, c in enumerate(scene.cylinders):
        objects.append((OBJ_CYLINDER, i))
        half_h = (c.z1 - c.z0) / 2
        bounds.append([c.x, c.y, (c.z0 + c.z1) / 2, float(np.hypot(half_h, c.radius))])

    sphere_mat = np.array([mid(s.material) for s in scene.spheres], np.int64)
    cyl_mat = np.array(
        [[mid(c.material), mid(c.cap or c.material)] for c in scene.cylinders], np.int64
    ).reshape(-1, 2)
    decal_rect = np.array([[d.s0, d.r0, d.s1, d.r1] for _, d in decals], float).reshape(-1, 4)
    decal_mat = np.array([mid(d.material) for _, d in decals], np.int64)

    tex_names = sorted({m.texture for m in materials if m.texture is not None})
    bank = build_texture_bank(tuple(tex_names))
    mat_f = np.array(
        [[*m.color, *m.emission, m.tile, m.mix] for m in materials], float
    ).reshape(-1, 8)
    mat_tex = np.array(
        [bank.index(m.texture) if m.texture is not None else -1 for m in materials], np.int64
    )
    lights = np.array(
        [[*lt.position, *lt.intensity, lt.radius] for lt in scene.lights], float
    ).reshape(-1, 7)
    return PackedScene(
        room=np.concatenate([lo, hi]),
        faces=np.asarray(face_rows, np.float64),
        face_mat=np.asarray(face_mat, np.int64),
        decal_rect=decal_rect,
        decal_mat=decal_mat,
        face_decal_start=start,
        face_decal_count=count,
        boxes=boxes,
        spheres=spheres,
        sphere_mat=sphere_mat,
        cylinders=cylinders,
        cylinder_mat=cyl_mat,
        objects=np.asarray(objects, np.int64).reshape(-1, 2),
        object_bounds=np.asarray(bounds, np.float64).reshape(-1, 4),
        mat_f=mat_f,
        mat_tex=mat_tex,
        lights=lights,
        ambient=np.asarray(scene.ambient, np.float64),
        textures=bank,
    )
