"""The asset in the room, both ways: the asset's surfels in the PBGI tree (it occludes and lights
itself) and the asset's shadow and bounce on the scan (differential rendering).

``AssetScene`` holds what the Relighter builds for an asset and keeps it while it stays valid:

* surfels (app/pbgi/surfels.py) and the joined tree (app/pbgi/scene_tree.py): rebuilt when the
  asset (its mesh or placement), the cloud's geometry or the surfel count change;
* the bounce: per surfel radiance rho / pi x E, E gathered through the joined tree at up to
  ``BOUNCE_SAMPLES`` surfels and interpolated to the others like the differential below
  (app/pbgi/point_gather.py) with the previous bounce's radiance on the asset (0 for the first:
  one bounce = direct light from the room, shadowed by the asset itself); never redone when
  only the camera moves. The first gather does not depend on the materials (it sees a black
  asset) and is kept: with one bounce a material edit only rescales it by the new albedo.
  A metal (``glossy``: any material with metallic > 0) gets the glossy bounce instead: the same
  surfels gathered with their real material, seen from VIEWS far-away cameras spread over the
  sphere (PointGather.views: one walk, a gather per camera), and per surfel the plane
  L(d) = colour + G d least-squares fitted to the views above its horizon (``fit_directional``);
  the gather evaluates it towards each receiver (app/pbgi/nodetex.py: set_directional). A rough
  metal's outgoing radiance is smooth in the direction, a plane holds it (in the white furnace
  within 3-6% of its directional albedo, which is a quarter below the base colour the diffuse
  bounce used); it depends on the material, so a material edit gathers again;
* the mirror bounce, for a smooth metal (``mirror_params``): its reflection is too sharp for a
  plane fitted to 24 views, each point-sampling a narrow lobe in a 16 x 16 micro-buffer (in the
  furnace they read 0.002 or 3,740 where the silver sends 0.95: hot pixels and black specks on a
  silver bunny). So the gather evaluates such a node towards each receiver as the room's light
  from the mirror direction about its normal, from a cube map of the scan seen from the asset's
  centre (``environment``, built once per placement), prefiltered to the lobe and times the
  metal's directional albedo (shaders/pbgi_gather.glsl: asset_mirror); mixed into the plane
  between MIRROR_ROUGHNESS's two roughnesses, which the blocks against the path tracer chose;
* the node textures the modes walk (colours of the latest bounce);
* the differential: the scan's points within ``REACH`` asset radii of the asset's bounding
  sphere are gathered without the asset (the room's tree) and with it (the joined tree, bounce
  included). A scan holds radiance, not albedo; for a diffuse point L = rho / pi x E, so
  rho = L / (E / pi), estimated per channel from the gather without the asset and clamped to
  [0, 1] (an emitter or a point whose light the scan holds but the gather misses reads as 1).
  The change of its radiance is rho x (E_with - E_without) / pi: a shadow where the asset hides
  the room, colour bleeding where the asset's bounce reaches it. Points farther away keep their
  colour (the asset's effect is bounded to its neighbourhood, and the gathers cost per point).
  Both gathers run at up to ``SAMPLES`` of the region's points (evenly drawn) and are
  interpolated to the others from the ``NEIGHBOURS`` nearest samples facing the same way
  (a Gaussian of the distance x normal agreement): E varies slowly over the scan, the gathers' per-point
  discretisation noise does not, and the cost stays bounded however dense the scan.

What it does not model: the scan's points are not re-gathered for the asset's own receivers
(the room's tree keeps the scanned colours, so the shadow on the floor is not seen in the
asset's reflection of the floor), the room's light does not bounce twice, and the mirror
bounce's room has no parallax and no asset in it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from app.pbgi.nodetex import NodeTextures
from app.pbgi.point_gather import PointGather
from app.pbgi.scene_tree import (SceneTree, asset_gradients, asset_hierarchy, asset_mirror,
                                 join, recolor_asset)
from app.pbgi.surfels import Surfels, sample_surfels, surfel_albedo, surfel_materials

REACH = 2.0          # the differential's region: points within (1 + REACH) x the asset radius
FADE = 0.75          # ... the change fading to 0 over its last FADE x the asset radius
SAMPLES = 2048       # the differential gathers at most this many of them and interpolates
BOUNCE_SAMPLES = 2048  # the bounce gathers at most this many surfels and interpolates
NEIGHBOURS = 12      # the interpolation's samples per point
VIEWS = 24           # the glossy bounce: far cameras (a Fibonacci sphere) each surfel is seen from
MIN_VIEW_COS = 0.05  # ... those more than this above its horizon fit its L(d) = colour + G d
MIRROR_ROUGHNESS = (0.2, 0.35)  # the mirror bounce alone below the first, the plane above the
                     # second, mixed linearly between (a metal's share: ``mirror_params``)


@dataclass
class SceneNodes:
    """What a render walks when the asset is in the tree."""
    textures: NodeTextures
    count: int
    asset_first: int
    key: tuple                # the tree's structure: part of the cut key (colours are not)
    records: np.ndarray       # the joined node records (layout.NODE_DTYPE) the textures hold


@dataclass
class Differential:
    """The scan's points near the asset and what the asset does to them."""
    index: np.ndarray         # (k,) point indices into the cloud
    without: np.ndarray       # (k, 3) E / pi gathered without the asset
    with_asset: np.ndarray    # (k, 3) E / pi gathered with the asset (its bounce included)
    albedo: np.ndarray        # (k, 3) estimated albedo, L / (E / pi) clamped to [0, 1]
    delta: np.ndarray         # (k, 3) albedo x (with - without): add to the scan's radiance
    seconds: float

    def colors(self, base: np.ndarray) -> np.ndarray:
        """The scan's colours with the asset's shadow and bounce (never below 0)."""
        out = np.array(base, dtype=np.float32, copy=True)
        out[self.index] = np.maximum(out[self.index] + self.delta, 0.0)
        return out


