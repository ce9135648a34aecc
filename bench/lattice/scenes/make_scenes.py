#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Writes the hard scenes of bench/lattice (lattice_honesty.cpp) next to this script.

One small scene per case where the lattice sampler's error estimate is known to be weak
(docs/accuracy.md, "The lattice sampler's error estimate"): features between corners, sub-pixel
features, corners of equal radiance on different objects. Every scene is 192x108, vfov 40, so a
pixel spans 2 tan(20 deg) / 108 = 0.00674 of the distance from the eye; the sizes below are
chosen from that (the comment of each function gives them in pixels).

The JSON and OBJ files are committed; rerun this only to change a scene:
    python3 bench/lattice/scenes/make_scenes.py
"""
import json
import math
import os
import random

HERE = os.path.dirname(os.path.abspath(__file__))
PIXEL = 2 * math.tan(math.radians(20)) / 108  # a pixel's size per unit of distance from the eye


def image():
    return {"width": 192, "height": 108, "spp": 16, "max_depth": 8, "seed": 1}


def write_scene(name, scene):
    """As scenes/whitted.json is laid out: one line a light, material or object (the sphere grid's
    objects two a line, so the file stays under 700 lines)."""
    c = lambda v: json.dumps(v, separators=(", ", ": "))
    lines = []
    for key, value in scene.items():
        if key == "lights" or key == "objects":
            per_line = 2 if len(value) > 600 else 1
            items = [", ".join(c(o) for o in value[i:i + per_line]) for i in range(0, len(value), per_line)]
            lines.append('  "%s": [\n%s\n  ]' % (key, ",\n".join("    " + t for t in items)))
        elif key == "materials":
            items = ["    %s: %s" % (c(k), c(v)) for k, v in value.items()]
            lines.append('  "materials": {\n%s\n  }' % ",\n".join(items))
        else:
            lines.append("  %s: %s" % (c(key), c(value)))
    with open(os.path.join(HERE, name + ".json"), "w") as f:
        f.write("{\n" + ",\n".join(lines) + "\n}\n")


def sub(a, b):
    return [a[i] - b[i] for i in range(3)]


def cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def unit(a):
    n = math.sqrt(sum(x * x for x in a))
    return [x / n for x in a]


def box_along(p0, p1, width):
    """A box of square cross-section `width` from p0 to p1: 8 vertices, 12 triangles."""
    d = unit(sub(p1, p0))
    ref = [0, 1, 0] if abs(d[1]) < 0.9 else [1, 0, 0]
    u = unit(cross(d, ref))
    v = cross(d, u)
    h = width / 2
    verts = []
    for p in (p0, p1):
        for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
            verts.append([p[i] + su * h * u[i] + sv * h * v[i] for i in range(3)])
    # Faces as quads over vertex indices (0-3 at p0, 4-7 at p1), each split in two triangles.
    quads = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    tris = []
    for a, b, c, e in quads:
        tris += [(a, b, c), (a, c, e)]
    return verts, tris


def write_obj(name, boxes):
    path = os.path.join(HERE, name + ".obj")
    with open(path, "w") as f:
        f.write("# Written by make_scenes.py\n")
        base = 1
        for verts, tris in boxes:
            for v in verts:
                f.write("v %.6f %.6f %.6f\n" % tuple(v))
            for t in tris:
                f.write("f %d %d %d\n" % tuple(base + i for i in t))
            base += len(verts)


def subpixel_spheres():
    """Spheres of 0.024-0.03 diameter on a floor seen 5.5-11.8 away: 0.3-0.8 pixel wide."""
    rng = random.Random(7)
    objects = [{"type": "plane", "name": "floor", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "floor"}]
    colors = ["red", "blue", "white", "black"]
    spacing = 0.35
    for iz in range(24):
        z = 2.6 - iz * spacing
        dist = math.hypot(5, 5 - z)  # about the distance from the eye
        for ix in range(-20, 21):
            x = ix * spacing + (0.5 * spacing if iz % 2 else 0)
            if abs(x) > 0.72 * dist + 0.3:
                continue  # outside the frame
            # Projected diameter 0.3-0.8 pixel whatever the distance.
            r = 0.5 * rng.uniform(0.3, 0.8) * PIXEL * dist
            objects.append({"type": "sphere", "center": [round(x, 4), round(r, 5), round(z, 4)], "radius": round(r, 5),
                            "material": colors[rng.randrange(len(colors))]})
    write_scene("subpixel_spheres", {
        "camera": {"position": [0, 5, 5], "look_at": [0, 0, 0], "up": [0, 1, 0], "vfov_deg": 40},
        "image": image(),
        "background": [0.5, 0.6, 0.8],
        "lights": [{"type": "point", "position": [3, 6, 2], "intensity": 100}],
        "materials": {
            "floor": {"type": "diffuse", "albedo": 0.6},
            "red": {"type": "diffuse", "albedo": [0.9, 0.1, 0.05]},
            "blue": {"type": "diffuse", "albedo": [0.05, 0.2, 0.9]},
            "white": {"type": "diffuse", "albedo": 0.95},
            "black": {"type": "diffuse", "albedo": 0.03},
        },
        "objects": objects,
    })


def wires():
    """Boxes 0.010-0.016 across at 6 from the eye (0.25-0.4 pixel), horizontal, sloped, vertical."""
    rng = random.Random(11)
    dark, light = [], []
    for k, y in enumerate([1.55, 1.75, 1.95, 2.15]):
        dark.append(box_along([-7, y, 0], [7, y + 0.25 * (k - 1.5), 0], rng.uniform(0.010, 0.016)))
    for x in [-2.2, -0.9, 0.6, 1.8]:
        light.append(box_along([x, 0, 0.3], [x + 0.4, 3.2, -0.3], rng.uniform(0.010, 0.016)))
    for k in range(3):
        x = -3 + 2.4 * k
        dark.append(box_along([x, 0.2, 0.5], [x + 2.5, 2.6, -0.5], rng.uniform(0.010, 0.016)))
        light.append(box_along([x + 2.5, 0.3, 0.2], [x, 2.4, -0.2], rng.uniform(0.010, 0.016)))
    write_obj("wires_dark", dark)
    write_obj("wires_light", light)
    write_scene("wires", {
        "camera": {"position": [0, 1.2, 6], "look_at": [0, 1.2, 0], "up": [0, 1, 0], "vfov_deg": 40},
        "image": image(),
        "background": [0.6, 0.75, 0.95],
        "lights": [{"type": "point", "position": [2, 5, 5], "intensity": 60}],
        "materials": {
            "floor": {"type": "diffuse", "albedo": 0.5},
            "dark": {"type": "diffuse", "albedo": 0.05},
            "light": {"type": "diffuse", "albedo": [0.95, 0.9, 0.6]},
        },
        "objects": [
            {"type": "plane", "name": "floor", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "floor"},
            {"type": "mesh", "name": "dark_wires", "file": "wires_dark.obj", "material": "dark"},
            {"type": "mesh", "name": "light_wires", "file": "wires_light.obj", "material": "light"},
        ],
    })


def thin_shadows():
    """Rods out of view at height 6 under a point light at 9 cast shadows 3x their width (0.003-0.009)
    on a floor 4 below the eye: 0.33-1 pixel wide."""
    rng = random.Random(5)
    light = [0.3, 9, 0.2]
    rods = []
    for k in range(9):
        angle = math.radians(rng.uniform(0, 180))
        cx, cz = light[0] + rng.uniform(-0.7, 0.7), light[2] + rng.uniform(-0.4, 0.4)
        dx, dz = math.cos(angle), math.sin(angle)
        w = rng.uniform(1 / 3, 1.0) * PIXEL * 4 / 3
        rods.append(box_along([cx - 1.2 * dx, 6, cz - 1.2 * dz], [cx + 1.2 * dx, 6, cz + 1.2 * dz], w))
    write_obj("thin_shadows_rods", rods)
    write_scene("thin_shadows", {
        "camera": {"position": [0, 4, 0], "look_at": [0, 0, 0], "up": [0, 0, -1], "vfov_deg": 40},
        "image": image(),
        "background": [0.5, 0.6, 0.8],
        "lights": [{"type": "point", "position": light, "intensity": 160}],
        "materials": {
            "floor": {"type": "diffuse", "albedo": 0.8},
            "rod": {"type": "diffuse", "albedo": 0.5},
        },
        "objects": [
            {"type": "plane", "name": "floor", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "floor"},
            {"type": "mesh", "name": "rods", "file": "thin_shadows_rods.obj", "material": "rod"},
        ],
    })


# The paints of the small spheres of mirror_small and glass_small.
SMALL_SPHERE_PAINTS = {
    "red": {"type": "diffuse", "albedo": [0.95, 0.15, 0.1]},
    "yellow": {"type": "diffuse", "albedo": [0.95, 0.85, 0.1]},
    "blue": {"type": "diffuse", "albedo": [0.1, 0.3, 0.95]},
    "white": {"type": "diffuse", "albedo": 0.95},
}


def small_spheres(spheres):
    """Sphere objects from (x, y, z, radius, paint) tuples."""
    return [{"type": "sphere", "center": [x, y, z], "radius": r, "material": m} for x, y, z, r, m in spheres]


def mirror_small():
    """Spheres behind the eye, seen in a mirror 3.6 x 2.4 (framed by the floor and the sky) 11-13 away:
    0.5-4 pixels wide."""
    mirror = ([[-1.8, 0, 0], [1.8, 0, 0], [1.8, 2.4, 0], [-1.8, 2.4, 0]], [(0, 1, 2), (0, 2, 3)])
    write_obj("mirror_quad", [mirror])
    spheres = [  # (x, y, z, radius, material)
        (0.8, 1.2, 7.0, 0.15, "red"), (-1.5, 0.6, 7.5, 0.08, "yellow"), (2.2, 1.9, 8.0, 0.045, "blue"),
        (-0.6, 1.7, 7.0, 0.025, "white"), (-2.8, 1.3, 8.5, 0.03, "red"), (1.6, 0.35, 6.5, 0.02, "white"),
        (0.1, 2.3, 9.0, 0.035, "yellow"), (3.4, 0.9, 7.5, 0.06, "blue"),
    ]
    objects = [
        {"type": "plane", "name": "floor", "point": [0, -0.5, 0], "normal": [0, 1, 0], "material": "floor"},
        {"type": "mesh", "name": "mirror", "file": "mirror_quad.obj", "material": "mirror"},
    ]
    objects += small_spheres(spheres)
    write_scene("mirror_small", {
        "camera": {"position": [0, 1, 4], "look_at": [0, 1, 0], "up": [0, 1, 0], "vfov_deg": 40},
        "image": image(),
        "background": [0.2, 0.25, 0.35],
        "lights": [{"type": "point", "position": [1, 4, 5], "intensity": 60}],
        "materials": {
            "floor": {"type": "diffuse", "albedo": 0.5},
            "mirror": {"type": "mirror", "reflectance": 0.9},
            **SMALL_SPHERE_PAINTS,
        },
        "objects": objects,
    })


def glass_small():
    """Small spheres hidden behind a glass ball (radius 1, 5 from the eye), seen only through it, which
    magnifies them to 0.5-3 pixels."""
    spheres = [
        (0.3, 1.25, -2.0, 0.05, "red"), (-0.45, 0.75, -2.3, 0.03, "yellow"), (0.2, 0.55, -1.8, 0.02, "blue"),
        (-0.25, 1.45, -2.6, 0.035, "white"), (0.55, 0.9, -2.2, 0.015, "yellow"),
    ]
    objects = [
        {"type": "plane", "name": "floor", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "floor"},
        {"type": "sphere", "name": "glass_ball", "center": [0, 1, 0], "radius": 1, "material": "glass"},
    ]
    objects += small_spheres(spheres)
    write_scene("glass_small", {
        "camera": {"position": [0, 1, 5], "look_at": [0, 1, 0], "up": [0, 1, 0], "vfov_deg": 40},
        "image": image(),
        "background": [0.5, 0.6, 0.8],
        # One light in front: the small spheres' shadows fall behind them, out of direct view too
        # (shadow rays pass through glass, so the ball does not shade them).
        "lights": [{"type": "point", "position": [-2, 5, 4], "intensity": 100}],
        "materials": {
            "floor": {"type": "diffuse", "albedo": 0.55},
            "glass": {"type": "glass", "ior": 1.5},
            **SMALL_SPHERE_PAINTS,
        },
        "objects": objects,
    })


def spot_edges():
    """Two spots whose cones fall off over 0.1 degree (a quarter pixel on the floor), a dim fill."""
    write_scene("spot_edges", {
        "camera": {"position": [0, 3, 5], "look_at": [0, 0, 0], "up": [0, 1, 0], "vfov_deg": 40},
        "image": image(),
        "background": [0.05, 0.05, 0.08],
        "lights": [
            {"type": "spot", "position": [0, 4, 0], "direction": [0, -1, 0], "intensity": 40,
             "inner_cone_deg": 29.9, "outer_cone_deg": 30},
            {"type": "spot", "position": [-3, 3, 1], "direction": [1.2, -1, -0.9], "intensity": [30, 25, 12],
             "inner_cone_deg": 19.9, "outer_cone_deg": 20},
            {"type": "point", "position": [2, 6, 6], "intensity": 8},
        ],
        "materials": {
            "floor": {"type": "diffuse", "albedo": 0.7},
            "wall": {"type": "diffuse", "albedo": 0.6},
        },
        "objects": [
            {"type": "plane", "name": "floor", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "floor"},
            {"type": "plane", "name": "wall", "point": [0, 0, -2.5], "normal": [0, 0, 1], "material": "wall"},
        ],
    })


def tir():
    """A tilted glass cube and slab in front of checkers: total internal reflection inside them."""
    cube = box_along([0, 0, -0.6], [0, 0, 0.6], 1.2)
    slab = box_along([0, 0, -0.125], [0, 0, 0.125], 1.6)
    write_obj("tir_cube", [cube])
    write_obj("tir_slab", [slab])
    write_scene("tir", {
        "camera": {"position": [0, 1.6, 4.5], "look_at": [0, 0.9, 0], "up": [0, 1, 0], "vfov_deg": 40},
        "image": image(),
        "background": [0.9, 0.9, 0.95],
        "lights": [{"type": "point", "position": [-3, 6, 4], "intensity": 120},
                   {"type": "directional", "direction": [0.2, -1, -0.4], "irradiance": 1.0}],
        "materials": {
            "checker": {"type": "diffuse", "albedo": 0.9, "checker": {"albedo2": [0.05, 0.05, 0.1], "scale": 0.4}},
            "wall": {"type": "diffuse", "albedo": [0.95, 0.8, 0.2], "checker": {"albedo2": [0.1, 0.3, 0.8], "scale": 0.5}},
            "glass": {"type": "glass", "ior": 1.5},
        },
        "objects": [
            {"type": "plane", "name": "floor", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "checker"},
            {"type": "plane", "name": "wall", "point": [0, 0, -3], "normal": [0, 0, 1], "material": "wall"},
            {"type": "mesh", "name": "cube", "file": "tir_cube.obj", "material": "glass",
             "transform": {"translate": [-0.7, 1.0, 0], "rotate": [35, 40, 20]}},
            {"type": "mesh", "name": "slab", "file": "tir_slab.obj", "material": "glass",
             "transform": {"translate": [1.1, 0.9, 0.4], "rotate": [-20, -55, 10]}},
        ],
    })


def checker_horizon():
    """A checker plane of 1-unit squares to the horizon, lit by a directional light."""
    write_scene("checker_horizon", {
        "camera": {"position": [0, 1, 0], "look_at": [0, 0.4, -10], "up": [0, 1, 0], "vfov_deg": 40},
        "image": image(),
        "background": [0.55, 0.7, 0.95],
        "lights": [{"type": "directional", "direction": [0.3, -1, -0.2], "irradiance": 2.5}],
        "materials": {
            "checker": {"type": "diffuse", "albedo": 0.9, "checker": {"albedo2": [0.05, 0.05, 0.05], "scale": 1.0}},
        },
        "objects": [
            {"type": "plane", "name": "floor", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "checker"},
        ],
    })


if __name__ == "__main__":
    subpixel_spheres()
    wires()
    thin_shadows()
    mirror_small()
    glass_small()
    spot_edges()
    tir()
    checker_horizon()
