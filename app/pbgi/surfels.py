"""The asset as surfels, so the PBGI sees it: it occludes the room for itself and lights itself.

Today's receivers are the asset's pixels and the micro-buffers hold only the room, so an asset is
lit as if it were alone and convex. Here the asset's surface is sampled into surfels (discs of
equal area: position, normal, base colour) and a small BSH is built over them
(app/pbgi/hierarchy.py, no pruning: a surfel's colour changes with the bounce, the tree must not
depend on it). app/pbgi/scene_tree.py joins that tree to the room's under one new root, so every
mode's walk meets the asset's discs in the same micro-buffer, with the same depth test, as the
room's points: the asset shadows the room for its own receivers.

Sampling is stratified over the surface area (systematic sampling of the triangles' cumulative
area: the i-th surfel sits at area (i + u_i) / n), and the surfels that share a triangle are
stratified inside it too (``_spread_in_triangles``), so surfels are spread evenly without a
Poisson pass and the result is deterministic for a seed. Each surfel stands for area A / n: its
disc radius is sqrt(A / (n pi)), the radius of the leaves of its tree.

Why receivers do not see their own surface: a surfel's disc faces along its normal, and the
micro-buffer's ray test (lib/microbuffer.glsl) ignores a disc hit from behind. A receiver lies on
or behind the tangent planes of the surfels around it on a convex part of the surface, so every
ray towards them meets their back; on a concave part (a crease between two faces) the other face
is in front and occludes, as it should. Leaves keep one surfel (the tree's cell is half the
surfel spacing) so that the per-disc test holds.

The bounce: a surfel carries outgoing radiance rho / pi x E, its irradiance gathered through the
joined tree (so it is shadowed by the asset as well) with rho its base colour - the diffuse
bounce. A metal's bounce is glossy instead: its outgoing radiance as a function of direction,
gathered with its real material (app/pbgi/asset_scene.py; ``surfel_materials`` gives each surfel
its material).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from app.errors import ScanlightError


@dataclass
class Surfels:
    positions: np.ndarray       # (n, 3) float64 world
    normals: np.ndarray         # (n, 3) float32 unit, the mesh's interpolated shading normal
    face: np.ndarray            # (n,) int64 triangle each surfel lies on
    texture: np.ndarray         # (n, 3) float32 the base colour texture at the surfel (1: none)
    area: float                 # surface area each surfel stands for (total / n)

    def __len__(self) -> int:
        return len(self.positions)

    @property
    def radius(self) -> float:
        """Radius of a disc of the surfel's area."""
        return float(np.sqrt(self.area / np.pi))


def _sample_texture(tex, uv: np.ndarray) -> np.ndarray:
    """Nearest texel of a float (H, W, C) texture, glTF convention (v down), repeat wrap."""
    t = np.asarray(tex, dtype=np.float32)
    h, w = t.shape[:2]
    x = np.floor(np.mod(uv[:, 0], 1.0) * w).astype(np.int64).clip(0, w - 1)
    y = np.floor(np.mod(uv[:, 1], 1.0) * h).astype(np.int64).clip(0, h - 1)
    return t[y, x]


def _radical_inverse2(j: np.ndarray) -> np.ndarray:
    """Van der Corput's base-2 radical inverse of non-negative integers below 2^32."""
    v = j.astype(np.uint64) & np.uint64(0xFFFFFFFF)
    for shift, mask in ((1, 0x55555555), (2, 0x33333333), (4, 0x0F0F0F0F), (8, 0x00FF00FF)):
        m, sh = np.uint64(mask), np.uint64(shift)
        v = ((v >> sh) & m) | ((v & m) << sh)
    v = ((v >> np.uint64(16)) | (v << np.uint64(16))) & np.uint64(0xFFFFFFFF)
    return v.astype(np.float64) / 2.0 ** 32