def glossy(materials) -> bool:
    """Whether the asset's bounce is the glossy one (a metal among its materials)."""
    return any(float(m.metallic) > 0.0 for m in materials)


def view_directions(k: int = VIEWS) -> np.ndarray:
    """(k, 3) unit directions spread evenly over the sphere (a Fibonacci lattice)."""
    i = np.arange(k) + 0.5
    z = 1.0 - 2.0 * i / k
    phi = np.pi * (1.0 + 5.0 ** 0.5) * i
    r = np.sqrt(np.maximum(1.0 - z * z, 0.0))
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def fit_directional(directions: np.ndarray, normals: np.ndarray, radiance: np.ndarray):
    """Per point, (colour (n, 3), G (n, 3, 3) [channel, axis]): the least-squares plane
    L(d) = colour + G d through its radiance (k, n, 3) seen from the k ``directions`` more than
    MIN_VIEW_COS above its horizon (a small ridge keeps G finite where few are)."""
    d = np.asarray(directions, np.float64)
    w = (np.asarray(normals, np.float64) @ d.T > MIN_VIEW_COS).astype(np.float64)   # (n, k)
    a = np.concatenate([np.ones((len(d), 1)), d], axis=1)                            # (k, 4)
    ata = np.einsum("nk,ka,kb->nab", w, a, a) + np.diag([1e-9, 1e-3, 1e-3, 1e-3])
    atl = np.einsum("nk,ka,knc->nac", w, a, np.asarray(radiance, np.float64))
    c = np.linalg.solve(ata, atl)                                                    # (n, 4, 3)
    return c[:, 0, :].astype(np.float32), c[:, 1:, :].transpose(0, 2, 1).astype(np.float32)


def mirror_params(surfels: Surfels, mesh, materials) -> np.ndarray | None:
    """(n, 5) float32 per surfel: F0 (its base colour), roughness and the weight of the mirror
    bounce (module docstring) - metallic x 1 below MIRROR_ROUGHNESS[0], falling linearly to 0 at
    MIRROR_ROUGHNESS[1]; None when no surfel has any."""
    mats, index = surfel_materials(surfels, mesh, materials)
    rough = np.array([float(m.roughness) for m in mats], np.float64)[index]
    metal = np.array([float(m.metallic) for m in mats], np.float64)[index]
    lo, hi = MIRROR_ROUGHNESS
    weight = np.clip(metal, 0.0, 1.0) * np.clip((hi - rough) / (hi - lo), 0.0, 1.0)
    if not (weight > 0.0).any():
        return None
    out = np.zeros((len(surfels), 5), np.float32)
    out[:, :3] = surfel_albedo(surfels, mesh, materials)
    out[:, 3], out[:, 4] = rough, weight
    return out


