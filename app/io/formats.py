"""The object JSON format: which asset to light and where it stands in the room.

    {"mesh": "path.glb" | "sphere", "translate": [x, y, z], "scale": s, "rotate_deg": [x, y, z]}

``mesh`` is relative to the JSON file (or "sphere": diameter 1, or "knot": the demo asset). ``translate`` (metres,
default 0) and ``scale`` (> 0, default 1) and ``rotate_deg`` (default 0) are optional; unknown keys
are errors, so a typo such as "translation" is not silently ignored.

Placement, in this order: the triangles' axis-aligned bounding box is centred on the origin and
scaled uniformly to a largest extent of 1 (glTF node transforms already applied); then rotated by
``rotate_deg`` as XYZ Euler angles about the fixed world axes - first about x, then y, then z,
i.e. R = Rz @ Ry @ Rx (right-handed, counter-clockwise looking down each axis); then scaled by
``scale``; then translated. The camera JSON lives in app.camera, the material JSON in app.material.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from app.errors import ScanlightError
from app.io.files import read_json, require_file
from app.io.limits import OBJECT_SCALE
from app.io.mesh import MESH_EXTENSIONS, Mesh, load_mesh, make_sphere_mesh, transform_mesh
from app.io.schema import Fields

SPHERE = "sphere"
BUILTIN_MESHES = (SPHERE, "knot")  # the demo's sphere and its procedural non-convex asset


def builtin_mesh(name: str, sphere_subdivisions: int = 4) -> Mesh:
    """A built-in asset, centred with largest extent 1 (the sphere: diameter 1)."""
    from app.io.mesh import make_default_asset, normalize_mesh
    if name == SPHERE:
        return make_sphere_mesh(sphere_subdivisions)
    return normalize_mesh(make_default_asset())
OBJECT_KEYS = ("mesh", "translate", "scale", "rotate_deg")


@dataclass(frozen=True)
class ObjectSpec:
    """mesh: "sphere" or an absolute path; the rest as in the module docstring."""

    mesh: str
    translate: tuple[float, float, float] = (0.0, 0.0, 0.0)
    scale: float = 1.0
    rotate_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    source: str | None = None


def object_from_dict(d, base_dir, source=None) -> ObjectSpec:
    """Validate a parsed object JSON; a relative mesh path is resolved against ``base_dir``."""
    f = Fields(d, "object", source, OBJECT_KEYS)
    if "mesh" not in f:
        raise ScanlightError(source, "object has no 'mesh' key (a mesh file path or \"sphere\" or \"knot\")")
    mesh = f.path("mesh", alternatives=' or "sphere" (or "knot")')
    if mesh not in BUILTIN_MESHES:
        p = Path(mesh)
        p = (Path(base_dir) / p if not p.is_absolute() else p).resolve()
        if p.suffix.lower() not in MESH_EXTENSIONS:
            raise ScanlightError(source, f"object mesh {mesh!r} has an unsupported extension "
                                         f"(supported: {', '.join(MESH_EXTENSIONS)}, "
                                         "or \"sphere\")")
        if not p.is_file():
            raise ScanlightError(source, f"object mesh file {mesh!r} not found (looked at {p})")
        mesh = str(p)
    scale = f.number("scale", 1.0, *OBJECT_SCALE)
    translate = f.vec3("translate", (0.0, 0.0, 0.0))
    rotate = f.vec3("rotate_deg", (0.0, 0.0, 0.0), limit=None)
    return ObjectSpec(mesh, translate, scale, rotate, None if source is None else str(source))


def load_object(path) -> ObjectSpec:
    p = require_file(path, "object", (".json",))
    return object_from_dict(read_json(p, "object"), p.parent, p)


def rotation_xyz(degrees) -> np.ndarray:
    """R = Rz @ Ry @ Rx: rotate about world x first, then y, then z."""
    x, y, z = np.radians(np.asarray(degrees, dtype=np.float64))
    cx, sx, cy, sy, cz, sz = np.cos(x), np.sin(x), np.cos(y), np.sin(y), np.cos(z), np.sin(z)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def object_matrix(spec: ObjectSpec) -> np.ndarray:
    """4x4 placement applied after normalisation: translate @ scale @ rotate."""
    m = np.eye(4)
    m[:3, :3] = spec.scale * rotation_xyz(spec.rotate_deg)
    m[:3, 3] = spec.translate
    return m


def placed_mesh(spec: ObjectSpec, sphere_subdivisions: int = 4) -> Mesh:
    """The object's mesh in room coordinates (see the module docstring for the order)."""
    if spec.mesh in BUILTIN_MESHES:
        mesh = builtin_mesh(spec.mesh, sphere_subdivisions)
    else:
        mesh = load_mesh(spec.mesh, normalize=True)
    return transform_mesh(mesh, object_matrix(spec))
