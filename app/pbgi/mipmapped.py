"""Mipmapped PBGI (paper Section 5.2.1): the BSH walk is shared between neighbouring receivers by
refining (node, pixel) pairs over a G-buffer pyramid (app/pbgi/gmip.py), then finished per
receiver. The exact Hybrid PBGI (app/pbgi/hybrid.py, parallax tolerance 0) is the same engine
with Omega_tr > 0; the default Hybrid shares the far field instead (app/pbgi/farfield.py).

``PairRefiner`` is a cut finder (app/pbgi/modebase.py) like app.pbgi.classic.ClassicCut: ``fill``
fills the micro-buffers of one batch of receivers. It also reads the batch's ``width`` (the tile
width: receivers carry row-major pixel indices, the pyramid needs x, y) and ``budget_bytes`` (the
memory budget the pair buffers are sized from).

Pipeline per batch:

1. pyramid: Z-order the batch's pixels, build the sparse pyramid (topology in numpy, bounds and
   normal cones merged on the GPU);
2. refinement passes (shaders/pbgi_refine.glsl): pairs [root, every pixel of the coarsest
   level] on a bounded stack; each pass pops the top K pairs, refines them in parallel (cull /
   children / child pixels / second stream) and appends the results with atomics; the next
   pass's dispatch size is computed on the GPU (indirect dispatch). Until the stack is empty.
3. finishing walk (shaders/pbgi_finish.glsl): per receiver, Classic's depth-first walk of every
   sub-tree handed to the second stream on the lists of the pixels above it, rasterising into
   its micro-buffer (Classic's rasteriser, lib/pbgi_cut.glsl). Mipmapped hands over only nodes
   every receiver below the pixel decides in one step (accepted at level 0, or small enough
   from the pixel's nearest point), so its finishing walk visits each once and rasterises;
   Hybrid hands over whole sub-trees below Omega_tr. When the second stream fills up it is
   finished and emptied mid-batch, so its size is bounded by the budget, not by the scene.

Memory: the stack and the second stream are images sized per batch from a per-receiver estimate
and capped at ``stream_share`` of the budget; a buffer more than twice too big is reallocated
smaller. Running short never fails, it costs passes (fewer
pairs per pass, or children disabled: pairs go to the second stream) or flushes. GL refusing an
allocation raises AllocationError, which the renderer answers by halving the batch.

Why compute passes, not a geometry shader with transform feedback (the paper's design): on
llvmpipe the same refinement step (read a pair, test it, emit its children) runs several times
faster as a compute dispatch with an atomic append than through a vertex + geometry shader into
transform feedback (tests/pbgi/test_refine_backends.py runs both; time them there), and the
compute version needs no per-pass query read-back: its next dispatch size is computed on the GPU
(indirect dispatch).

Every pass and the finishing walk keep per-invocation work below llvmpipe's 65,535 loop
iterations (the refinement has no loop over more than 4 items; the walk has Classic's budgets),
and ``fill`` reports per receiver whether its walk completed.
"""

from __future__ import annotations

import time

import numpy as np

from app.pbgi.gmip import PIXEL_BYTES, WIDTH, MipPyramid, image_rows, to_rows, z_order
from app.pbgi.gpu_layout import (FINISH_STATE, HEAD, IMAGE, ITEM, NIL, PAIR, PAIR_COUNTERS,
                                 LOOP_LIMIT, RECEIVER, SSBO, WALK_CUT_SHORT, WALK_DONE,
                                 dispatch_groups)
from app.pbgi.microbuffer import entries, omega_horizon, omega_micro, set_frame_uniforms
from app.pbgi.modebase import (AllocationError, Batch, CutFigures, CutFinder, MicroBufferMode,
                               RenderParams)
from app.pbgi.stats import PairFigures
from app.render.programs import load_compute