def _bounce_key(tree_key, bounces: int, albedo: np.ndarray, materials) -> tuple:
    """What a bounce depends on: the tree, the bounce count, the surfels' albedo and, for the
    glossy bounce, every material parameter (its lobe, not only its colour)."""
    from app.pbgi.brdf import pack_params
    return (tree_key, int(bounces), albedo.tobytes(),
            tuple(pack_params(m).tobytes() for m in materials) if glossy(materials) else None)


def _bytes(a) -> bytes | None:
    return None if a is None else np.ascontiguousarray(a).tobytes()


def _evenly(index: np.ndarray, most: int) -> np.ndarray:
    """At most ``most`` of ``index``, drawn without replacement (seeded), in order."""
    if len(index) <= most:
        return index
    return np.sort(np.random.default_rng(0).choice(index, most, replace=False))


def _interpolate(positions, normals, sample: np.ndarray, index: np.ndarray,
                 fields) -> list[np.ndarray]:
    """``fields`` known at points ``sample`` (indices into ``positions``/``normals``), at
    points ``index`` (see the module docstring)."""
    if len(sample) == len(index):
        return list(fields)
    from scipy.spatial import cKDTree
    k = min(NEIGHBOURS, len(sample))
    dist, near = cKDTree(positions[sample]).query(positions[index], k=k)
    dist, near = dist.reshape(len(index), k), near.reshape(len(index), k)
    agree = np.einsum("nkc,nc->nk", normals[sample][near].astype(np.float64),
                      normals[index].astype(np.float64))
    # a Gaussian of the typical distance to the k-th sample: a low-pass over ~k samples (the
    # gathers' discretisation noise differs from sample to sample, E does not), not 1 / d,
    # which would give every point its nearest sample's noise back
    h = max(float(np.median(dist[:, -1])), 1e-9)
    w = np.maximum(agree, 0.0) ** 4 * np.exp(-(dist / h) ** 2)
    none = w.sum(axis=1) <= 0.0
    w[none, 0] = 1.0                                     # nothing faces the same way: nearest
    w /= w.sum(axis=1, keepdims=True)
    return [np.einsum("nk,nkc->nc", w, f[near]).astype(np.float32) for f in fields]


