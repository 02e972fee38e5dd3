"""The scenes that measure the asset in the room against the reference protocol
(app/bench/mitsuba_scene.py): a non-convex asset lit by a panorama room, and an asset's shadow on
the demo room's floor. References: tests/pbgi/references/asset/ (made by
tests/pbgi/make_asset_references.py; CI only reads them).

* ``blocks_mesh``: the issue's "logo made of three cubes in front of a plate" - a 1.0 x 0.7 x
  0.05 m plate and three cubes (0.30, 0.24, 0.18 m) touching its front face at staggered heights,
  flat-shaded (every face its own vertices and normal): faces under another part of the asset,
  faces turned to the plate, crevices between cubes and plate.
* ``asset_scene(room, asset)``: the glossy sweep's panorama box room (100k points), the asset at
  the sweep sphere's centre, a three-quarter view from the front left and above, 96 x 96.
* ``shadow_scene()``: the demo room's ground truth, the demo sphere (0.2 m above the floor), a
  camera looking down at the floor around it, and the floor rectangle a shadow catcher covers
  in the reference (Mitsuba renders the catcher - a diffuse square of albedo CATCHER_ALBEDO a
  millimetre above the scan's floor - with and without the asset: their ratio is the shadow).

The reference path traces with ``max_depth`` 3: camera -> asset -> asset -> room, so one
inter-reflection of the asset is in it (what one bounce of our surfels models), and camera ->
catcher -> asset -> room, the asset's bounce onto the floor.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


ROOMS = {"apartment": "../shared/data/apartment.exr",     # tuning room
         "city": "../shared/data/city.exr"}               # held out
ASSETS = ("blocks", "sphere")
KINDS = ("diffuse", "rough_metal", "glossy_metal", "mirror_metal")
CONVEX_KINDS = ("diffuse",)       # the sphere cannot light itself: its other kinds add nothing
SIZE = 96
MAX_DEPTH = 3
CATCHER_ALBEDO = 0.5
FLOOR_RECT = (-0.9, 0.9, -0.9, 0.9)          # x0, x1, z0, z1 of the catcher on y = 0
REFERENCES = Path(__file__).resolve().parents[2] / "tests" / "pbgi" / "references" / "asset"
INDEX = "references.json"


def material(kind: str):
    from app.material import Material
    if kind == "diffuse":
        return Material(base_color=(0.7, 0.7, 0.7), metallic=0.0, roughness=1.0, specular=0.0)
    if kind == "rough_metal":
        return Material(base_color=(0.95, 0.64, 0.37), metallic=1.0, roughness=0.6)
    if kind == "glossy_metal":       # the plane and the mirror bounce mixed (asset_scene.py)
        return Material(base_color=(0.95, 0.64, 0.37), metallic=1.0, roughness=0.25)
    if kind == "mirror_metal":       # the mirror bounce alone
        return Material(base_color=(0.97, 0.96, 0.92), metallic=1.0, roughness=0.05)
    raise ValueError(f"unknown material kind {kind!r}")


def _box(lo, hi):
    """Flat-shaded box: 24 vertices (4 per face, the face's outward normal), 12 triangles."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    pos, nrm, idx = [], [], []
    for axis in range(3):
        for side in (0, 1):
            n = np.zeros(3)
            n[axis] = 1.0 if side else -1.0
            u, v = (axis + 1) % 3, (axis + 2) % 3
            corners = []
            for a, b in ((0, 0), (1, 0), (1, 1), (0, 1)):
                c = np.where(side, hi, lo).astype(float).copy()
                c[axis] = hi[axis] if side else lo[axis]
                c[u] = hi[u] if a else lo[u]
                c[v] = hi[v] if b else lo[v]
                corners.append(c)
            base = len(pos)
            # (u, v, axis) is right-handed: counter-clockwise seen from +axis
            order = (0, 1, 2, 0, 2, 3) if side else (0, 2, 1, 0, 3, 2)
            pos += corners
            nrm += [n] * 4
            idx += [base + k for k in order]
    return np.array(pos), np.array(nrm), np.array(idx).reshape(-1, 3)


def blocks_mesh():
    """Three cubes in front of a plate (module docstring), centred near the origin."""
    from app.io.mesh import build_mesh
    parts = [((-0.5, -0.35, -0.05), (0.5, 0.35, 0.0))]               # plate, front at z = 0
    for (x, y), s in (((-0.26, -0.12), 0.30), ((0.07, 0.12), 0.24), ((0.31, -0.16), 0.18)):
        parts.append(((x - s / 2, y - s / 2, 0.0), (x + s / 2, y + s / 2, s)))
    pos, nrm, idx = [], [], []
    for lo, hi in parts:
        p, n, i = _box(lo, hi)
        idx.append(i + sum(len(q) for q in pos))
        pos.append(p)
        nrm.append(n)
    return build_mesh(np.concatenate(pos), np.concatenate(idx), normals=np.concatenate(nrm),
                      source="builtin:blocks")


def asset_scene(room: str, asset: str):
    """(cloud, mesh, camera): the panorama room ``room`` (a key of ROOMS or an .exr path)."""
    from app.bench.glossy import SPHERE, glossy_scene
    from app.camera import Camera
    from app.io.mesh import transform_mesh
    path = ROOMS.get(room, room)
    cloud, sphere, cam = glossy_scene(path, size=SIZE)
    centre = 0.5 * np.add(*sphere.bounds())
    if asset == "sphere":
        mesh = sphere
    elif asset == "blocks":
        m = np.eye(4)
        m[:3, 3] = centre
        mesh = transform_mesh(blocks_mesh(), m)
    else:
        raise ValueError(f"unknown asset {asset!r}")
    eye = centre + np.array([-0.55, 0.45, 1.25]) * (1.0 if asset == "blocks" else 1.4)
    cam = Camera(eye, centre + np.array([0.0, 0.0, 0.1 if asset == "blocks" else 0.0]),
                 fov_y_deg=45, width=SIZE, height=SIZE)
    return cloud, mesh, cam


def shadow_scene(points: int = 200_000):
    """(cloud, mesh, camera) of the demo room's shadow check (module docstring)."""
    from app.camera import Camera
    from app.demo.room import default_object, sample_room
    from app.io.formats import object_from_dict, placed_mesh
    cloud = sample_room(points, 0)
    mesh = placed_mesh(object_from_dict(default_object("sphere"), "."))
    cam = Camera((0.0, 1.9, 1.3), (0.0, 0.0, 0.05), fov_y_deg=50, width=SIZE, height=SIZE)
    return cloud, mesh, cam


def reference_name(room: str, asset: str, kind: str) -> str:
    return f"{room}_{asset}_{kind}.exr"


def load_index(directory=REFERENCES) -> dict:
    from app.bench.mitsuba_scene import read_index
    return read_index(directory, "tests/pbgi/make_asset_references.py")


def load_image(name: str, directory=REFERENCES) -> np.ndarray:
    from app.bench.mitsuba_scene import read_reference
    return read_reference(Path(directory) / name)