COUNTER_WORDS = PAIR_COUNTERS.words
PAIR_BYTES = PAIR.nbytes
ITEM_BYTES = ITEM.nbytes
STATE_BYTES = FINISH_STATE.nbytes
# counters[] word indexes: gpu_layout.PAIR_COUNTERS (the shader's C_* from gen/pair_streams.glsl)
_C = {f.name: PAIR_COUNTERS.index(f.name) for f in PAIR_COUNTERS.fields}
C_STACK, C_S2, C_BASE, C_K = _C["stack"], _C["s2"], _C["base"], _C["k"]
C_REFINE_ARGS, C_MOVE_ARGS = _C["refine_args"], _C["move_args"]
C_PUSHED_BACK, C_PROCESSED = _C["pushed_back"], _C["processed"]
C_NODE_REFINES, C_PIXEL_SPLITS = _C["node_refines"], _C["pixel_splits"]
C_CULLED, C_TO_S2, C_PEAK_STACK = _C["culled"], _C["to_s2"], _C["peak_stack"]
C_PASSES, C_ACCEPTED, C_KMAX = _C["passes"], _C["accepted"], _C["kmax"]
C_CAP, C_S2_CAP, C_DISABLED_PASSES = _C["cap"], _C["s2_cap"], _C["disabled_passes"]

MIN_STACK_PAIRS = 4096
MIN_ITEMS = 4096


def gl_alloc(ctx, kind: str, *args):
    """ctx.buffer(reserve=n) (kind "buffer", args (n,)) or ctx.texture(size, comps, dtype=...)
    (kind "texture", args (size, comps, dtype)), GL's out-of-memory turned into
    AllocationError so the caller can halve its tile and retry."""
    import moderngl
    try:
        if kind == "buffer":
            return ctx.buffer(reserve=int(args[0]))
        size, comps, dtype = args
        return ctx.texture(size, comps, dtype=dtype)
    except (moderngl.Error, MemoryError) as exc:
        raise AllocationError(f"could not allocate a {kind} {args}: {exc}") from None


def _set(prog, **uniforms) -> None:
    """Set the uniforms the compiler kept (unused ones are optimised away)."""
    for k, v in uniforms.items():
        if k in prog:
            prog[k] = v


