"""One BSH for the room and the asset: the room's tree and the asset's surfel tree under a new root.

Every mode walks one tree from node 0 (app/pbgi/layout.py's traversal convention; Mipmapped's
refinement starts from (root, pixel) pairs), so the simplest way to make every walk meet both is
a tree with both below its root: node 0 is a new root whose children are the room's root (node
1) and the asset's root (node 1 + R). Only indices shift: the room's records are copied with
their skip + 1, never rebuilt (its build is the expensive part, cached per cloud); the asset's get
skip + 1 + R and their centres re-expressed relative to the room's origin (float64, then rounded
conservatively like the hierarchy's own records: the radius grows by the rounding).

``asset_first`` (= 1 + R) is the first asset node: shaders that treat the two differently (the
lobe walk grows the scan's leaves by the scan spacing, not the asset's) compare against it.
Colours: the asset's part is recoloured from per-surfel radiance (app.pbgi.hierarchy.recolor on
the asset tree) and the root's colour follows; the structure, hence every cut, is unchanged, so a
new bounce keeps the micro-buffers' cut valid.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from app.pbgi import layout
from app.pbgi.hierarchy import Hierarchy, build_bsh, merge_spheres, recolor, round_spheres

# A surfel leaf's disc radius, in units of the radius of the surfel's own area (sqrt(A / (n pi))).
# Discs of exactly that area cannot tile a face: where they leave gaps the room shines through
# the asset. With the surfels stratified inside each triangle (app/pbgi/surfels.py) a flat face
# is 79% covered at 1.0, 94% at 1.25 and 99% at 1.5 (it was 66 / 80 / 91% with independent
# points, when 1.5 was needed). Wider discs overhang the faces' edges and shade their
# neighbours: 1.25 measured best over the blocks against the path tracer (4096 surfels, 4x4
# error, Classic: at 1.5 apartment diffuse 3.3% / rough metal 4.0%, city 6.0 / 7.1%; at 1.25
# 2.4 / 3.8%, 4.9 / 6.6%; at 1.1 2.4 / 5.7%, 4.5 / 6.5%). The neighbours of a receiver on a
# convex part stay behind it (app/pbgi/surfels.py).
LEAF_DISC = 1.25


@dataclass
class SceneTree:
    nodes: np.ndarray            # joined records (layout.NODE_DTYPE), root at 0
    asset_first: int             # index of the asset tree's root
    asset: Hierarchy             # the asset's own tree (its origin, point_node for recolouring)
    surfel_area: float = 0.0     # the area each surfel stands for

    def __len__(self) -> int:
        return len(self.nodes)


def asset_hierarchy(surfels) -> Hierarchy:
    """The surfels' BSH: unpruned, cells of half the surfel spacing (one surfel per leaf, mostly),
    leaves at least LEAF_DISC x the surfel's disc (see app/pbgi/surfels.py). Unpruned because a
    cluster leaf of similar normals is a thicker, wider disc that shadows its own neighbours:
    measured on the knot, pruning at tn = 0.98 made it 7-12% darker for no speed."""
    spacing = 2.0 * surfels.radius
    return build_bsh(surfels.positions, surfels.normals, np.zeros((len(surfels), 3), np.float32),
                     cell_size=0.5 * spacing, min_leaf_radius=LEAF_DISC * surfels.radius,
                     prune=False)


def join(room: Hierarchy, asset: Hierarchy, surfel_area: float = 0.0) -> SceneTree:
    """The joined tree (see the module docstring)."""
    r, a = len(room.nodes), len(asset.nodes)
    nodes = np.empty(1 + r + a, dtype=layout.NODE_DTYPE)
    nodes[1:1 + r] = room.nodes
    nodes["skip"][1:1 + r] = room.nodes["skip"] + np.uint32(1)
    an = asset.nodes.copy()
    shift = np.asarray(asset.origin, np.float64) - np.asarray(room.origin, np.float64)
    c, rad = round_spheres((an["center"].astype(np.float64) + shift).T,
                           an["radius"].astype(np.float64))
    an["center"], an["radius"] = c.T, rad
    an["skip"] = an["skip"] + np.uint32(1 + r)
    nodes[1 + r:] = an
    _set_root(nodes, 1, 1 + r)
    return SceneTree(nodes, 1 + r, asset, float(surfel_area))


def _set_root(nodes: np.ndarray, left: int, right: int) -> None:
    c1, r1 = nodes["center"][left].astype(np.float64), float(nodes["radius"][left])
    c2, r2 = nodes["center"][right].astype(np.float64), float(nodes["radius"][right])
    c, rad = merge_spheres(c1[:, None], np.array([r1]), c2[:, None], np.array([r2]))
    n1 = int(nodes["count_flags"][left] & layout.COUNT_MASK)
    n2 = int(nodes["count_flags"][right] & layout.COUNT_MASK)
    root = nodes[0:1]
    root["center"], root["radius"] = c.T, rad
    col = (nodes["color"][left].astype(np.float64) * n1
           + nodes["color"][right].astype(np.float64) * n2) / max(n1 + n2, 1)
    root["color"] = col.astype(np.float32)
    root["cone"] = layout.pack_cone(np.array([[0.0, 0.0, 1.0]]), np.array([np.pi]))
    root["skip"] = len(nodes)
    root["count_flags"] = np.uint32(min(n1 + n2, int(layout.COUNT_MASK)))


def recolor_asset(tree: SceneTree, colors: np.ndarray) -> SceneTree:
    """The same tree with the asset's nodes coloured from per-surfel ``colors`` (radiance)."""
    nodes = tree.nodes.copy()
    nodes["color"][tree.asset_first:] = recolor(tree.asset, colors)["color"]
    _set_root(nodes, 1, tree.asset_first)
    return SceneTree(nodes, tree.asset_first, tree.asset, tree.surfel_area)


def _asset_means(tree: SceneTree, values: np.ndarray) -> np.ndarray:
    """(asset nodes, k) float32: per asset node the mean of the per-surfel columns ``values``
    (n, k) below it - the point-count-weighted mean ``recolor`` gives the colours, three
    columns at a time."""
    v = np.asarray(values, np.float64).reshape(len(values), -1)
    k = v.shape[1]
    padded = np.zeros((len(v), -(-k // 3) * 3))
    padded[:, :k] = v
    cols = [recolor(tree.asset, padded[:, c:c + 3])["color"] for c in range(0, k, 3)]
    return np.concatenate(cols, axis=1)[:, :k].astype(np.float32)


def asset_gradients(tree: SceneTree, gradients: np.ndarray) -> np.ndarray:
    """(asset nodes, 3, 3) float32: per asset node the mean of per-surfel ``gradients`` (n, 3, 3)
    below it (the glossy bounce's G, app/pbgi/nodetex.py: set_directional), node order from
    ``tree.asset_first`` on - the same point-count-weighted mean as the colours, so a cluster
    sends the mean of its surfels' L(d) = colour + G d."""
    return _asset_means(tree, np.asarray(gradients).reshape(len(gradients), 9)).reshape(-1, 3, 3)


def asset_mirror(tree: SceneTree, mirror: np.ndarray) -> np.ndarray:
    """(asset nodes, 5) float32: per asset node the mean of per-surfel ``mirror`` (n, 5) below it
    (the mirror bounce's F0, roughness and weight, app/pbgi/asset_scene.py: mirror_params), in
    ``asset_gradients``' order and weighting."""
    return _asset_means(tree, mirror)