def _spread_in_triangles(face: np.ndarray, rng) -> np.ndarray:
    """(n, 3) barycentrics of the surfels on each triangle (``face`` sorted): the k that share a
    triangle form a Hammersley set ((j + 1/2) / k, radical inverse of j), shifted on the torus
    by one random offset per triangle and mapped to the triangle by Heitz's area-preserving,
    low-distortion square-to-triangle map (2019). Independent uniform points leave Poisson gaps
    (about 1/e of a large face uncovered by discs of the surfels' own area), through which the
    room shines through the asset; a stratified set closes them at the same count."""
    n = len(face)
    start = np.r_[True, face[1:] != face[:-1]]
    first = np.flatnonzero(start)
    group = np.cumsum(start) - 1
    k = np.diff(np.r_[first, n])[group]
    j = np.arange(n) - first[group]
    shift = rng.random((len(first), 2))[group]
    u1 = np.mod((j + 0.5) / k + shift[:, 0], 1.0)
    u2 = np.mod(_radical_inverse2(j) + shift[:, 1], 1.0)
    lower = u2 > u1
    b0 = np.where(lower, 0.5 * u1, u1 - 0.5 * u2)
    b1 = np.where(lower, u2 - 0.5 * u1, 0.5 * u2)
    return np.stack([b0, b1, 1.0 - b0 - b1], axis=1)


def sample_surfels(mesh, count: int, seed: int = 0) -> Surfels:
    """``count`` surfels of equal area spread over ``mesh`` (see the module docstring)."""
    count = int(count)
    if count < 1:
        raise ValueError("sample_surfels needs at least one surfel")
    tri = mesh.indices.astype(np.int64)
    p = mesh.positions[tri]                                   # (F, 3, 3) float64
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    areas = 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1)
    total = float(areas.sum())
    if not np.isfinite(total) or total <= 0.0:
        raise ScanlightError(mesh.source, "the asset has no surface area to sample")
    rng = np.random.default_rng(seed)
    cum = np.cumsum(areas)
    targets = (np.arange(count) + rng.random(count)) * (total / count)
    face = np.searchsorted(cum, targets, side="right").clip(0, len(tri) - 1)
    bc = _spread_in_triangles(face, rng)
    pos = np.einsum("nk,nkc->nc", bc, p[face])
    nrm = np.einsum("nk,nkc->nc", bc, mesh.normals[tri[face]].astype(np.float64))
    length = np.linalg.norm(nrm, axis=1, keepdims=True)
    geo = np.cross(e1[face], e2[face])
    geo /= np.maximum(np.linalg.norm(geo, axis=1, keepdims=True), 1e-30)
    nrm = np.where(length > 1e-12, nrm / np.maximum(length, 1e-30), geo)
    texture = np.ones((count, 3), np.float32)
    mat = mesh.material_ids[face].astype(np.int64)
    uv = None
    if mesh.uvs is not None:
        uv = np.einsum("nk,nkc->nc", bc, mesh.uvs[tri[face]].astype(np.float64))
    for k, m in enumerate(mesh.materials):
        sel = mat == k
        if sel.any() and m.base_color_texture is not None and uv is not None:
            texture[sel] = _sample_texture(m.base_color_texture, uv[sel])[:, :3]
    return Surfels(pos, nrm.astype(np.float32), face, texture, total / count)


def _per_mesh_material(materials, mesh) -> list:
    """``materials`` one per mesh material (a single one stands for all)."""
    materials = list(materials)
    if len(materials) == 1 and len(mesh.materials) > 1:
        materials = materials * len(mesh.materials)
    return materials


def surfel_albedo(surfels: Surfels, mesh, materials) -> np.ndarray:
    """The bounce albedo of every surfel for ``materials`` (one per mesh material, or one for
    all): the render's base colours, textured where the mesh's own material has a texture."""
    materials = _per_mesh_material(materials, mesh)
    mat = mesh.material_ids[surfels.face].astype(np.int64)
    out = np.zeros((len(surfels), 3), np.float32)
    for k, m in enumerate(materials[:len(mesh.materials)]):
        sel = mat == k
        if sel.any():
            out[sel] = np.clip(np.asarray(m.base_color, np.float32)[:3] * surfels.texture[sel],
                               0.0, 1.0)
    return out


def surfel_materials(surfels: Surfels, mesh, materials) -> tuple[list, np.ndarray]:
    """(materials, per-surfel row into them): ``materials`` one per mesh material, or one for
    all (as surfel_albedo reads them)."""
    materials = _per_mesh_material(materials, mesh)
    index = np.clip(mesh.material_ids[surfels.face].astype(np.int64), 0, len(materials) - 1)
    return materials, index.astype(np.uint32)
