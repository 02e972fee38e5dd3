"""The micro-buffer shared by every PBGI mode: its micro-pixel table, its storage and its batching.

A micro-buffer is an M x M image of the receiver's upper hemisphere under the Nusselt projection
Phi(x, y) = (x, y, sqrt(1 - x^2 - y^2)) (paper Section 5.2, Ritschel et al. 2009 Section 2.3),
x, y in [-1, 1] along the receiver's frame: orthonormal_basis(N) (lib/principled.glsl) turned
about N by a random angle per receiver and pass (``set_frame_uniforms``; in Hybrid's shared
blocks per block and pass).

Micro-pixel table (computed here once per M, uploaded as gpu_layout.MB_DIRECTION texels):
  * ``weight`` = area of (pixel square intersected with the unit disc) = the pixel's
    *cosine-weighted* solid angle: integral of cos(theta) d omega over the pixel. Eq. 9's
    Omega_ij (n . w_ij) is exactly this number, so the gather weights each micro-pixel by its own
    solid angle (paper Section 5.3's correction) and pixels that straddle the horizon only count
    their part above it. The weights sum to pi, so a constant radiance L and a Lambertian BRDF
    a / pi gather to a * L exactly.
  * ``dir`` = Phi of the centroid of that clipped area: the representative incoming direction,
    always strictly above the horizon.
  * ``solid_angle`` (kept on the CPU) = the pixel's plain solid angle; sums to 2 pi.

Storage: one RG32UI texel per micro-pixel, gpu_layout.MB_ENTRY (depth key, node index); empty =
(MB_EMPTY, MB_EMPTY). The depth key is the depth's float bits with a coplanar tie-break in its low bits
(lib/microbuffer.glsl). Keeping the node index rather than its colour halves the memory of an RGBA16F
texel, and radiance is read from the float32 node record at gather time, so HDR values above the
half-float limit (65504) cannot overflow. Non-negative floats order like their bit patterns, so a
mode whose invocations race on one micro-buffer can depth-test the key with imageAtomicMin.

Batching: a render's receivers (object pixels) are processed in batches whose micro-buffers fit a
memory budget and the largest texture (one image row per receiver).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from app.params import BY_KEY
from app.pbgi.gpu_layout import (IMAGE, MB_BANDS, MB_DIRECTION, MB_EMPTY, MB_ENTRY, MB_FLUX,
                                 TEXTURE, dispatch_groups)

# the micro-buffer sizes the shaders support: the range of the parameter table's pbgi.microbuffer
MIN_SIZE, MAX_SIZE = int(BY_KEY["pbgi.microbuffer"].lo), int(BY_KEY["pbgi.microbuffer"].hi)
ENTRY_BYTES = MB_ENTRY.nbytes       # RG32UI (depth key, node index)
EMPTY = MB_EMPTY                    # empty key and node


def omega_micro(m: int) -> float:
    """Eq. 5: the constant solid angle 2 pi / M^2 the stopping threshold is based on."""
    return 2.0 * np.pi / (m * m)


HORIZON_SPLIT = 4.0   # a micro-pixel spanning more than HORIZON_SPLIT / M radians of elevation
MAX_SPLIT = 8         # ... is cut into that many elevation bands (at most MAX_SPLIT)

# The largest node (solid angle, sr) accepted across the receiver's horizon: 2 pi / 64, Omega at
# M = 8. A node the horizon cuts is drawn only in the directions above it, into rim micro-pixels
# split into elevation bands (above); at M = 8 a pixel has two bands of ~20 degrees, and the stop
# rule's 4 Omega (0.39 sr) nodes there smeared the light below the horizon into them: a light
# panel cut in half by a receiver's tangent plane came out 1.56x the reference, 1.28x with nodes
# of Omega (tests/pbgi/test_pbgi_reference.py). From M = 10 up the bands are thin enough for the
# stop rule's own nodes (1.00-1.11x at M 10-20, any factor up to 4), and refining the horizon's
# nodes further cost Classic 29% of its node visits at M 16 for no accuracy against the path
# tracer (the asset references within 0.05 points).
HORIZON_OMEGA = 2.0 * np.pi / 64.0


def omega_horizon(m: int, stop_factor: float) -> float:
    """The acceptance threshold of a node straddling the horizon (lib/pbgi_cut.glsl's
    omega_horizon): the stop rule's, at most HORIZON_OMEGA."""
    return min(stop_factor * omega_micro(m), HORIZON_OMEGA)


