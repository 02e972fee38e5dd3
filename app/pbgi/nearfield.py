"""When the near field is not worth its cost: an asset far from every surface of the scan.

The micro-buffer modes exist for light that is near: a wall beside the asset subtends a
different solid angle from each of its points, and only a per-receiver cut sees that. Seen from
an asset far from every surface (its clearance, the distance from the asset to the nearest scan
point over the asset's bounding radius, is large), the room is the same from every point of the
asset, and the environment map from the asset's centre is exact enough at a fraction of the
cost. ``pbgi.envmap_beyond`` is the clearance from which the micro-buffer modes hand the frame
to the environment map; 0 never does.

The environment map has no self-occlusion and no narrow lobes worth the name, so the hand-over
happens only when neither is asked for (``near_field_needed``):
- every material is rough (roughness >= GLOSSY_ROUGHNESS and pbgi.glossy_below, no clearcoat,
  no roughness texture that could lower it): measured on the demo room, a roughness 0.25 lobe
  read from the cube map is still 16% (4x4 RMSE) from Classic at a clearance of 16;
- the asset cannot shadow itself: convex (its volume is that of its convex hull), or asset
  occlusion is off. The asset's own surfels are never dropped while they can matter.

README "Speed against accuracy" has the measurement that set the default.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from app.pbgi.lobe import needs_lobe

CONVEX_VOLUME_RATIO = 0.98    # mesh volume / hull volume above this: no concavity to shadow
GLOSSY_ROUGHNESS = 0.5        # below this (or any clearcoat, or a roughness texture) a material
#                               keeps the near field even when pbgi.glossy_below is lower


@dataclass(frozen=True)
class Clearance:
    ratio: float              # distance to the nearest scan point / the asset's bounding radius
    distance: float           # metres from the asset's surface (vertices) to the nearest point
    radius: float             # the asset's bounding radius about its box centre
    convex: bool              # the mesh is closed and its volume fills its convex hull


def mesh_is_convex(mesh) -> bool:
    """A closed mesh whose enclosed volume is at least CONVEX_VOLUME_RATIO of its hull's.
    An open or degenerate mesh counts as not convex (it may shadow itself)."""
    from scipy.spatial import ConvexHull, QhullError
    p = np.asarray(mesh.positions, np.float64)
    f = np.asarray(mesh.indices, np.int64).reshape(-1, 3)
    if len(f) < 4:
        return False
    used = p[np.unique(f)]
    c = used.mean(axis=0)
    a, b, d = p[f[:, 0]] - c, p[f[:, 1]] - c, p[f[:, 2]] - c
    volume = abs(np.einsum("ij,ij->i", a, np.cross(b, d)).sum()) / 6.0
    try:
        hull = ConvexHull(used).volume
    except (QhullError, ValueError):
        return False
    return hull > 0 and volume >= CONVEX_VOLUME_RATIO * hull and volume <= 1.02 * hull


def clearance(cloud_positions: np.ndarray, mesh, tree=None) -> Clearance:
    """The asset's clearance in the scan (``tree``: a cKDTree of the positions, if built)."""
    from scipy.spatial import cKDTree
    used = np.asarray(mesh.positions, np.float64)[np.unique(mesh.indices)]
    lo, hi = used.min(axis=0), used.max(axis=0)
    centre = 0.5 * (lo + hi)
    radius = float(np.linalg.norm(used - centre, axis=1).max())
    tree = tree if tree is not None else cKDTree(np.asarray(cloud_positions, np.float64))
    dist = float(tree.query(used, k=1)[0].min())
    ratio = dist / radius if radius > 0 else math.inf
    return Clearance(ratio, dist, radius, bool(mesh_is_convex(mesh)))


def near_field_needed(params, materials, clear: Clearance) -> str | None:
    """Why the frame keeps its micro-buffer mode (a short reason), or None when the
    environment map may take it (see the module docstring)."""
    beyond = float(params.envmap_beyond)
    if params.mode == "envmap":
        return "already the environment map"
    if beyond <= 0:
        return "pbgi.envmap_beyond is 0"
    if clear.ratio < beyond:
        return f"clearance {clear.ratio:.2f} < {beyond:g}"
    if needs_lobe(materials, max(float(params.glossy_below), GLOSSY_ROUGHNESS)):
        return "a glossy material"
    if params.asset_occlusion and not clear.convex:
        return "the asset may shadow itself"
    return None
