"""The built-in procedural indoor scenes (fixed layouts; the seed only drives the camera).

World frame: metres, ``z`` up, floor at ``z = 0``. See :mod:`scene` for face coordinates
``(s, r)`` used by decals: on a wall, ``s`` runs to the right as seen from inside the room and
``r`` is the height above the floor. For the walls of a room ``[0, X] x [0, Y]``:
``x-``: ``s = y``; ``x+``: ``s = Y - y``; ``y-``: ``s = X - x``; ``y+``: ``s = x``;
floor: ``s = x, r = y``; ceiling: ``s = X - x, r = y``.

Radiance scale: 1.0 is LDR white at camera gain 1. Walls are lit to roughly 0.1-0.6; lamp
shades, ceiling panels, screens and windows emit 1-10 (HDR: they saturate in the LDR frames
while their texture still modulates log-brightness, so events see detail there).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from egs_bench.datasets.synthetic.scene import (
    Box,
    Cylinder,
    Decal,
    Light,
    Material,
    Scene,
    Sphere,
)
from egs_bench.errors import ConfigError

# Shared materials (linear albedo / radiance).
PLASTER = Material((0.62, 0.6, 0.55), "gravel", tile=2.5, mix=0.15)
CEILING = Material((0.7, 0.7, 0.7), "gravel", tile=3.0, mix=0.08)
BRICK = Material((0.55, 0.3, 0.22), "brick", tile=1.2)
WOOD = Material((0.45, 0.28, 0.15), "grass", tile=0.5, mix=0.35)
DARK_WOOD = Material((0.25, 0.14, 0.07), "grass", tile=0.5, mix=0.3)
METAL = Material((0.2, 0.2, 0.22))
BLACK = Material((0.03, 0.03, 0.035))
WHITE = Material((0.8, 0.8, 0.78))
FRAME = Material((0.08, 0.06, 0.05))
PANEL = Material((0.0, 0.0, 0.0), emission=(6.0, 6.0, 5.5))


def picture(texture: str, gain: float = 1.0) -> Material:
    """A photograph stretched over its rectangle (diffuse)."""
    return Material((gain, gain, gain), texture, tile=0.0)


def glowing(texture: str, radiance: float,
            tint: tuple[float, float, float] = (1.0, 1.0, 1.0)) -> Material:
    """A self-luminous photograph (screen, window view): emission = radiance * tint * texture."""
    emission = (radiance * tint[0], radiance * tint[1], radiance * tint[2])
    return Material((0.0, 0.0, 0.0), texture, tile=0.0, emission=emission)


def framed(face: str | tuple[int, str], s0: float, r0: float, s1: float, r1: float,
           material: Material, border: float = 0.04) -> list[Decal]:
    """A decal with a dark frame around it."""
    return [
        Decal(face, s0 - border, r0 - border, s1 + border, r1 + border, FRAME),
        Decal(face, s0, r0, s1, r1, material),
    ]


def window(face: str | tuple[int, str], s0: float, r0: float, s1: float, r1: float, view: Material,
           bars: int = 1) -> list[Decal]:
    """A bright window: white frame, emissive view, ``bars`` vertical and one horizontal bar."""
    out = [
        Decal(face, s0 - 0.06, r0 - 0.06, s1 + 0.06, r1 + 0.06, WHITE),
        Decal(face, s0, r0, s1, r1, view),
    ]
    for k in range(1, bars + 1):
        s = s0 + (s1 - s0) * k / (bars + 1)
        out.append(Decal(face, s - 0.025, r0, s + 0.025, r1, WHITE))
    rm = (r0 + r1) / 2
    out.append(Decal(face, s0, rm - 0.025, s1, rm + 0.025, WHITE))
    return out


def potted_plant(x: float, y: float, size: float = 1.0) -> tuple[Cylinder, Sphere]:
    pot = Cylinder(x, y, 0.0, 0.35 * size, 0.17 * size, Material((0.55, 0.25, 0.12)), BLACK)
    leaves = Sphere((x, y, 0.35 * size + 0.3 * size), 0.33 * size,
                    Material((0.12, 0.3, 0.06), "grass", tile=0.25))
    return pot, leaves


def books(x_face: float, y0: float, y1: float, z: float, rng: np.random.Generator,
          toward: float = -1.0) -> list[Box]:
    """A row of books standing on a shelf whose front is the plane ``x = x_face``."""
    out = []
    y = y0
    palette = [(0.5, 0.08, 0.06), (0.08, 0.2, 0.45), (0.1, 0.35, 0.12), (0.6, 0.5, 0.1),
               (0.35, 0.1, 0.35), (0.7, 0.7, 0.65), (0.05, 0.05, 0.05)]
    while True:
        w = rng.uniform(0.03, 0.07)
        if y + w > y1:
            break
        h = rng.uniform(0.2, 0.3)
        depth = 0.22
        cx = x_face + toward * (depth / 2 - 0.04)
        color = palette[rng.integers(len(palette))]
        out.append(Box((cx, y + w / 2, z + h / 2), (depth, w * 0.95, h), Material(color)))
        y += w
    return out


def office() -> Scene:
    X, Y, Z = 5.0, 4.0, 2.7
    rng = np.random.default_rng(7)
    chair_fabric = Material((0.12, 0.18, 0.4), "grass", tile=0.3, mix=0.4)
    sc = Scene(
        name="office",
        description="5x4 m office: desk with glowing monitor, bookshelf, whiteboard, brick wall "
        "with a bright window, ceiling light panels, desk lamp",
        lo=(0.0, 0.0, 0.0),
        hi=(X, Y, Z),
        walls={"x-": PLASTER, "x+": PLASTER, "y-": PLASTER, "y+": BRICK,
               "floor": Material((0.3, 0.28, 0.32), "gravel", tile=0.6, mix=0.5),
               "ceiling": CEILING},
        camera_box=((1.6, 0.8, 1.25), (3.4, 1.9, 1.7)),
        target_box=((0.8, 2.8, 0.7), (4.2, 3.9, 1.5)),
        ambient=(0.1, 0.1, 0.1),
    )
    # Desk, legs, monitor, keyboard.
    sc.boxes.append(Box((2.5, 3.55, 0.73), (1.6, 0.8, 0.04), WOOD))
    for lx in (1.75, 3.25):
        for ly in (3.2, 3.9):
            sc.boxes.append(Box((lx, ly, 0.355), (0.05, 0.05, 0.71), METAL))
    sc.boxes.append(Box((2.5, 3.7, 1.02), (0.62, 0.04, 0.38), BLACK,
                        faces={"y-": glowing("astronaut", 1.3)}))
    sc.boxes.append(Box((2.5, 3.72, 0.82), (0.06, 0.06, 0.16), METAL))
    sc.boxes.append(Box((2.5, 3.72, 0.76), (0.25, 0.18, 0.02), METAL))
    sc.boxes.append(Box((2.4, 3.35, 0.76), (0.45, 0.15, 0.02), Material((0.1, 0.1, 0.1))))
    sc.boxes.append(Box((2.0, 3.3, 0.77), (0.21, 0.3, 0.04), picture("page", 0.9), yaw=0.3))
    # Chair.
    sc.boxes.append(Box((2.5, 2.85, 0.47), (0.46, 0.46, 0.07), chair_fabric))
    sc.boxes.append(Box((2.5, 2.62, 0.8), (0.46, 0.06, 0.5), chair_fabric))
    sc.cylinders.append(Cylinder(2.5, 2.85, 0.08, 0.44, 0.025, METAL))
    sc.cylinders.append(Cylinder(2.5, 2.85, 0.0, 0.08, 0.28, METAL))
    # Bookshelf against x+ with three shelves of books.
    shelf_front = 4.62
    sc.boxes.append(Box((4.81, 1.6, 0.95), (0.38, 1.0, 1.9), DARK_WOOD))
    for z in (0.3, 0.85, 1.4):
        sc.boxes.append(Box((4.74, 1.6, z - 0.015), (0.3, 1.0, 0.03), WOOD))
        sc.boxes.extend(books(shelf_front, 1.12, 2.08, z, rng))
    # Globe, mug, desk lamp, bin, plant.
    sc.spheres.append(Sphere((1.95, 3.65, 0.9), 0.15, picture("moon", 1.0)))
    sc.cylinders.append(Cylinder(1.95, 3.65, 0.75, 0.76, 0.08, METAL))
    sc.cylinders.append(Cylinder(3.0, 3.35, 0.75, 0.85, 0.04, Material((0.6, 0.1, 0.08)), WHITE))
    sc.cylinders.append(Cylinder(3.45, 3.78, 0.75, 0.77, 0.08, METAL))
    sc.cylinders.append(Cylinder(3.45, 3.78, 0.77, 1.12, 0.012, METAL))
    bulb = Material((0, 0, 0), emission=(9.0, 8.0, 6.0))
    sc.spheres.append(Sphere((3.45, 3.78, 1.17), 0.07, bulb))
    sc.lights.append(Light((3.45, 3.7, 1.15), (0.35, 0.3, 0.22), 0.1))
    sc.cylinders.append(Cylinder(3.7, 3.1, 0.0, 0.32, 0.13, Material((0.25, 0.3, 0.3)), BLACK))
    sc.cylinders.append(potted_plant(0.45, 3.5)[0])
    sc.spheres.append(potted_plant(0.45, 3.5)[1])
    # Walls: whiteboard (x-), window and picture (y+), poster (y-), rug, ceiling panels.
    sc.decals += [Decal("x-", 1.0, 0.9, 3.0, 2.0, Material((0.55, 0.55, 0.55))),
                  Decal("x-", 1.03, 0.93, 2.97, 1.97, picture("page", 1.0))]
    sc.decals += window("y+", 0.6, 1.0, 1.6, 2.2, glowing("rocket", 3.0))
    sc.decals += framed("y+", 3.7, 1.3, 4.5, 2.0, picture("coffee"))
    sc.decals += framed("y-", 1.6, 1.1, 3.0, 2.1, picture("chelsea"))
    sc.decals += framed("y-", 3.5, 1.2, 4.2, 1.9, picture("camera"))
    sc.decals.append(Decal("floor", 1.3, 1.0, 3.7, 2.5, picture("ihc", 0.8)))
    for y0 in (1.1, 2.6):
        sc.decals.append(Decal("ceiling", 1.9, y0, 3.1, y0 + 0.6, PANEL))
        sc.lights.append(Light((2.5, y0 + 0.3, 2.5), (1.6, 1.6, 1.5), 0.3))
    return sc


def livingroom() -> Scene:
    X, Y, Z = 6.0, 4.5, 2.6
    fabric = Material((0.2, 0.28, 0.5), "grass", tile=0.3, mix=0.35)
    cushion = Material((0.55, 0.42, 0.2), "gravel", tile=0.3, mix=0.3)
    sc = Scene(
        name="livingroom",
        description="6x4.5 m living room: sofa under a garden window, coffee table on a rug, "
        "TV, brick fireplace with a glowing fire, floor lamp, pendant light",
        lo=(0.0, 0.0, 0.0),
        hi=(X, Y, Z),
        walls={"x-": BRICK, "x+": Material((0.62, 0.55, 0.45), "gravel", tile=2.5, mix=0.15),
               "y-": PLASTER, "y+": Material((0.5, 0.55, 0.5), "gravel", tile=2.5, mix=0.15),
               "floor": Material((0.42, 0.28, 0.16), "grass", tile=0.7, mix=0.35),
               "ceiling": CEILING},
        camera_box=((1.3, 1.0, 1.2), (3.3, 3.4, 1.7)),
        target_box=((3.8, 0.6, 0.4), (5.9, 4.2, 1.6)),
        ambient=(0.08, 0.075, 0.07),
    )
    # Sofa along x+ under the window, facing -x.
    sc.boxes.append(Box((5.45, 2.25, 0.22), (0.9, 2.0, 0.44), fabric))
    sc.boxes.append(Box((5.82, 2.25, 0.6), (0.16, 2.0, 0.5), fabric))
    for y in (1.17, 3.33):
        sc.boxes.append(Box((5.45, y, 0.31), (0.9, 0.16, 0.62), fabric))
    for y in (1.6, 2.25, 2.9):
        sc.boxes.append(Box((5.38, y, 0.5), (0.6, 0.6, 0.12), fabric))
    sc.boxes.append(Box((5.62, 1.75, 0.7), (0.14, 0.45, 0.4), cushion, yaw=0.15))
    # Coffee table, things on it, rug.
    sc.boxes.append(Box((4.2, 2.25, 0.42), (0.6, 1.1, 0.05), WOOD))
    for dx in (-0.25, 0.25):
        for dy in (-0.5, 0.5):
            sc.cylinders.append(Cylinder(4.2 + dx, 2.25 + dy, 0.0, 0.4, 0.025, DARK_WOOD))
    sc.spheres.append(Sphere((4.15, 2.0, 0.53), 0.08, picture("colorwheel")))
    sc.boxes.append(Box((4.25, 2.55, 0.465), (0.25, 0.32, 0.04), picture("astronaut"), yaw=-0.4))
    coffee = Material((0.2, 0.1, 0.05))
    sc.cylinders.append(Cylinder(4.3, 1.85, 0.445, 0.56, 0.045, WHITE, coffee))
    sc.decals.append(Decal("floor", 3.3, 1.2, 5.0, 3.3, picture("ihc", 0.9)))
    # TV on a sideboard against y+.
    sc.boxes.append(Box((3.5, 4.25, 0.25), (1.6, 0.45, 0.5), DARK_WOOD))
    tv_screen = glowing("rocket", 1.0)
    sc.boxes.append(Box((3.5, 4.44, 1.25), (1.2, 0.06, 0.7), BLACK, faces={"y-": tv_screen}))
    # Fireplace on the brick wall (x-).
    stone = Material((0.5, 0.48, 0.45), "gravel", tile=0.8, mix=0.4)
    soot = Material((0.04, 0.03, 0.03))
    sc.boxes.append(Box((0.25, 2.25, 0.55), (0.5, 1.5, 1.1), stone, faces={"x+": soot}))
    sc.boxes.append(Box((0.3, 2.25, 1.14), (0.6, 1.7, 0.08), DARK_WOOD))
    fire = Material((0.0, 0.0, 0.0), "gravel", tile=0.4, emission=(3.5, 1.5, 0.4))
    # Box (index) faces are addressed as (box index, face); the fireplace is box len-2.
    fp = len(sc.boxes) - 2
    sc.decals.append(Decal((fp, "x+"), 0.35, 0.1, 1.15, 0.7, fire))
    sc.lights.append(Light((0.7, 2.25, 0.4), (0.6, 0.3, 0.08), 0.2))
    sc.spheres.append(Sphere((0.3, 1.7, 1.28), 0.1, picture("moon")))
    sc.cylinders.append(Cylinder(0.3, 2.8, 1.18, 1.42, 0.06, Material((0.1, 0.25, 0.4))))
    # Window with a garden view over the sofa (x+), pictures.
    garden = glowing("grass", 1.8, (0.55, 1.0, 0.4))
    sc.decals += window("x+", 1.4, 0.95, 3.1, 2.25, garden, bars=2)
    sc.decals += framed("y+", 1.0, 1.2, 1.9, 1.9, picture("chelsea"))
    sc.decals += framed("y-", 2.0, 1.1, 3.2, 1.9, picture("coffee"))
    sc.decals += framed("x-", 3.3, 1.3, 3.9, 1.9, picture("camera"))
    # Floor lamp, pendant light, plant.
    sc.cylinders.append(Cylinder(5.6, 0.45, 0.0, 0.03, 0.15, METAL))
    sc.cylinders.append(Cylinder(5.6, 0.45, 0.03, 1.45, 0.015, METAL))
    shade = Material((0.0, 0.0, 0.0), "page", tile=0.0, emission=(3.5, 2.9, 2.0))
    sc.cylinders.append(Cylinder(5.6, 0.45, 1.45, 1.75, 0.2, shade, Material((0.9, 0.85, 0.7))))
    sc.lights.append(Light((5.6, 0.45, 1.6), (0.9, 0.75, 0.5), 0.25))
    pendant = Material((0, 0, 0), emission=(7.0, 6.3, 5.0))
    sc.spheres.append(Sphere((3.0, 2.25, 2.25), 0.16, pendant))
    sc.cylinders.append(Cylinder(3.0, 2.25, 2.4, 2.6, 0.008, BLACK))
    sc.lights.append(Light((3.0, 2.25, 2.15), (2.2, 2.0, 1.7), 0.3))
    pot, leaves = potted_plant(0.45, 4.05, 1.2)
    sc.cylinders.append(pot)
    sc.spheres.append(leaves)
    return sc


def studio() -> Scene:
    X, Y, Z = 7.0, 5.0, 3.2
    concrete = Material((0.4, 0.4, 0.42), "gravel", tile=1.5, mix=0.35)
    sc = Scene(
        name="studio",
        description="7x5 m photo studio: checkerboard floor, textured spheres on pedestals, "
        "bright softboxes, easel with a canvas, brick column, large mural",
        lo=(0.0, 0.0, 0.0),
        hi=(X, Y, Z),
        walls={"x-": Material((0.75, 0.75, 0.72), "brick", tile=1.2, mix=0.6), "x+": concrete,
               "y-": concrete, "y+": concrete,
               "floor": Material((0.6, 0.6, 0.6), "checkerboard", tile=1.2),
               "ceiling": Material((0.2, 0.2, 0.2))},
        camera_box=((2.0, 0.8, 1.2), (4.8, 2.2, 1.8)),
        target_box=((1.5, 3.0, 0.5), (5.8, 4.6, 1.6)),
        ambient=(0.07, 0.07, 0.075),
    )
    sc.decals += framed("y+", 1.5, 0.6, 5.5, 2.8, picture("coffee", 0.9), border=0.08)
    # Pedestals with spheres.
    for (x, y), tex in zip([(2.5, 3.6), (3.5, 3.95), (4.5, 3.6)], ["moon", "colorwheel", "hubble"],
                           strict=True):
        sc.boxes.append(Box((x, y, 0.45), (0.4, 0.4, 0.9), WHITE))
        sc.spheres.append(Sphere((x, y, 1.1), 0.2, picture(tex)))
    # Easel with a canvas, turned towards the room centre.
    yaw = -0.99
    sc.boxes.append(Box((5.8, 3.0, 1.25), (0.9, 0.04, 0.7), WHITE, yaw=yaw,
                        faces={"y-": picture("rocket")}))
    sc.boxes.append(Box((5.83, 3.05, 0.8), (0.05, 0.05, 1.6), DARK_WOOD, yaw=yaw))
    sc.boxes.append(Box((5.8, 3.0, 0.88), (0.9, 0.06, 0.04), DARK_WOOD, yaw=yaw))
    # Softboxes on stands, each with a point light in front.
    for x, y, yaw_s in [(1.0, 3.3, -0.6), (6.2, 1.6, 0.9)]:
        sc.boxes.append(Box((x, y, 1.8), (0.7, 0.15, 0.7), BLACK, yaw=yaw_s,
                            faces={"y-": Material((0, 0, 0), emission=(10.0, 10.0, 9.5))}))
        sc.cylinders.append(Cylinder(x, y, 0.0, 1.45, 0.02, METAL))
        front = np.array([np.sin(yaw_s), -np.cos(yaw_s)])
        lamp_pos = (x + 0.3 * front[0], y + 0.3 * front[1], 1.8)
        sc.lights.append(Light(lamp_pos, (2.0, 2.0, 1.9), 0.35))
    column = Material((0.55, 0.35, 0.28), "brick", tile=0.8)
    sc.cylinders.append(Cylinder(6.3, 4.3, 0.0, Z, 0.25, column))
    stool, stool_top = Material((0.5, 0.1, 0.1)), Material((0.3, 0.05, 0.05))
    sc.cylinders.append(Cylinder(1.0, 1.0, 0.0, 0.6, 0.22, stool, stool_top))
    sc.decals += framed("x-", 1.5, 1.1, 2.4, 1.8, picture("astronaut"))
    skylight = Material((0, 0, 0), emission=(3.0, 3.0, 3.0))
    sc.decals.append(Decal("ceiling", 2.5, 1.5, 4.5, 3.5, skylight))
    sc.lights.append(Light((3.5, 2.5, 3.0), (2.0, 2.0, 2.0), 0.5))
    return sc


def corridor() -> Scene:
    X, Y, Z = 10.0, 2.4, 2.6
    wall = Material((0.7, 0.68, 0.6), "gravel", tile=2.0, mix=0.12)
    dado = Material((0.35, 0.22, 0.12), "grass", tile=0.6, mix=0.3)
    door = Material((0.3, 0.18, 0.09), "grass", tile=0.8, mix=0.25)
    sc = Scene(
        name="corridor",
        description="10x2.4 m corridor: doors, posters, pillars and a row of ceiling lights "
        "leading to a bright glass door; large depth range",
        lo=(0.0, 0.0, 0.0),
        hi=(X, Y, Z),
        walls={"x-": wall, "x+": wall, "y-": wall, "y+": wall,
               "floor": Material((0.5, 0.48, 0.45), "gravel", tile=0.8, mix=0.6),
               "ceiling": CEILING},
        camera_box=((0.8, 0.9, 1.3), (3.0, 1.5, 1.7)),
        target_box=((5.0, 0.2, 0.7), (9.5, 2.2, 1.9)),
        ambient=(0.06, 0.06, 0.06),
    )
    for face in ("y-", "y+"):
        sc.decals.append(Decal(face, 0.0, 0.0, X, 0.9, dado))
        sc.decals.append(Decal(face, 0.0, 0.9, X, 0.95, DARK_WOOD))
    # Doors: (face, s0); y+ has s = x, y- has s = X - x.
    for face, s0 in [("y+", 2.0), ("y+", 6.0), ("y-", 1.1), ("y-", 5.1)]:
        sc.decals.append(Decal(face, s0 - 0.06, 0.0, s0 + 0.96, 2.11, WHITE))
        sc.decals.append(Decal(face, s0, 0.0, s0 + 0.9, 2.05, door))
        x_handle = s0 + 0.8 if face == "y+" else X - (s0 + 0.8)
        y_handle = Y - 0.03 if face == "y+" else 0.03
        sc.spheres.append(Sphere((x_handle, y_handle, 1.0), 0.03, Material((0.7, 0.6, 0.3))))
    posters = [("y+", 3.6, "astronaut"), ("y+", 7.6, "chelsea"), ("y+", 8.8, "camera"),
               ("y-", 2.8, "coffee"), ("y-", 6.8, "rocket"), ("y-", 8.2, "page")]
    for face, s0, tex in posters:
        sc.decals += framed(face, s0, 1.15, s0 + 0.7, 1.9, picture(tex))
    # Far end: bright glass door; near end: exit sign.
    sc.decals += window("x+", 0.7, 0.0, 1.7, 2.2, glowing("rocket", 5.0))
    exit_sign = Material((0, 0, 0), emission=(0.2, 2.5, 0.5))
    sc.decals.append(Decal("x-", 0.9, 2.15, 1.5, 2.4, exit_sign))
    # Ceiling lights.
    for x in (1.5, 3.5, 5.5, 7.5, 9.0):
        sc.decals.append(Decal("ceiling", X - x - 0.3, 0.95, X - x + 0.3, 1.45, PANEL))
        sc.lights.append(Light((x, 1.2, 2.45), (0.9, 0.9, 0.85), 0.3))
    # Pillars, bench, extinguisher, plants, radiator.
    for x in (4.0, 8.0):
        for y in (0.1, Y - 0.1):
            sc.boxes.append(Box((x, y, Z / 2), (0.3, 0.2, Z), Material((0.75, 0.75, 0.72))))
    sc.boxes.append(Box((6.0, 0.25, 0.22), (1.2, 0.4, 0.06), WOOD))
    for x in (5.5, 6.5):
        sc.boxes.append(Box((x, 0.25, 0.095), (0.06, 0.35, 0.19), METAL))
    extinguisher = Material((0.7, 0.05, 0.03))
    sc.cylinders.append(Cylinder(4.5, Y - 0.15, 0.25, 0.8, 0.09, extinguisher, BLACK))
    radiator = Material((0.85, 0.85, 0.85), "page", tile=0.25, mix=0.2)
    sc.boxes.append(Box((7.0, Y - 0.07, 0.45), (1.0, 0.08, 0.6), radiator))
    for y in (0.35, Y - 0.35):
        pot, leaves = potted_plant(9.5, y, 1.1)
        sc.cylinders.append(pot)
        sc.spheres.append(leaves)
    return sc


SCENES: dict[str, Callable[[], Scene]] = {
    "office": office,
    "livingroom": livingroom,
    "studio": studio,
    "corridor": corridor,
}


def list_scenes() -> dict[str, str]:
    """Scene names with a one-line description each."""
    return {name: build().description for name, build in SCENES.items()}


def build_scene(name: str) -> Scene:
    """The named scene; raises :class:`ConfigError` listing the names for an unknown one."""
    if name not in SCENES:
        raise ConfigError(f"unknown scene {name!r}; available: {', '.join(SCENES)}")
    return SCENES[name]()