def set_frame_uniforms(prog, seed_tile=(0, 0, 1, 1), pass_index: int = 0,
                       turned: bool = True) -> None:
    """The uniforms of lib/microbuffer.glsl's ``mb_frame``: the receiver's frame turned about
    its normal by an angle drawn from its pixel in the whole image (``seed_tile``: tile x0, y0,
    tile width, image width) and the pass; ``turned`` False: orthonormal_basis(N) itself. Every
    program that draws or reads a receiver's own micro-buffer sets them from the same render,
    so its walk, rasteriser and gather agree.

    Why (issue 12, seed 001 Section 2.3): in a fixed frame the micro-pixel grid turns smoothly
    with the normal, so the instant a light crosses a micro-pixel's edge, or the cut swaps a node
    for its children, is the same for neighbouring receivers, and a smooth diffuse surface shows
    the grid as lines and facets (Classic, README "Frames turned per receiver"). A random turn
    per receiver makes the same quantisation error noise, which the passes average. Hybrid's
    blocks share one micro-buffer among receivers: the programs that draw and read it take
    its seed from their records instead (``mb_frame_shared``; farfield.square_seeds), one turn
    per block and pass, and the same uniforms give the pass and the pixels of receivers
    without a block. The point gathers (app/pbgi/point_gather.py) keep the fixed frame: no
    passes average their noise, and the asset's glossy bounce fits a plane to each surfel's
    views, which noise from surfel to surfel makes worse."""
    values = {"u_frame_tile": tuple(int(v) for v in seed_tile), "u_frame_pass": int(pass_index),
              "u_frame_turned": bool(turned)}
    for name, value in values.items():
        if name in prog:
            prog[name] = value


def _region_integrals(x0, x1, y0, y1, r_in, r_out, samples):
    """For regions [x0, x1] x [y0, y1] intersected with the annulus r_in <= r <= r_out (arrays
    of shape (E,)): cosine-weighted solid angle (= projected area), its centroid (x, y), solid
    angle, and the x and y parts of the direction flux (integral of w d omega; its z part is the
    projected area). The y integrals are analytic per x (d omega = dA / z, z = sqrt(a^2 - y^2)
    with a^2 = 1 - x^2: y / z integrates to -z); x is a midpoint sum of ``samples`` nodes."""
    t = (np.arange(samples) + 0.5) / samples
    xs = x0[:, None] + (x1 - x0)[:, None] * t[None, :]                    # (E, S)
    dx = ((x1 - x0) / samples)[:, None]
    a1 = np.sqrt(np.maximum(1.0 - xs * xs, 0.0))                           # unit-disc half chord
    a_in = np.sqrt(np.maximum(r_in[:, None] ** 2 - xs * xs, 0.0))
    a_out = np.sqrt(np.maximum(r_out[:, None] ** 2 - xs * xs, 0.0))
    area = mx = my = omega = fx = fy = 0.0
    for lo_, hi_ in ((a_in, a_out), (-a_out, -a_in)):                     # y > 0 and y < 0 parts
        lo = np.maximum(lo_, y0[:, None])
        hi = np.minimum(hi_, y1[:, None])
        ok = hi > lo
        length = np.where(ok, hi - lo, 0.0)
        area = area + (length * dx).sum(1)
        mx = mx + (length * xs * dx).sum(1)
        my = my + (np.where(ok, 0.5 * (hi * hi - lo * lo), 0.0) * dx).sum(1)
        with np.errstate(divide="ignore", invalid="ignore"):
            ang = np.where(ok & (a1 > 0), np.arcsin(np.clip(hi / a1, -1, 1))
                           - np.arcsin(np.clip(lo / a1, -1, 1)), 0.0)
        omega = omega + (ang * dx).sum(1)
        fx = fx + (ang * xs * dx).sum(1)
        fy = fy + (np.where(ok, np.sqrt(np.maximum(a1 * a1 - lo * lo, 0.0))
                            - np.sqrt(np.maximum(a1 * a1 - hi * hi, 0.0)), 0.0) * dx).sum(1)
    return area, mx, my, omega, fx, fy


