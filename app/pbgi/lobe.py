"""The lobe micro-buffer: glossy and mirror-like materials (seed 001, Section 2.3: BRDF
importance-warped micro-buffers; the mapping itself is shaders/lib/lobe.glsl).

Why. A cosine-mapped M x M micro-buffer has micro-pixels of ~2 pi / M^2 sr; a GGX lobe of
alpha = roughness^2 is ~alpha^2 sr wide, so below roughness ~0.3 the lobe covers a few micro-pixels
and each bright node lands in one of them or none: the regular grid of dots, and errors of
100-1000% towards the mirror (measured against Mitsuba in the README). Refining the cosine buffer
cannot fix that at any affordable M.

What. A glossy receiver gets a second micro-buffer whose rings x sectors micro-pixels follow its
own lobe: rings equal in the GGX NDF's cumulative distribution, sectors equal in azimuth, around
its normal in half-vector space, mapped to directions by reflecting the view direction. Each
micro-pixel's solid angle (the Jacobian of that mapping) drives the cut - a narrow lobe refines
the hierarchy to the leaves around the reflection and nowhere else, a leaf larger than a
micro-pixel is ray cast as a disc through every micro-pixel it covers (a closed mirror image, not a
dot) - and weights the gather (f cos(theta) Omega per micro-pixel). The cosine micro-buffer keeps
the wide lobes (diffuse, subsurface, sheen) and the specular lobe outside the lobe's domain, so
the sphere of directions is split, not counted twice. Roughness -> 0 needs no separate mirror
path: the micro-pixels shrink into the reflection direction and all see the leaf the reflected
ray hits, continuously in roughness (the warp's alpha stops at 1e-3, the BRDF's own minimum).
Towards ``glossy_below`` the specular lobe is shared between the two buffers over a blend
(lib/lobe.glsl: lobe_spec_share), so the roughness slider shows no seam where the method changes.

Each receiver's frame is rotated by a random azimuth and each micro-pixel's ray is jittered
inside it (per pixel and ``pass``), so what quantisation remains is noise, never a grid; passes
average it (``render --passes``, the viewer's idle refinement).

The walk is the same in every mode (no far-field sharing for a lobe: its micro-pixels are too
small for a block's parallax) and resumable like Classic's (llvmpipe's loop limit).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from app.pbgi.gpu_layout import (CLASSIC_STATE, IMAGE, LOOP_LIMIT, MB_ENTRY, SSBO,
                                 WALK_CUT_SHORT, dispatch_groups)
from app.render.context import is_software_renderer
from app.render.programs import load_compute


@dataclass(frozen=True)
class LobeWalkTuning:
    """The lobe walk's private memory per invocation, which costs opposite ways on a CPU
    rasteriser and on a GPU (measured: README, "The lobe walk on a GPU").

    ``ray_table``: every micro-pixel's ray and solid angle computed once per receiver and
    dispatch into a table (LOBE_CELLS vec4s), or again for each accepted node that covers it.
    ``list_cap``: accepted nodes a dispatch collects before it ray casts them (two uint arrays
    of that length), so also how many dispatches a receiver's walk takes.
    ``accepted_table``: shaders/pbgi_lobe.glsl's LOBE_ACCEPTED_TABLE - the walk decides on a
    node's rings alone and a loop of its own over the accepted nodes computes their rectangles'
    sectors and their ray-cast records into a table (36 bytes a node), and the receiver's row
    is ray cast in the invocation's memory; without it the walk computes each rectangle whole
    and the ray casts fetch each node's record and read and write the image per hit.

    On llvmpipe the table saves the warp's trigonometry - a micro-pixel is ray cast against
    ~10-30 nodes - and the arrays live in the invocation's own stack, so it keeps both. On a GPU
    both are per-thread local memory, spilled to the caches and DRAM for thousands of threads at
    once, and they cost more than the trigonometry and the extra dispatches they save: a GPU
    computes each ray where it is cast and keeps a shorter list (the sizes measured in the
    README). The accepted-node table follows the same split: llvmpipe runs every branch of a
    loop's body on every iteration, so what only an accepted node needs costs it on every
    visit and every ray test unless it has a loop of its own; a GPU pays a branch only where
    it is taken, and the table would be spilled local memory ("The lobe walk's accepted nodes
    in a table", README). The list of 512 halves the dispatches a receiver's walk takes (each
    sets up its frame and ray table again); with the table, 1024 was no faster."""
    list_cap: int
    ray_table: bool
    accepted_table: bool = False


SOFTWARE_TUNING = LobeWalkTuning(list_cap=512, ray_table=True, accepted_table=True)
GPU_TUNING = LobeWalkTuning(list_cap=128, ray_table=False, accepted_table=False)
LOBE_TUNINGS = {"software": SOFTWARE_TUNING, "gpu": GPU_TUNING}   # by name (bench profile)


def tuning_name(tuning: LobeWalkTuning) -> str:
    return next((k for k, v in LOBE_TUNINGS.items() if v == tuning), str(tuning))


def lobe_walk_tuning(renderer: str) -> LobeWalkTuning:
    """The tuning for a GL_RENDERER string: llvmpipe and the other CPU rasterisers keep the
    table, any other renderer is taken for a GPU."""
    return SOFTWARE_TUNING if is_software_renderer(renderer) else GPU_TUNING


@dataclass(frozen=True)
class LobeSettings:
    """What a render's lobe micro-buffers are: ``rings`` x ``sectors`` micro-pixels, for the
    specular lobes of receivers rougher than nothing and smoother than ``glossy_below`` (and every
    clearcoat), jittered by ``pass_index``.

    ``stop_factor``: a node is accepted once its solid angle is at most this x the smallest
    micro-pixel it covers. Below 1 on purpose: an inner node is ray cast as the disc of its
    bounding sphere, which covers more than its points do, so a coarse near node hides the far
    ones behind it - on a room that darkens the grazing reflections of the window (metal r = 0.3:
    8% pooled error at 4, 3.7% at 1, 1.9% at 0.25 against Mitsuba)."""
    rings: int
    sectors: int
    glossy_below: float
    pass_index: int = 0
    stop_factor: float = 0.25
    # (x0, y0, tile width, image width): a receiver's frame is seeded by its pixel in the whole
    # image (shaders/lib/lobe.glsl: lobe_seed_pixel), so that a tile's receivers get the seeds
    # the same pixels get in one render of the image - a tile's own pixel index would repeat the
    # same seeds in every tile of the viewer's refinement, a pattern with the tiles' period
    seed_tile: tuple = (0, 0, 1, 1)
    # the M of the cosine micro-buffer that takes each lobe's tail outside the lobe's domain (per
    # run of receivers: pbgi.lobe_only_microbuffer's for a glossy metal's, app/pbgi/modebase.py):
    # the domain reaches a micro-pixel of it past the mirror direction (shaders/lib/lobe.glsl:
    # lobe_tan_floor); 0: no floor
    cosine_m: int = 0

    @property
    def cells(self) -> int:
        return self.rings * self.sectors

    @staticmethod
    def for_microbuffer(m: int, glossy_below: float, pass_index: int = 0) -> "LobeSettings":
        """LOBE_SIDE_FRACTION x M rings and sectors (at least LOBE_MIN_SIDE): what a clearcoat's
        two lobes use; shaders/lib/lobe_size.glsl gives a receiver with one lobe 2/3 of each
        side and one whose lobe is a small share of its light (a dielectric) fewer still. The
        warp already puts every micro-pixel inside the lobe, so fewer are needed than the cosine
        buffer's M x M, and the lobe walk's work grows with them: against Mitsuba (apartment
        room, M = 24, Hybrid) 12 x 12 was within 0.6 points of 16 x 16 in pooled error (metal
        r = 0, 0.1, 0.3; dielectric 0.3) at 60% of the lobe walk's time, and 16 x 16 within 1
        point of 24 x 24 at half of it."""
        side = max(LOBE_MIN_SIDE, int(round(LOBE_SIDE_FRACTION * m)))
        return LobeSettings(side, side, float(glossy_below), int(pass_index), cosine_m=int(m))


LOBE_SIDE_FRACTION = 0.5
LOBE_MIN_SIDE = 8


SURFACE_SAMPLE = 20_000


SURFACE_MARGIN = 1.5


def surface_radius(positions, k: int = 4, seed: int = 0) -> float:
    """Radius of the disc each point stands for when a ray meets the scan's surface (a leaf
    ray cast into a lobe micro-buffer, and the reference protocol's emissive squares):
    SURFACE_MARGIN x the median distance to the k-th nearest neighbour (app/pbgi/reference.py).
    Without the margin uniformly random points leave 2.5% of the surface uncovered - a mirror
    shows those holes as black dots -; with it, 0.02%. Estimated on a random subset of
    SURFACE_SAMPLE points and scaled by sqrt(n / sample) (a surface: the density is per area)."""
    from app.pbgi.reference import estimate_disc_radius
    pts = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    n = len(pts)
    if n <= SURFACE_SAMPLE:
        return SURFACE_MARGIN * estimate_disc_radius(pts, k) if n >= 2 else 0.0
    sub = pts[np.random.default_rng(seed).choice(n, SURFACE_SAMPLE, replace=False)]
    return float(SURFACE_MARGIN * estimate_disc_radius(sub, k) * np.sqrt(SURFACE_SAMPLE / n))


def needs_lobe(materials, glossy_below: float) -> bool:
    """Can any receiver of these materials need a lobe buffer? (A roughness texture can lower the
    roughness below its factor's: glTF multiplies, so the factor is an upper bound.)"""
    for m in materials:
        if m.clearcoat > 0.0 or m.roughness < glossy_below or (
                m.metallic_roughness_texture is not None):
            return True
    return False


LOBE_BLEND = 0.3      # lib/lobe.glsl's LOBE_BLEND: the lobe buffer takes the whole specular
                      # lobe up to (1 - LOBE_BLEND) x glossy_below (tests/pbgi/test_lobe_only.py)


def lobe_only_receivers(metallic, roughness, glossy_below: float) -> np.ndarray:
    """Per receiver (its metallic and roughness as the G-buffer sampled them, textures applied):
    is its light gathered from the lobe micro-buffers alone, up to a tail a coarse cosine
    micro-buffer resolves? Those receivers get pbgi.lobe_only_microbuffer's M, the others the
    full one, in the same image (app/pbgi/modebase.py: receiver groups). A metal (metallic 1)
    has no diffuse, sheen or subsurface lobe, and below (1 - LOBE_BLEND) glossy_below its whole
    specular lobe and any clearcoat are in the lobe buffer. The cosine micro-buffer then holds
    only the specular lobe's tail outside the lobe's domain (about 1% of its energy), so a
    coarse one is enough, down to the mirror. Below roughness ~0.1 that tail used to be a
    narrow ring just outside the domain that one coarse micro-pixel's centre sampled or missed
    (white furnace, Classic, single pixels off by 34% at roughness 0 - 0.02 and 13% at 0.05
    with M 8), and those metals kept the full M; the domain now reaches a coarse micro-pixel
    past the mirror direction (LobeSettings.cosine_m, shaders/lib/lobe.glsl: lobe_tan_floor):
    1.5% at 0 - 0.05, 2.3-3.1% at 0.08 - 0.1 with M 8.

    The rule is the opposite of "a rough receiver needs fewer micro-pixels": a rough receiver's
    light is all in the cosine buffer, a glossy metal's nearly none of it."""
    metallic = np.asarray(metallic, dtype=np.float64)
    roughness = np.asarray(roughness, dtype=np.float64)
    full = float(glossy_below) * (1.0 - LOBE_BLEND)
    return (metallic >= 1.0) & (roughness < full)


def bytes_per_receiver(settings: LobeSettings | None) -> int:
    return 0 if settings is None else settings.cells * MB_ENTRY.nbytes + CLASSIC_STATE.nbytes


class LobeBuffers:
    """The lobe micro-buffers of one batch (an RG32UI image, one row per receiver) and the walk
    that fills them (shaders/pbgi_lobe.glsl)."""

    def __init__(self, ctx, tuning: LobeWalkTuning, steps: int = 16384,
                 splat_budget: int = 32768, max_rounds: int = 100000,
                 defines: dict | None = None):
        self.tuning = tuning
        self.defines = dict(defines or {})   # added to the walk's (gpu_layout.WALK_ONLY)
        list_cap = tuning.list_cap
        if steps + splat_budget + list_cap >= LOOP_LIMIT:
            raise ValueError("steps + splat_budget must stay below llvmpipe's loop limit")
        self.ctx = ctx
        self.list_cap = int(list_cap)
        self._progs = {}                 # absent BRDF features -> the walk's program variant
        self._clear = load_compute(ctx, "mb_clear.glsl")
        self.steps, self.splat_budget, self.max_rounds = int(steps), int(splat_budget), max_rounds
        self.image = None
        self.width = self.rows = 0
        self.state = None
        self.counter = ctx.buffer(reserve=4)

    @property
    def nbytes(self) -> int:
        return 0 if self.image is None else self.width * self.rows * MB_ENTRY.nbytes + (
            self.state.size if self.state is not None else 0)

    def _prepare(self, width: int, capacity: int, count: int) -> None:
        if self.image is None or self.width != width or self.rows < capacity:
            if self.image is not None:
                self.image.release()
            self.image = self.ctx.texture((width, capacity), MB_ENTRY.texel_components,
                                          dtype=MB_ENTRY.texture_dtype)
            self.width, self.rows = width, capacity
        need = CLASSIC_STATE.nbytes * count
        if self.state is None or self.state.size < need:
            if self.state is not None:
                self.state.release()
            self.state = self.ctx.buffer(reserve=need)
        self.state.clear(size=need)
        # empty the rows: mb_clear.glsl writes the image bound to the micro-buffer unit
        self.image.bind_to_image(IMAGE.MB, read=True, write=True)
        self._clear["u_width"] = width
        self._clear["u_count"] = count
        self._clear.run(dispatch_groups(count))
        self.ctx.memory_barrier()

    def bind(self) -> None:
        self.image.bind_to_image(IMAGE.LOBE, read=True, write=True)

    def program(self, cells: int, absent: tuple = ()):
        """The walk for ``cells`` micro-pixels (the size of its per-receiver ray table),
        compiled without the code of the BRDF features no material uses
        (gather.absent_features; lib/lobe.glsl leaves the anisotropic stretch out)."""
        key = (int(cells), tuple(absent))
        if key not in self._progs:
            # the walk's visits, its ray tests, the accepted list's loop, the ray table and the
            # row's load and store: all one invocation's loops together
            if (self.steps + self.splat_budget + 2 * self.list_cap + 3 * cells
                    >= LOOP_LIMIT):
                raise ValueError("the lobe walk's loops would pass llvmpipe's loop limit")
            defines = {"LIST_CAP": self.list_cap, "LOBE_CELLS": int(cells),
                       "LOBE_RAY_TABLE": int(self.tuning.ray_table),
                       "LOBE_ACCEPTED_TABLE": int(self.tuning.accepted_table)}
            defines.update({f"PRINCIPLED_NO_{tag}": 1 for tag in absent})
            defines.update(self.defines)
            self._progs[key] = load_compute(self.ctx, "pbgi_lobe.glsl", defines=defines)
        return self._progs[key]

    def fill(self, settings: LobeSettings, receivers, materials, first: int, count: int,
             capacity: int, nodes, cell_size: float, camera_rel, leaf_radius: float,
             absent: tuple = ()) -> dict:
        """Walk and ray cast the lobe micro-buffers of receivers [first, first + count);
        each point is a disc of ``leaf_radius`` (surface_radius of the cloud), so a leaf is a disc
        of its sphere's radius + leaf_radius - except the asset's surfels (nodes from
        ``nodes.asset_first`` on, app/pbgi/scene_tree.py), discs of their own size."""
        if self.splat_budget < settings.cells:
            raise ValueError("splat budget must cover one whole lobe micro-buffer")
        self._prepare(settings.cells, capacity, count)
        receivers.bind_to_storage_buffer(SSBO.RECEIVERS)
        materials.bind_to_storage_buffer(SSBO.MATERIALS)
        self.state.bind_to_storage_buffer(SSBO.WALK_STATE)
        self.counter.bind_to_storage_buffer(SSBO.COUNTERS)
        nodes.use()
        self.bind()
        prog = self.program(settings.cells, absent)
        values = {"u_first": first, "u_count": count, "u_rings": settings.rings,
                  "u_lobe_tile": tuple(int(v) for v in settings.seed_tile),
                  "u_lobe_cosine_m": int(settings.cosine_m),
                  "u_sectors": settings.sectors, "u_pass": settings.pass_index,
                  "u_glossy_below": settings.glossy_below, "u_stop_factor": settings.stop_factor,
                  "u_steps": self.steps, "u_splat_budget": self.splat_budget,
                  "u_inv_cell_area": 1.0 / max(cell_size, 1e-9) ** 2,
                  "u_node_count": nodes.count, "u_leaf_radius": float(leaf_radius),
                  "u_camera": tuple(float(c) for c in camera_rel)}
        for name, value in values.items():
            if name in prog:
                prog[name] = value
        nodes.set_uniforms(prog)
        rounds, remaining = 0, count
        while remaining and rounds < self.max_rounds:
            self.counter.write(b"\0\0\0\0")
            prog.run(dispatch_groups(count))
            self.ctx.memory_barrier()
            remaining = int(np.frombuffer(self.counter.read(), np.uint32)[0])
            rounds += 1
        st = CLASSIC_STATE.view(self.state.read(size=CLASSIC_STATE.nbytes * count))
        return {"rounds": rounds, "incomplete": int((st["next"] < nodes.count).sum()),
                "visited": float(st["visited"].mean()), "tests": float(st["tests"].mean()),
                "cut_short": int(((st["flags"] & WALK_CUT_SHORT) != 0).sum())}

    def read(self, receivers: int) -> np.ndarray:
        raw = np.frombuffer(self.image.read(), dtype=np.uint32)
        return raw.reshape(self.rows, self.width, MB_ENTRY.words)[:receivers]

    def release(self) -> None:
        for obj in (self.image, self.state, self.counter):
            if obj is not None:
                obj.release()
        self.image = self.state = self.counter = None
