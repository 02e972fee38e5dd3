"""The G-buffer pyramid ("G-buffer mipmaps", paper Section 5.2.1 and Fig. 6) that Mipmapped and
Hybrid PBGI refine (node, pixel) pairs on.

One pyramid per batch of receivers. Level 0 holds one pixel per receiver; a pixel of level k + 1
covers the (up to) four level-k pixels with the same Z-order code >> 2, so coarse pixels are
squares of the image. Pixels are stored *sparsely*: only non-empty pixels exist (an empty image
region has no pixel at any level, so "empty stays empty" holds by construction and costs no
memory), each level in Z-order, finest level first. The topology (who is whose child) is pure
integer work and is built here in numpy; the geometry is merged on the GPU
(shaders/gbuffer_mip.glsl) because the receivers already live there.

Per pixel the GPU stores what the cone-vs-cone visibility test (paper eqs. 6-8) and the
refinement need about every receiver below it:

* a **bounding sphere of the positions** (centre, radius): level 0 is the receiver's position
  with radius 0; coarser levels merge their children's spheres with the exact smallest sphere
  enclosing two spheres (app.pbgi.hierarchy.merge_spheres' operator);
* a **normal cone** (unit axis, half-angle): level 0 is the receiver's shading normal with
  half-angle 0; coarser levels merge their children's cones with the *same* exact minimum-cone
  operator as the BSH (app.pbgi.hierarchy.merge_cones, paper Fig. 6: "the same procedure as the
  normal cone of internal nodes"). Four children are merged as (c0 + c1) + (c2 + c3).

Both merges are made conservative on the GPU (angles from atan2, containment re-checked against
both inputs, a small growth margin), because a bound that is too tight would let a coarse pixel
cull a node that one of its receivers sees.

GPU records (``MipPyramid``; app/pbgi/gpu_layout.py MIP_SPHERE, MIP_CONE, MIP_LINK, generated
into gen/mip.glsl): three images, one texel per pixel: sphere (centre, radius), cone (axis,
half-angle), link (first child pixel | receiver slot at level 0, child count (0 at level 0),
parent pixel or NIL, level).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from app.pbgi import gpu_layout as G
from app.pbgi.hierarchy import merge_cones, merge_spheres

NIL = G.NIL
IMAGES = {"sphere": G.MIP_SPHERE, "cone": G.MIP_CONE, "link": G.MIP_LINK}   # texel records
PIXEL_BYTES = sum(r.nbytes for r in IMAGES.values())    # sphere, cone, link texels per pixel
MAX_LEVELS = 16           # 2^16 x 2^16 pixels per tile at most
# columns of Topology.link (a MIP_LINK record per row)
L_FIRST, L_COUNT, L_PARENT, L_LEVEL = (G.MIP_LINK.index(n) for n in
                                       ("first", "count", "parent", "level"))


def _spread16(v: np.ndarray) -> np.ndarray:
    v = v.astype(np.uint64) & np.uint64(0xFFFF)
    v = (v | (v << np.uint64(8))) & np.uint64(0x00FF00FF)
    v = (v | (v << np.uint64(4))) & np.uint64(0x0F0F0F0F)
    v = (v | (v << np.uint64(2))) & np.uint64(0x33333333)
    v = (v | (v << np.uint64(1))) & np.uint64(0x55555555)
    return v


def morton2(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """2-D Z-order codes of integer pixel coordinates (< 2**16): x in the even bits."""
    return _spread16(x) | (_spread16(y) << np.uint64(1))


def z_order(pixels: np.ndarray, width: int) -> np.ndarray:
    """Z-order codes of row-major pixel indices of an image ``width`` pixels wide."""
    p = np.asarray(pixels, dtype=np.int64)
    return morton2(p % width, p // width)


@dataclass
class Topology:
    """Who is whose child in a sparse Z-order pyramid over ``n0`` receivers.

    ``link`` (n_pixels, 4) uint32: the MIP_LINK records (columns L_FIRST, L_COUNT, L_PARENT,
    L_LEVEL); ``offsets[k]`` is the first pixel of
    level k (offsets[-1] == n_pixels); ``codes[k]`` the Z codes of level k; ``order`` the receiver
    slot of each level-0 pixel (Z-sorted); ``top`` the pixels of the coarsest level (where the
    refinement starts).
    """

    link: np.ndarray
    offsets: np.ndarray
    codes: list
    order: np.ndarray

    @property
    def levels(self) -> int:
        return len(self.offsets) - 1

    @property
    def n_pixels(self) -> int:
        return int(self.offsets[-1])

    @property
    def top(self) -> np.ndarray:
        return np.arange(self.offsets[-2], self.offsets[-1], dtype=np.uint32)

    def level_of(self, k: int) -> slice:
        return slice(int(self.offsets[k]), int(self.offsets[k + 1]))

    def receivers_below(self, pixel: int) -> np.ndarray:
        """Receiver slots of the level-0 pixels below ``pixel`` (for tests)."""
        lvl = int(self.link[pixel, L_LEVEL])
        code = self.codes[lvl][pixel - int(self.offsets[lvl])]
        c0 = self.codes[0] >> np.uint64(2 * lvl)
        return self.order[c0 == code]


def build_topology(codes: np.ndarray, max_top: int = 1) -> Topology:
    """Sparse pyramid over receivers with Z codes ``codes`` (one per receiver slot, unique).

    Levels are added until at most ``max_top`` pixels remain (or MAX_LEVELS).
    """
    codes = np.asarray(codes, dtype=np.uint64)
    n0 = len(codes)
    if n0 == 0:
        raise ValueError("a pyramid needs at least one receiver")
    order = np.argsort(codes, kind="stable").astype(np.uint32)
    level_codes = [codes[order]]
    if np.any(level_codes[0][1:] == level_codes[0][:-1]):
        raise ValueError("two receivers share a pixel")
    firsts, counts, inverses = [], [], []
    while len(level_codes[-1]) > max_top and len(level_codes) < MAX_LEVELS:
        up = level_codes[-1] >> np.uint64(2)
        u, first, inv, cnt = np.unique(up, return_index=True, return_inverse=True,
                                       return_counts=True)
        level_codes.append(u)
        firsts.append(first)
        counts.append(cnt)
        inverses.append(inv)
    sizes = [len(c) for c in level_codes]
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    link = np.empty((offsets[-1], G.MIP_LINK.words), dtype=np.uint32)
    link[:, L_PARENT] = NIL
    for k, size in enumerate(sizes):
        sl = slice(offsets[k], offsets[k + 1])
        link[sl, L_LEVEL] = k
        if k == 0:
            link[sl, L_FIRST] = order
            link[sl, L_COUNT] = 0
        else:
            link[sl, L_FIRST] = offsets[k - 1] + firsts[k - 1]
            link[sl, L_COUNT] = counts[k - 1]
        if k + 1 < len(sizes):
            link[sl, L_PARENT] = offsets[k + 1] + inverses[k]
    return Topology(link=link, offsets=offsets, codes=level_codes, order=order)


def reference_pyramid(topo: Topology, positions: np.ndarray, normals: np.ndarray) -> dict:
    """The pyramid's geometry in numpy with the BSH's own merge operators (the GPU's twin).

    positions/normals: per receiver *slot* (not Z-sorted). Returns centre (n, 3), radius (n,),
    axis (n, 3), angle (n,) per pyramid pixel.
    """
    n = topo.n_pixels
    cen = np.zeros((3, n))
    rad = np.zeros(n)
    axs = np.zeros((3, n))
    ang = np.zeros(n)
    sl = topo.level_of(0)
    slots = topo.link[sl, L_FIRST].astype(np.int64)
    cen[:, sl] = np.asarray(positions, dtype=np.float64)[slots].T
    nrm = np.asarray(normals, dtype=np.float64)[slots]
    axs[:, sl] = (nrm / np.linalg.norm(nrm, axis=1, keepdims=True)).T
    for k in range(1, topo.levels):
        sl = topo.level_of(k)
        first = topo.link[sl, L_FIRST].astype(np.int64)
        cnt = topo.link[sl, L_COUNT].astype(np.int64)
        ch = [first + np.minimum(j, cnt - 1) for j in range(4)]

        def pair(a, b):
            c, r = merge_spheres(cen[:, a], rad[a], cen[:, b], rad[b])
            x, t = merge_cones(axs[:, a], ang[a], axs[:, b], ang[b])
            return c, r, x, t

        c01, r01, x01, t01 = pair(ch[0], ch[1])
        c23, r23, x23, t23 = pair(ch[2], ch[3])
        cen[:, sl], rad[sl] = merge_spheres(c01, r01, c23, r23)
        axs[:, sl], ang[sl] = merge_cones(x01, t01, x23, t23)
    return {"centre": cen.T, "radius": rad, "axis": axs.T, "angle": ang}


WIDTH = G.MIP_WIDTH       # texels per image row (MIP_WIDTH in gen/mip.glsl)
UNITS = {"sphere": G.IMAGE.MIP_SPHERE, "cone": G.IMAGE.MIP_CONE, "link": G.IMAGE.MIP_LINK}


def image_rows(n: int) -> int:
    return max(1, (int(n) + WIDTH - 1) // WIDTH)


def to_rows(a: np.ndarray, comps: int) -> np.ndarray:
    """Pad a (n, comps) array to whole image rows (flattened texel order)."""
    rows = image_rows(len(a))
    out = np.zeros((rows * WIDTH, comps), dtype=a.dtype)
    out[:len(a)] = a.reshape(len(a), comps)
    return out


class MipPyramid:
    """GPU pyramids for batches of receivers (images grown on demand and reused)."""

    def __init__(self, ctx, alloc=None):
        from app.render.programs import load_compute
        self.ctx = ctx
        self.prog = load_compute(ctx, "gbuffer_mip.glsl")
        self._alloc = alloc or (lambda size, comps, dtype: ctx.texture(size, comps, dtype=dtype))
        self.images: dict = {}
        self.rows = 0
        self.topology: Topology | None = None

    def _ensure(self, n: int) -> None:
        rows = image_rows(n)
        if rows <= self.rows <= 2 * rows:          # reuse, unless more than twice too big
            return
        self.release()
        for name, rec in IMAGES.items():
            self.images[name] = self._alloc((WIDTH, rows), rec.texel_components, rec.texture_dtype)
        self.rows = rows

    def bind(self) -> None:
        for name, unit in UNITS.items():
            self.images[name].bind_to_image(unit, read=True, write=name != "link")

    def build(self, receivers, first: int, codes: np.ndarray, max_top: int = 1) -> Topology:
        """Topology from the receivers' Z codes, geometry merged level by level on the GPU."""
        topo = build_topology(codes, max_top)
        n = topo.n_pixels
        self._ensure(n)
        link = to_rows(topo.link, G.MIP_LINK.words)
        self.images["link"].write(link.tobytes(), viewport=(0, 0, WIDTH, len(link) // WIDTH))
        receivers.bind_to_storage_buffer(G.SSBO.RECEIVERS)
        self.bind()
        prog = self.prog
        prog["u_first"] = int(first)
        for k in range(topo.levels):
            sl = topo.level_of(k)
            cnt = sl.stop - sl.start
            prog["u_offset"] = sl.start
            prog["u_count"] = cnt
            prog.run(G.dispatch_groups(cnt))
            self.ctx.memory_barrier()
        self.topology = topo
        return topo

    def read(self) -> dict:
        """The GPU geometry of the last build as numpy (for tests)."""
        n = self.topology.n_pixels
        sph = G.MIP_SPHERE.view(self.images["sphere"].read())[:n]
        cone = G.MIP_CONE.view(self.images["cone"].read())[:n]
        return {"centre": sph["center"].astype(np.float64),
                "radius": sph["radius"].astype(np.float64),
                "axis": cone["axis"].astype(np.float64), "angle": cone["angle"].astype(np.float64)}

    @property
    def nbytes(self) -> int:
        return PIXEL_BYTES * WIDTH * self.rows

    def release(self) -> None:
        for t in self.images.values():
            t.release()
        self.images = {}
        self.rows = 0