@lru_cache(maxsize=None)
def micro_pixel_table(m: int, samples: int = 1024) -> dict:
    """The micro-pixel table of an M x M micro-buffer.

    Each grid pixel that meets the unit disc holds one or more *entries* (micro-buffer texels).
    A pixel near the rim spans many degrees of elevation in the Nusselt projection (the outer
    ring of a 16 x 16 buffer: from the horizon to ~28 degrees), so a single direction ray decides
    all-or-nothing for a thin light just above the horizon - the edge micro-pixel then counts it
    over its whole area, up to 2x too much (measured: 1.7x at M = 16 against the CPU reference).
    Such a pixel is cut into bands of equal elevation, at most HORIZON_SPLIT / M radians each,
    one entry per band, each with its own direction and weight.

    Layout: entry k < M*M is band 0 (the one nearest the horizon) of grid pixel k = y * M + x -
    pixels outside the disc keep a zero-weight entry, so a rasteriser that only knows the grid
    still addresses valid texels - and the further bands of every split pixel follow from entry
    M*M on, grouped by pixel in grid order.

    Returns: dir (E, 3) unit centroid direction of the entry's region (cosine-weighted); weight
    (E,) its cosine-weighted solid angle (sums to pi); solid_angle (E,) (sums to 2 pi); flux
    (E, 3) the integral of the direction over the region, so that the cosine-weighted solid
    angle about ANY normal n the region lies above is n . flux (flux.z = weight); pixel
    (E,) its grid pixel; extra_first, extra_count (M*M,) where a pixel's further bands start and
    how many there are; prefix (M + 1, M + 1) the summed-area table of extra_count, so that a
    rectangle's entry count is its area plus four look-ups (rect_entries); elevation_lo,
    elevation_step (M*M,) the elevation where band b of a pixel starts is elevation_lo +
    b * elevation_step (band 0 reaches down to the horizon), so a rasteriser can skip the bands
    a node's elevations miss; entries = E.
    """
    if not MIN_SIZE <= m <= MAX_SIZE:
        raise ValueError(f"micro-buffer size must be in [{MIN_SIZE}, {MAX_SIZE}], got {m}")
    e = np.linspace(-1.0, 1.0, m + 1)
    gy, gx = np.meshgrid(np.arange(m), np.arange(m), indexing="ij")
    x0, x1, y0, y1 = e[gx].ravel(), e[gx + 1].ravel(), e[gy].ravel(), e[gy + 1].ravel()
    r_min = np.hypot(np.clip(0.0, x0, x1), np.clip(0.0, y0, y1))
    r_max = np.minimum(1.0, np.hypot(np.maximum(np.abs(x0), np.abs(x1)),
                                     np.maximum(np.abs(y0), np.abs(y1))))
    e_lo, e_hi = np.arccos(r_max), np.arccos(np.minimum(r_min, 1.0))        # elevations
    split = np.clip(np.ceil((e_hi - e_lo) / (HORIZON_SPLIT / m) - 1e-9), 1, MAX_SPLIT)
    split = np.where(r_min < 1.0, split, 1).astype(np.int64)
    pix = np.repeat(np.arange(m * m), split)
    band = np.arange(len(pix)) - np.repeat(np.cumsum(split) - split, split)
    n = split[pix]
    r_in = np.where(band + 1 == n, r_min[pix],
                    np.cos(e_lo[pix] + (e_hi - e_lo)[pix] * (band + 1) / n))
    r_out = np.where(band == 0, 1.0, np.cos(e_lo[pix] + (e_hi - e_lo)[pix] * band / n))
    area, mx, my, omega, fx, fy = _region_integrals(x0[pix], x1[pix], y0[pix], y1[pix],
                                                    np.minimum(r_in, 1.0), r_out, samples)
    order = np.r_[np.flatnonzero(band == 0), np.flatnonzero(band > 0)]     # band 0 first
    pix, area, mx, my, omega = pix[order], area[order], mx[order], my[order], omega[order]
    flux = np.stack([fx[order], fy[order], area], axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        cx = np.where(area > 0, mx / area, 0.0)
        cy = np.where(area > 0, my / area, 0.0)
    dirs = np.stack([cx, cy, np.sqrt(np.maximum(1.0 - cx * cx - cy * cy, 0.0))], axis=-1)
    dirs /= np.linalg.norm(dirs, axis=-1, keepdims=True)
    extra_count = split - 1
    extra_first = m * m + np.cumsum(extra_count) - extra_count
    prefix = np.zeros((m + 1, m + 1), dtype=np.int64)
    prefix[1:, 1:] = extra_count.reshape(m, m).cumsum(0).cumsum(1)
    return {"dir": dirs, "weight": area, "solid_angle": omega, "flux": flux, "pixel": pix,
            "extra_first": extra_first, "extra_count": extra_count, "prefix": prefix,
            "elevation_lo": e_lo, "elevation_step": (e_hi - e_lo) / split,
            "entries": len(pix)}


def rect_entries(table: dict, x0: int, y0: int, x1: int, y1: int) -> int:
    """Entries of the pixel rectangle [x0, x1] x [y0, y1] (inclusive)."""
    p = table["prefix"]
    extra = p[y1 + 1, x1 + 1] - p[y0, x1 + 1] - p[y1 + 1, x0] + p[y0, x0]
    return int((x1 - x0 + 1) * (y1 - y0 + 1) + extra)


def table_bytes(m: int) -> bytes:
    """The entry table of size M as MB_DIRECTION texels."""
    t = micro_pixel_table(m)
    rec = MB_DIRECTION.zeros(t["entries"])
    rec["dir"], rec["weight"] = t["dir"], t["weight"]
    return rec.tobytes()


def flux_bytes(m: int) -> bytes:
    """The entries' flux and solid angle as MB_FLUX texels."""
    t = micro_pixel_table(m)
    rec = MB_FLUX.zeros(t["entries"])
    rec["flux"], rec["solid_angle"] = t["flux"], t["solid_angle"]
    return rec.tobytes()


def index_bytes(m: int) -> bytes:
    """The (M + 1) x (M + 1) grid pixel index as MB_BANDS texels, row y = grid row y."""
    t = micro_pixel_table(m)
    rec = MB_BANDS.zeros((m + 1) * (m + 1)).reshape(m + 1, m + 1)
    rec["first"][:m, :m] = t["extra_first"].reshape(m, m)
    rec["count"][:m, :m] = t["extra_count"].reshape(m, m)
    rec["prefix"] = t["prefix"]
    rec["elevation"][:m, :m] = (_elevation_units(t["elevation_lo"])
                                | (_elevation_units(t["elevation_step"]) << 16)).reshape(m, m)
    return rec.tobytes()


ELEVATION_UNIT = (np.pi / 2) / 65535.0     # MB_BANDS.elevation's 16-bit fractions of pi / 2


def _elevation_units(angle: np.ndarray) -> np.ndarray:
    return np.clip(np.rint(np.asarray(angle) / ELEVATION_UNIT), 0, 65535).astype(np.uint32)


def entries(m: int) -> int:
    """Micro-buffer texels per receiver for size M (M*M grid pixels plus the further
    elevation bands of rim pixels: 1.15-1.35 x M*M)."""
    return micro_pixel_table(m)["entries"]


def bytes_per_receiver(m: int) -> int:
    return entries(m) * ENTRY_BYTES


def batch_size(m: int, budget_bytes: float, max_rows: int, n_receivers: int,
               minimum: int = 64) -> int:
    """Receivers per batch: as many micro-buffers as the budget allows (at least ``minimum``, so
    a tiny budget still makes progress), one image row each, at most ``max_rows`` rows."""
    fit = int(budget_bytes // bytes_per_receiver(m))
    return int(max(1, min(max(fit, minimum), max_rows, max(n_receivers, 1))))


_TABLES: dict = {}


def _cached(ctx, m: int, name: str, size, record, data):
    key = (id(ctx), m, name)
    tex = _TABLES.get(key)
    if tex is None:
        import moderngl
        tex = ctx.texture(size, record.texel_components, data(m), dtype=record.texture_dtype)
        tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        _TABLES[key] = tex
    return tex


def table_texture(ctx, m: int):
    """The entry table of size M as an (E, 1) texture of MB_DIRECTION texels (dir, weight), one
    per context and M (TEXTURE.MB_TABLE)."""
    return _cached(ctx, m, "table", (entries(m), 1), MB_DIRECTION, table_bytes)


def flux_texture(ctx, m: int):
    """The entries' direction flux (micro_pixel_table's ``flux``) and solid angle as an (E, 1)
    texture of MB_FLUX texels: how a receiver weights a micro-buffer kept in another normal's
    frame (Hybrid's far-field sharing; FRAME_NORMALS in shaders/pbgi_gather.glsl, unit
    TEXTURE.MB_FLUX)."""
    return _cached(ctx, m, "flux", (entries(m), 1), MB_FLUX, flux_bytes)


def index_texture(ctx, m: int):
    """(M + 1) x (M + 1) MB_BANDS texels, texel (x, y): first further band of pixel (x, y),
    number of further bands, summed-area prefix of those numbers (TEXTURE.MB_INDEX)."""
    return _cached(ctx, m, "index", (m + 1, m + 1), MB_BANDS, index_bytes)


class MicroBuffers:
    """The GPU storage of one batch of micro-buffers: an RG32UI image, one row per receiver,
    one texel per micro-pixel (see lib/microbuffer.glsl). Reused across batches and frames."""

    def __init__(self, ctx):
        from app.render.programs import load_compute
        self.ctx = ctx
        self.image = None
        self.m = 0
        self.rows = 0
        self.table = self.index = None
        self._clear = load_compute(ctx, "mb_clear.glsl")

    def prepare(self, m: int, capacity: int, receivers: int | None = None) -> None:
        """Storage for ``capacity`` micro-buffers of size M (kept while M and the capacity
        stay the same), the first ``receivers`` (default all) of them emptied."""
        receivers = capacity if receivers is None else receivers
        width = entries(m)
        if self.image is None or self.m != m or self.rows != capacity:
            if self.image is not None:
                self.image.release()
            self.image = self.ctx.texture((width, capacity), MB_ENTRY.texel_components,
                                          dtype=MB_ENTRY.texture_dtype)
            self.m, self.rows = m, capacity
        self.table = table_texture(self.ctx, m)
        self.index = index_texture(self.ctx, m)
        self.bind()
        if receivers > 0:
            self._clear["u_width"] = width
            self._clear["u_count"] = receivers
            self._clear.run(dispatch_groups(receivers))
            self.ctx.memory_barrier()

    def bind(self, image_unit: int = IMAGE.MB, table_unit: int = TEXTURE.MB_TABLE,
             index_unit: int = TEXTURE.MB_INDEX) -> None:
        self.image.bind_to_image(image_unit, read=True, write=True)
        self.table.use(location=table_unit)
        self.index.use(location=index_unit)

    def read(self, receivers: int) -> np.ndarray:
        """(receivers, E, 2) uint32 MB_ENTRY words (depth key, node index) - for tests and
        debugging."""
        raw = np.frombuffer(self.image.read(), dtype=np.uint32)
        return raw.reshape(self.rows, entries(self.m), MB_ENTRY.words)[:receivers]

    @property
    def nbytes(self) -> int:
        if self.image is None:
            return 0
        return (entries(self.m) * (self.rows * ENTRY_BYTES + MB_DIRECTION.nbytes)
                + MB_BANDS.nbytes * (self.m + 1) ** 2)

    def release(self) -> None:
        if self.image is not None:
            self.image.release()
        self.image = self.table = self.index = None
        self.m = self.rows = 0
