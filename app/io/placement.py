"""Where a mesh opened directly stands in the scanned room: on the scan's floor, below its centre.

A user with a scan and a model (``render --object bunny.glb``, ``scanlight view room.ply
bunny.glb``, a mesh dropped on the viewer) wants to see the model in the room without writing an
object JSON. The placement, in this order (pure numpy: tests check it against the demo room):

1. Size: the file's own units (glTF is metres; OBJ has no unit and is read as metres), or with
   ``fit`` the largest extent of its bounding box scaled to ``fit`` metres. The built-in
   "sphere" and "knot" are 1 m across.
2. Rotation: ``rotate_deg``, the object JSON's XYZ Euler angles (R = Rz @ Ry @ Rx, world axes),
   about the mesh's bounding-box centre. It comes before the floor, so a turned model (a Z-up
   OBJ turned by -90 about x) still stands on the floor: the *rotated* mesh's lowest vertex
   touches it.
3. Floor: the rotated mesh's lowest vertex on the floor height (``floor_height``), its
   bounding-box centre in x and z over the room's centre (``room_centre_xz``).
4. ``translate`` (metres) last, from that spot: (0, 0.5, 0) lifts it half a metre.

The result is an object JSON's ``ObjectSpec`` (app.io.formats): the same normalised mesh and
translate/scale/rotate_deg the JSON and the viewer's asset transform use, so the viewer, the
renderer and a saved session agree on the placement to the bit.

The floor (y is up: app/camera.py, the demo room): the lowest large horizontal surface of the
scan. Points whose normal is within ~37 degrees of vertical (|n.y| > 0.8, either sign, because
photogrammetry flips normals) are the horizontal ones (all points where there are fewer than 16
of them); their 5th height percentile lies on the floor under a few percent of stray points
below it; the floor is then the median height of the horizontal points within ``FLOOR_BAND``
(5 cm) of that, i.e. the middle of the floor's noisy layer rather than its underside. With fewer
than 16 usable points there is no floor: the asset then stands on the scan's lowest point (or
y = 0 with none), and ``Room.floor_found`` is False (the callers log it).

The room's centre in x and z: the middle of the 2nd..98th percentile range of the scan's x and
z, a bounding box that a few stray points far outside the room do not move.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from app.errors import ScanlightError
from app.io.limits import MAX_COORD, OBJECT_SCALE

MIN_FLOOR_POINTS = 16
HORIZONTAL_NY = 0.8          # |normal.y| above this: a horizontal surface
FLOOR_PERCENTILE = 5.0       # of the horizontal points' heights: under it, strays and noise
FLOOR_BAND = 0.05            # metres above/below that percentile taken as the floor's layer
CENTRE_PERCENTILES = (2.0, 98.0)


@dataclass(frozen=True)
class Room:
    """What the placement needs of a scan: floor height, centre in x/z and how they were found."""

    floor_y: float
    centre_xz: tuple[float, float]
    floor_found: bool = True
    floor_from: str = "horizontal points"

    def to_dict(self) -> dict:
        return {"floor_y": round(self.floor_y, 6), "floor_found": self.floor_found,
                "floor_from": self.floor_from,
                "room_centre_xz": [round(v, 6) for v in self.centre_xz]}


def _finite(points) -> tuple[np.ndarray, np.ndarray]:
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    ok = np.isfinite(p).all(axis=1)
    return p[ok], ok


def floor_height(points, normals=None) -> tuple[float | None, str]:
    """(the floor's height or None, which points it came from); see the module docstring."""
    p, ok = _finite(points)
    y, source = p[:, 1], "all points (no normals)"
    if normals is not None:
        ny = np.abs(np.asarray(normals, dtype=np.float64).reshape(-1, 3)[ok, 1])
        flat = ny > HORIZONTAL_NY
        if flat.sum() >= MIN_FLOOR_POINTS:
            y, source = y[flat], "horizontal points"
        else:
            source = "all points (fewer than 16 horizontal ones)"
    if len(y) < MIN_FLOOR_POINTS:
        return None, f"none: {len(y)} usable points"
    low = np.percentile(y, FLOOR_PERCENTILE)
    layer = y[np.abs(y - low) <= FLOOR_BAND]
    return float(np.median(layer)), source


def room_centre_xz(points) -> tuple[float, float]:
    """The middle of the scan's robust x/z bounding box (origin for an empty scan)."""
    p, _ = _finite(points)
    if len(p) == 0:
        return 0.0, 0.0
    lo, hi = np.percentile(p[:, [0, 2]], CENTRE_PERCENTILES, axis=0)
    c = (lo + hi) / 2
    return float(c[0]), float(c[1])


def room_of(cloud) -> Room:
    """The floor and centre of a PointCloud (app.cloud)."""
    floor, source = floor_height(cloud.positions, cloud.normals)
    centre = room_centre_xz(cloud.positions)
    if floor is not None:
        return Room(floor, centre, True, source)
    p, _ = _finite(cloud.positions)
    low = float(p[:, 1].min()) if len(p) else 0.0
    return Room(low, centre, False, source + ("; standing on the lowest point" if len(p)
                                              else "; standing on y = 0"))


def _vec3(value, what: str) -> tuple[float, float, float]:
    v = np.zeros(3) if value is None else np.asarray(value, dtype=np.float64).reshape(-1)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or np.any(np.abs(v) > MAX_COORD):
        raise ScanlightError(None, f"{what} must be three finite numbers, got {value!r}")
    return float(v[0]), float(v[1]), float(v[2])


def floor_spec(name: str, mesh, room: Room, fit: float | None = None, translate=None,
               rotate=None, source=None):
    """The ObjectSpec (app.io.formats) standing ``mesh`` (the file as read, not normalised; its
    path or built-in name ``name``) in ``room``: see the module docstring for the order."""
    from app.io.formats import ObjectSpec, rotation_xyz
    used = mesh.positions[np.unique(mesh.indices)] if mesh.n_faces else mesh.positions
    lo, hi = used.min(axis=0), used.max(axis=0)
    extent = float(np.max(hi - lo))
    if not np.isfinite(extent) or extent <= 0:
        raise ScanlightError(source or name, "mesh has zero size (all vertices at one point)")
    scale = float(fit) if fit is not None else extent
    if not OBJECT_SCALE[0] <= scale <= OBJECT_SCALE[1]:
        raise ScanlightError(source or name, f"mesh is {scale:g} m across in its own units; "
                                             "give --fit S to scale it to S metres")
    rotate = _vec3(rotate, "rotate")
    # the normalised mesh (centred, extent 1), rotated and sized: where do its bounds fall?
    q = (used - (lo + hi) / 2) / extent @ (scale * rotation_xyz(rotate)).T
    qlo, qhi = q.min(axis=0), q.max(axis=0)
    move = _vec3(translate, "translate")
    spot = (room.centre_xz[0] - (qlo[0] + qhi[0]) / 2, room.floor_y - qlo[1],
            room.centre_xz[1] - (qlo[2] + qhi[2]) / 2)
    return ObjectSpec(name, tuple(float(a + b) for a, b in zip(spot, move)), scale, rotate,
                      None if source is None else str(source))


def read_unplaced(name: str):
    """The mesh file as read (its own units), or the built-in "sphere"/"knot" (1 m)."""
    from app.io.formats import BUILTIN_MESHES, builtin_mesh
    from app.io.mesh import load_mesh
    return builtin_mesh(name) if name in BUILTIN_MESHES else load_mesh(name)


def load_floor_spec(name: str, room: Room, fit=None, translate=None, rotate=None):
    """(spec, mesh placed by it, the file's largest extent in its own units): read the mesh
    file (or build the built-in), stand it in ``room``. The mesh is normalised once and placed
    with ``object_matrix``, exactly as ``placed_mesh(spec)`` would."""
    from app.io.formats import object_matrix
    from app.io.mesh import normalize_mesh, transform_mesh
    raw = read_unplaced(name)
    spec = floor_spec(name, raw, room, fit, translate, rotate, source=name)
    lo, hi = raw.bounds()
    return spec, transform_mesh(normalize_mesh(raw), object_matrix(spec)), float(np.max(hi - lo))


__all__ = ["Room", "floor_height", "room_centre_xz", "room_of", "floor_spec", "load_floor_spec",
           "read_unplaced", "FLOOR_BAND", "FLOOR_PERCENTILE", "HORIZONTAL_NY", "MIN_FLOOR_POINTS"]