class PairRefiner(CutFinder):
    """The (node, pixel) pair engine; ``omega_tr_factor`` = 0 is Mipmapped, > 0 Hybrid.

    ``steps``, ``splat_budget`` and ``list_cap`` are the finishing walk's per-dispatch budgets
    (Classic's, below llvmpipe's loop limit); ``stop_factor`` Classic's threshold (the horizon's:
    microbuffer.omega_horizon); ``pixel_factor`` scales the paper's node-vs-pixel-cone test;
    ``cull_margin`` (radians) is how far a coarse cull must clear its test (float32 slack);
    ``stream_share`` of the budget (at most ``max_stream_bytes``) caps each stream;
    ``alloc(kind, *args)`` makes GL objects (tests inject refusals); ``defines`` go to every
    shader (profiling)."""

    clears_microbuffers = False       # the walks write only the entries their nodes cover

    def __init__(self, ctx, omega_tr_factor: float = 0.0, steps: int = 16384,
                 splat_budget: int = 32768, list_cap: int = 256, stop_factor: float = 4.0,
                 pixel_factor: float = 1.0,
                 cull_margin: float = 1e-3, stream_share: float = 1.0 / 16.0,
                 max_stream_bytes: int = 64 << 20, max_rounds: int = 100000, alloc=None,
                 defines: dict | None = None):
        if steps + splat_budget + list_cap >= LOOP_LIMIT:
            raise ValueError("steps + splat_budget must stay below llvmpipe's loop limit")
        self.ctx = ctx
        self.omega_tr_factor = float(omega_tr_factor)
        self.steps, self.splat_budget = int(steps), int(splat_budget)
        self.stop_factor = float(stop_factor)
        self.pixel_factor, self.cull_margin = float(pixel_factor), float(cull_margin)
        self.stream_share, self.max_stream_bytes = float(stream_share), int(max_stream_bytes)
        self.max_rounds = int(max_rounds)
        self._alloc = alloc or (lambda kind, *a: gl_alloc(ctx, kind, *a))
        cap = {"CUT_LIST_CAP": int(list_cap), **(defines or {})}
        self.prepare = load_compute(ctx, "pbgi_refine.glsl", defines={"STAGE_PREPARE": 1, **cap})
        self.refine = load_compute(ctx, "pbgi_refine.glsl", defines={"STAGE_REFINE": 1, **cap})
        self.fixup = load_compute(ctx, "pbgi_refine.glsl", defines={"STAGE_FIXUP": 1, **cap})
        self.move = load_compute(ctx, "pbgi_refine.glsl", defines={"STAGE_MOVE": 1, **cap})
        self.finish = load_compute(ctx, "pbgi_finish.glsl", defines=cap)
        self.finish_init = load_compute(ctx, "pbgi_finish.glsl", defines={"STAGE_INIT": 1, **cap})
        self.pyramid = MipPyramid(ctx, alloc=lambda *a: self._alloc("texture", *a))
        self._bufs: dict = {}
        self._images: dict = {}
        self.passes_per_check = 4
        self.pairs_per_receiver = 8 if self.omega_tr_factor > 0 else 128

    # -- buffers -------------------------------------------------------------------------------
    # Buffers and images are reused while big enough, and reallocated when more than twice too
    # big, so a render with a small budget never keeps what a big one allocated.
    def _buf(self, name: str, nbytes: int):
        b = self._bufs.get(name)
        if b is None or b.size < nbytes or b.size > 2 * max(nbytes, 4096):
            if b is not None:
                b.release()
                self._bufs.pop(name)
            b = self._bufs[name] = self._alloc("buffer", max(int(nbytes), 16))
        return b

    def _image(self, name: str, n: int, record):
        """An image of >= n ``record`` texels (WIDTH per row), reused while large enough."""
        rows = image_rows(n)
        t = self._images.get(name)
        if t is None or t.size[1] < rows or t.size[1] > 2 * rows:
            if t is not None:
                t.release()
                self._images.pop(name)
            t = self._images[name] = self._alloc("texture", (WIDTH, rows),
                                                 record.texel_components, record.texture_dtype)
        return t

    def stream_bytes(self, budget_bytes: float) -> int:
        """The most bytes each of the two bounded streams (pair stack, second stream) may take."""
        floor = MIN_ITEMS * ITEM_BYTES
        return int(max(min(budget_bytes * self.stream_share, self.max_stream_bytes), floor))

    def capacities(self, count: int, budget_bytes: float) -> tuple[int, int]:
        """(stack pairs, second-stream items) for a batch of ``count`` receivers: a per-receiver
        estimate (``pairs_per_receiver``: Hybrid's 8 is ~3x what the demo views need at
        M = 32; Mipmapped's lists hold every accepted node, ~300-500 per receiver at M = 24, so
        its 128 means a few flushes per batch), capped by the budget. Too small never fails, it
        only costs passes (fewer pairs per pass, or children disabled) and flushes."""
        cap_bytes = self.stream_bytes(budget_bytes)
        est = self.pairs_per_receiver * max(count, 1)
        cap = int(min(max(est, MIN_STACK_PAIRS), max(cap_bytes // PAIR_BYTES, MIN_STACK_PAIRS)))
        s2 = int(min(max(est, MIN_ITEMS), max(cap_bytes // ITEM_BYTES, MIN_ITEMS)))
        return cap, s2

    def reserve_bytes(self, budget_bytes: float) -> int:
        """The most this finder allocates whatever the batch size (the renderer subtracts it
        from the budget before sizing micro-buffer batches): both streams at their cap, one
        image row of pyramid and list heads, the counters."""
        return (2 * self.stream_bytes(budget_bytes) + (PIXEL_BYTES + HEAD.nbytes) * WIDTH
                + PAIR_COUNTERS.nbytes + 16)

    def bytes_per_receiver(self, m: int) -> int:
        """Per-receiver memory besides its micro-buffer: state, pyramid (<= 4/3 pixels per
        receiver, PIXEL_BYTES each) and list heads."""
        return STATE_BYTES + 2 * (PIXEL_BYTES + HEAD.nbytes)

    # -- one batch -----------------------------------------------------------------------------
    def fill(self, batch: Batch) -> CutFigures:
        """Fill the micro-buffers (already emptied) of the batch's receivers."""
        receivers, first, count, m = batch.receivers, batch.first, batch.count, batch.m
        nodes, mb, cell_size = batch.nodes, batch.microbuffers, batch.cell_size
        if self.splat_budget < entries(m):
            raise ValueError("splat budget must cover one whole micro-buffer")
        ctx = self.ctx
        t_start = time.perf_counter()
        pixels = RECEIVER.view(receivers.read(size=RECEIVER.nbytes * count,
                                              offset=RECEIVER.nbytes * first))["pixel"]
        topo = self.pyramid.build(receivers, first, z_order(pixels, int(batch.width)))
        n_pix = topo.n_pixels

        cap, s2_cap = self.capacities(count, batch.budget_bytes)
        kmax = max(cap // 5, 1)
        pairs = self._image("pairs", cap, PAIR)
        items = self._image("items", s2_cap, ITEM)
        heads = self._image("heads", n_pix, HEAD)
        state = self._buf("state", STATE_BYTES * count)
        counters = self._buf("counters", 4 * COUNTER_WORDS)
        remaining = self._buf("remaining", 4)
        nil_rows = np.full((image_rows(n_pix) * WIDTH,), NIL, np.uint32).tobytes()
        heads.write(nil_rows, viewport=(0, 0, WIDTH, image_rows(n_pix)))
        state.clear(size=STATE_BYTES * count)
        top = topo.top
        first_pairs = PAIR.zeros(len(top))             # (root, every top pixel)
        first_pairs["pixel"] = top
        first_pairs = to_rows(PAIR.flat(first_pairs), PAIR.words)
        pairs.write(first_pairs.tobytes(), viewport=(0, 0, WIDTH, len(first_pairs) // WIDTH))
        c0 = np.zeros(COUNTER_WORDS, dtype=np.uint32)
        c0[C_STACK] = len(top)
        c0[C_KMAX], c0[C_CAP], c0[C_S2_CAP] = kmax, cap, s2_cap
        counters.write(c0.tobytes())

        om = omega_micro(m)
        omega_stop = self.stop_factor * om
        omega_h = omega_horizon(m, self.stop_factor)
        inv_cell = 1.0 / max(cell_size, 1e-9) ** 2
        receivers.bind_to_storage_buffer(SSBO.RECEIVERS)
        counters.bind_to_storage_buffer(SSBO.COUNTERS)
        nodes.use()
        mb.bind()
        pairs.bind_to_image(IMAGE.PAIRS, read=True, write=True)
        items.bind_to_image(IMAGE.ITEMS, read=True, write=True)
        heads.bind_to_image(IMAGE.HEADS, read=True, write=True)
        self.pyramid.bind()
        _set(self.refine, u_first=first, u_m=m, u_omega_stop=omega_stop,
             u_omega_horizon=omega_h, u_omega_tr=self.omega_tr_factor * om,
             u_pixel_factor=self.pixel_factor, u_cull_margin=self.cull_margin)
        _set(self.finish, u_first=first, u_count=count, u_m=m, u_omega_stop=omega_stop,
             u_omega_horizon=omega_h, u_steps=self.steps, u_splat_budget=self.splat_budget,
             u_inv_cell_area=inv_cell)
        for prog in (self.refine, self.finish):
            set_frame_uniforms(prog, batch.seed_tile, batch.pass_index, batch.turned_frames)
        nodes.set_uniforms(self.finish)
        self.finish_init["u_count"] = int(topo.offsets[1])

        ctx.finish()
        t_pyr = time.perf_counter()
        t_fin = 0.0
        passes = flushes = finish_rounds = peak_s2 = 0
        complete = True
        while True:
            # a few passes between read-backs: the GPU sizes each dispatch itself (indirect), a
            # pass over an empty stack costs four empty dispatches, and PREPARE never pops more
            # than the second stream can take, so nothing can overflow in between
            for _ in range(self.passes_per_check):
                self.prepare.run(1)
                ctx.memory_barrier()
                self.refine.run_indirect(counters, 4 * C_REFINE_ARGS)
                ctx.memory_barrier()
                self.fixup.run(1)
                ctx.memory_barrier()
                self.move.run_indirect(counters, 4 * C_MOVE_ARGS)
                ctx.memory_barrier()
            passes += self.passes_per_check
            c = np.frombuffer(counters.read(), dtype=np.uint32)
            stack, s2 = int(c[C_STACK]), int(c[C_S2])
            if stack and 2 * s2 < s2_cap and passes < self.max_rounds:
                continue
            peak_s2 = max(peak_s2, min(s2, s2_cap))
            if s2:                            # finish (and empty) the second stream
                tf = time.perf_counter()
                rounds, ok = self._finish(state, remaining, count, topo)
                t_fin += time.perf_counter() - tf
                finish_rounds += rounds
                complete &= ok
                flushes += 1
                heads.write(nil_rows, viewport=(0, 0, WIDTH, image_rows(n_pix)))
                counters.write(np.zeros(1, np.uint32).tobytes(), offset=4 * C_S2)
                counters.bind_to_storage_buffer(SSBO.COUNTERS)
            if not stack:
                break
            if passes >= self.max_rounds:
                complete = False
                break

        c = np.frombuffer(counters.read(), dtype=np.uint32).copy()
        t_end = time.perf_counter()
        st = FINISH_STATE.view(state.read(size=STATE_BYTES * count))
        walk = st["visited"].astype(np.int64)
        done = ((st["flags"] & WALK_DONE) != 0) | (flushes == 0)
        done &= complete
        processed = int(c[C_PROCESSED])
        share = processed / max(count, 1)
        peak_used = (int(c[C_PEAK_STACK]) * PAIR_BYTES + peak_s2 * ITEM_BYTES
                     + (PIXEL_BYTES + HEAD.nbytes) * n_pix + STATE_BYTES * count)
        return CutFigures(
            visited=walk + int(round(share)), done=done, tests=st["tests"].astype(np.int64),
            rounds=int(c[C_PASSES]) + finish_rounds,
            cut_short=int(((st["flags"] & WALK_CUT_SHORT) != 0).sum()), nbytes=self.nbytes,
            pairs=PairFigures(
                refine_passes=int(c[C_PASSES]), finish_rounds=finish_rounds, flushes=flushes,
                pairs_processed=processed, node_refines=int(c[C_NODE_REFINES]),
                pixel_splits=int(c[C_PIXEL_SPLITS]), culled_shared=int(c[C_CULLED]),
                stream2_items=int(c[C_TO_S2]), decided_shared=int(c[C_ACCEPTED]),
                pushed_back=int(c[C_PUSHED_BACK]), disabled_passes=int(c[C_DISABLED_PASSES]),
                pyramid_pixels=n_pix, walk_visited=int(walk.sum()),
                ms_pyramid=(t_pyr - t_start) * 1e3, ms_finish=t_fin * 1e3,
                ms_refine=(t_end - t_pyr - t_fin) * 1e3,
                peak_stack_pairs=int(c[C_PEAK_STACK]), peak_stream2_items=peak_s2,
                stack_capacity=cap, stream2_capacity=s2_cap, pyramid_levels=topo.levels,
                mb_extra_used=peak_used / 2**20))

    def _finish(self, state, remaining, count: int, topo) -> tuple[int, bool]:
        """Run the finishing walk until every receiver has walked all its lists."""
        ctx = self.ctx
        state.bind_to_storage_buffer(SSBO.WALK_STATE)
        remaining.bind_to_storage_buffer(SSBO.COUNTERS)
        n0 = int(topo.offsets[1])
        self.finish_init.run(dispatch_groups(n0))
        ctx.memory_barrier()
        groups = dispatch_groups(count)
        rounds, left = 0, count
        while left and rounds < self.max_rounds:
            remaining.write(b"\0\0\0\0")
            self.finish.run(groups)
            ctx.memory_barrier()
            left = int(np.frombuffer(remaining.read(), np.uint32)[0])
            rounds += 1
        return rounds, left == 0

    @property
    def nbytes(self) -> int:
        tex = sum(t.size[0] * t.size[1] * t.components * 4 for t in self._images.values())
        return sum(b.size for b in self._bufs.values()) + tex + self.pyramid.nbytes

    def release(self) -> None:
        for b in list(self._bufs.values()) + list(self._images.values()):
            b.release()
        self._bufs.clear()
        self._images.clear()
        self.pyramid.release()


class MipmappedCut(PairRefiner):
    """Mipmapped PBGI's cut finder: every pair is refined in parallel down to the cut."""

    def __init__(self, ctx, **kw):
        super().__init__(ctx, omega_tr_factor=0.0, **kw)


class MipmappedMode(MicroBufferMode):
    """Mipmapped PBGI: walks shared through the G-buffer pyramid."""

    name = "mipmapped"

    def __init__(self, ctx, params: RenderParams, defines: dict | None = None):
        self.stop_factor = float(params.stop_factor)
        super().__init__(ctx, params, MipmappedCut(ctx, stop_factor=self.stop_factor,
                                                   defines=defines))

    def fits(self, params: RenderParams) -> bool:
        return float(params.stop_factor) == self.stop_factor