class AssetScene:
    def __init__(self, ctx, gather, environment=None):
        """``environment``: () -> a new EnvironmentMap of the room seen from the asset's
        centre (the Relighter's), for the mirror bounce; None: no mirror bounce."""
        self.ctx = ctx
        self.points = PointGather(ctx, gather)
        self.environment = environment
        self._env = None          # (tree key, EnvironmentMap) of the mirror bounce
        self._surfels = None      # (key, Surfels)
        self._tree = None         # (key, SceneTree) uncoloured
        self._bounce = None       # (key, per-surfel radiance)
        self._direct = None       # (tree key, per-surfel E / pi of the room alone, shadowed)
        self._upload = None       # (key, buffer, NodeTextures, SceneTree)
        self._diff = None         # (key, Differential)
        self._without = None      # (region key, the differential's gather without the asset)
        self.seconds = 0.0        # building work done by the latest call (0: all cached)

    # -- pieces ----------------------------------------------------------------------------
    def surfels(self, mesh, asset_version: int, count: int) -> Surfels:
        key = (asset_version, int(count))
        if self._surfels is None or self._surfels[0] != key:
            self._surfels = (key, sample_surfels(mesh, count))
        return self._surfels[1]

    def tree(self, room, geo_version, mesh, asset_version: int, count: int) -> tuple:
        key = (geo_version, asset_version, int(count))
        if self._tree is None or self._tree[0] != key:
            s = self.surfels(mesh, asset_version, count)
            self._tree = (key, join(room, asset_hierarchy(s), s.area))
        return self._tree

    def radiance(self, tree_key, tree: SceneTree, room, mesh, materials, surfels: Surfels,
                 bounces: int):
        """Per surfel outgoing radiance after ``bounces`` bounces: (colour (n, 3), G or None).
        Diffuse materials: colour = rho / pi x E. With a metal (``glossy``) the surfels are
        gathered with their real material from VIEWS far cameras and L(d) = colour + G d is
        fitted to what each sees (module docstring)."""
        albedo = surfel_albedo(surfels, mesh, materials)
        shiny = glossy(materials)
        key = _bounce_key(tree_key, bounces, albedo, materials)
        if self._bounce is not None and self._bounce[0] == key:
            return self._bounce[1]
        rad = np.zeros((len(surfels), 3), np.float32)
        grads = None
        mirror = mirror_params(surfels, mesh, materials) if shiny else None
        every = np.arange(len(surfels))
        sample = _evenly(every, BOUNCE_SAMPLES)
        rel = surfels.positions[sample] - room.origin
        offset = 0.25 * surfels.radius
        for b in range(int(bounces)):
            if shiny:
                _, tex, _ = self._textures((tree_key, rad.tobytes(), _bytes(grads),
                                            _bytes(mirror) if b else None), tree, rad, grads,
                                           mirror if b else None)
                mats, index = surfel_materials(surfels, mesh, materials)
                dirs = view_directions()
                seen = self.points.views(rel, surfels.normals[sample], tex, room.cell_size,
                                         mats, index[sample], albedo[sample], dirs,
                                         offset=offset)
                colour, g = fit_directional(dirs, surfels.normals[sample], seen)
                colour, g = _interpolate(surfels.positions, surfels.normals, sample, every,
                                         [colour, g.reshape(len(sample), 9)])
                rad, grads = colour.astype(np.float32), g.reshape(-1, 3, 3).astype(np.float32)
                continue
            if b == 0 and self._direct is not None and self._direct[0] == tree_key:
                e = self._direct[1]          # the first gather sees a black asset: no albedo
            else:
                _, tex, _ = self._textures((tree_key, rad.tobytes(), None), tree, rad)
                e = self.points.run(rel, surfels.normals[sample], tex, room.cell_size,
                                    offset=offset)
                e = _interpolate(surfels.positions, surfels.normals, sample, every, [e])[0]
                if b == 0:
                    self._direct = (tree_key, e)
            rad = (albedo * e).astype(np.float32)
        self._bounce = (key, (rad, grads))
        return rad, grads

    def _mirror_environment(self, tree_key):
        """The room seen from the asset's centre, kept per tree (the room and the placement)."""
        if self.environment is None:
            return None
        if self._env is None or self._env[0] != tree_key:
            if self._env is not None:
                self._env[1].release()
            self._env = None
            self._env = (tree_key, self.environment())
        return self._env[1]

    def _textures(self, key, tree: SceneTree, radiance: np.ndarray, gradients=None,
                  mirror=None):
        if self._upload is None or self._upload[0] != key:
            if self._upload is not None:
                self._upload[1].release()
                self._upload[2].release()
            coloured = recolor_asset(tree, radiance) if radiance.any() else tree
            buf = self.ctx.buffer(np.ascontiguousarray(coloured.nodes).tobytes())
            tex = NodeTextures(self.ctx, buf, len(coloured))
            tex.asset_first, tex.surfel_area = tree.asset_first, tree.surfel_area
            if gradients is not None:
                env = None if mirror is None else self._mirror_environment(key[0])
                tex.set_directional(asset_gradients(tree, gradients), tree.asset_first,
                                    None if env is None else asset_mirror(tree, mirror), env)
            self._upload = (key, buf, tex, coloured)
        return self._upload[1], self._upload[2], self._upload[3]

    def ready(self, geo_version, mesh, asset_version: int, materials, params) -> bool:
        """``nodes`` would only look up what is built (no surfels, tree or gather to make)."""
        count = int(params.asset_surfels)
        key = (geo_version, asset_version, count)
        if self._tree is None or self._tree[0] != key or self._surfels is None \
                or self._surfels[0] != (asset_version, count):
            return False
        if self._bounce is not None and self._bounce[0] == _bounce_key(
                key, params.asset_bounces, surfel_albedo(self._surfels[1], mesh, materials),
                materials):
            return True
        # one diffuse bounce whose first gather is kept: a material edit only rescales it
        return int(params.asset_bounces) == 0 or (
            int(params.asset_bounces) == 1 and not glossy(materials)
            and self._direct is not None and self._direct[0] == key)

    # -- what the Relighter asks -----------------------------------------------------------
    def nodes(self, room, geo_version, mesh, asset_version: int, materials, params) -> SceneNodes:
        """The joined tree's textures, coloured with ``params.asset_bounces`` bounces."""
        t0 = time.perf_counter()
        count = int(params.asset_surfels)
        tree_key, tree = self.tree(room, geo_version, mesh, asset_version, count)
        surfels = self.surfels(mesh, asset_version, count)
        rad, grads = self.radiance(tree_key, tree, room, mesh, materials, surfels,
                                   int(params.asset_bounces))
        mirror = None if grads is None else mirror_params(surfels, mesh, materials)
        _, tex, coloured = self._textures((tree_key, rad.tobytes(), _bytes(grads),
                                           _bytes(mirror)), tree, rad, grads, mirror)
        self.seconds = time.perf_counter() - t0
        return SceneNodes(tex, len(tree), tree.asset_first, ("asset",) + tree_key,
                          coloured.nodes)

    def differential_key(self, cloud_version: int, room, geo_version, mesh,
                         asset_version: int, materials, params) -> tuple:
        """What the differential depends on (builds the asset's tree and bounce if needed)."""
        scene = self.nodes(room, geo_version, mesh, asset_version, materials, params)
        return (scene.key, hash(self._upload[0][1:]), cloud_version)

    def differential(self, *args, chunk: int | None = None):
        """The asset's shadow and bounce on the scan's points near it (module docstring):
        ``differential_steps`` run to the end."""
        steps = self.differential_steps(*args, chunk=chunk)
        while True:
            try:
                next(steps)
            except StopIteration as done:
                return done.value

    def differential_steps(self, cloud, cloud_version: int, room, room_textures, geo_version,
                           mesh, asset_version: int, materials, params,
                           chunk: int | None = None):
        """A generator: yields the fraction done after each ``chunk`` points gathered (the
        viewer advances it a step per frame, so the window never waits for all of it) and
        returns the Differential. The gather without the asset is kept for the next asset or
        material (it depends on the cloud and the region only)."""
        key = self.differential_key(cloud_version, room, geo_version, mesh, asset_version,
                                    materials, params)
        if self._diff is not None and self._diff[0] == key:
            return self._diff[1]
        scene = self.nodes(room, geo_version, mesh, asset_version, materials, params)
        t0 = time.perf_counter()
        lo, hi = mesh.bounds()
        centre = 0.5 * (np.asarray(lo, np.float64) + np.asarray(hi, np.float64))
        surfels = self.surfels(mesh, asset_version, int(params.asset_surfels))
        radius = float(np.linalg.norm(surfels.positions - centre, axis=1).max()) + surfels.radius
        d = np.linalg.norm(cloud.positions - centre, axis=1)
        index = np.flatnonzero(d <= (1.0 + REACH) * radius)
        fade = np.clip(((1.0 + REACH) * radius - d[index]) / (FADE * radius), 0.0, 1.0)
        sample = _evenly(index, SAMPLES)
        rel = cloud.positions[sample] - room.origin
        nrm = cloud.normals[sample]
        offset = room.cell_size
        chunk = max(int(chunk or len(sample) or 1), 1)
        region = (cloud_version, sample.tobytes())
        cached = self._without is not None and self._without[0] == region
        work = [("with", scene.textures)] + ([] if cached else [("without", room_textures)])
        parts: dict = {name: [] for name, _ in work}
        total, done = len(work) * len(sample), 0
        for name, tex in work:
            for i in range(0, len(sample), chunk):
                parts[name].append(self.points.run(rel[i:i + chunk], nrm[i:i + chunk], tex,
                                                   room.cell_size, offset=offset))
                done += min(chunk, len(sample) - i)
                yield done / max(total, 1)
        joined = {k: np.concatenate(v) if v else np.zeros((0, 3), np.float32)
                  for k, v in parts.items()}
        if not cached:
            self._without = (region, joined["without"])
        e0, e1 = self._without[1], joined["with"]
        without, with_asset = _interpolate(cloud.positions, cloud.normals, sample, index,
                                           (e0, e1))
        col = np.asarray(cloud.colors[index], np.float32)
        albedo = np.clip(np.where(without > 1e-8, col / np.maximum(without, 1e-8), 1.0), 0.0, 1.0)
        delta = (albedo * (with_asset - without) * fade[:, None]).astype(np.float32)
        diff = Differential(index, without, with_asset, albedo.astype(np.float32), delta,
                            time.perf_counter() - t0)
        self._diff = (key, diff)
        return diff

    @property
    def bounce(self):
        """The latest bounce per surfel: (colour (n, 3), G (n, 3, 3) or None), or None."""
        return None if self._bounce is None else self._bounce[1]

    @property
    def nbytes(self) -> int:
        return 0 if self._upload is None else (self._upload[1].size + self._upload[2].nbytes
                                               + self._upload[2].directional_nbytes)

    def release(self) -> None:
        self.points.release()
        if self._env is not None:
            self._env[1].release()
        self._env = None
        if self._upload is not None:
            self._upload[1].release()
            self._upload[2].release()
        self._upload = None
