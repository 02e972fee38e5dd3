"""What a render mode is - the interface every mode implements, what the Relighter hands it, what
it gives back - modelled on pbrt-v4's ``src/pbrt/base/*.h`` (the interface; the closed list of
variants and ``Create(name, params)`` are app/pbgi/modes.py).

A render (app/pbgi/renderer.py): G-buffer -> receivers (object pixels, Z-ordered) ->
``mode.render(frame, stats)`` lights them into ``frame.output`` -> image. The Relighter keeps one
object per mode and makes a new one when ``mode.fits(params)`` says a parameter fixed at
construction changed.

* ``RenderMode``: the interface. ``render`` gets a ``Frame`` (the tile's receivers, materials,
  output, node textures, micro-buffers, gather, camera, parameters), fills its part of the
  ``RenderStats`` and returns the GPU bytes it used besides the G-buffer.
* ``MicroBufferMode``: the three PBGI modes (classic, mipmapped, hybrid). They differ only in
  their ``CutFinder``, which fills the micro-buffers of one batch of receivers and reports
  ``CutFigures``; the batching is here: batches sized from the memory budget, the micro-buffers
  emptied (unless the finder writes every entry itself), the cut, the shared gather. GL refusing
  memory (``AllocationError``, or MemoryError / moderngl.Error from a plain allocation) halves
  the batch. When the micro-buffers still hold this render's cut (a material-only edit: same
  cloud, asset, camera, tile, size, mode, parameters and normal maps, all receivers in one
  batch), only the gather runs.
* The environment map (app/pbgi/envmap.py) implements ``render`` directly: the same gather, lit
  by a cube map instead of micro-buffers.
"""

from __future__ import annotations

import logging
import time
from abc import ABC, abstractmethod
from dataclasses import dataclass, replace
from typing import Any, Callable, ClassVar

import moderngl
import numpy as np

from app.errors import ScanlightError
from app.params import RENDER_KEYS, param_record
from app.pbgi.gather import Gather
from app.pbgi.lobe import bytes_per_receiver as lobe_bytes_per_receiver
from app.pbgi.microbuffer import MicroBuffers, batch_size, bytes_per_receiver
from app.pbgi.nodetex import NodeTextures
from app.pbgi.stats import MB, PairFigures, RenderStats, ShareFigures

log = logging.getLogger(__name__)


class AllocationError(RuntimeError):
    """GL refused memory (a buffer or texture): the renderer halves the batch and retries."""


# what the batching answers by halving the batch; anything else is a real error
REFUSED = (AllocationError, MemoryError, moderngl.Error)


@param_record(*RENDER_KEYS)
class RenderParams:
    """What one render takes: the ``pbgi.*`` rows of app/params.py named in RENDER_KEYS, with
    the table's defaults and ranges. ``validated()`` returns a checked copy or raises
    ScanlightError.
    """


@dataclass
class HeldCut:
    """The Relighter's micro-buffers and the cut they hold, which the next render may reuse."""
    buffers: MicroBuffers
    key: tuple | None = None          # Frame.cut_key of the render that filled them; None: none
    figures: CutSummary | None = None  # that render's cut figures
    frames: Any = None                # that render's CutFigures.frames


@dataclass
class Layer:
    """The whole layer a tile belongs to (the viewer's refinement: one pass of tiles, each a
    render call of its own): its receivers, from one G-buffer, so that a cut finder can choose
    what its receivers share over all of them (Hybrid's blocks, app/pbgi/farfield.py) and keep
    it for the next tile - a tile's edge is then no edge of the picture."""
    key: tuple                        # what the shared work depends on: the view, the scene,
                                      # the receivers' geometry (not their materials)
    width: int                        # the layer's width (pixels are row-major in the layer)
    receivers: np.ndarray             # (L,) RECEIVER records of the layer, in image order
    rows: np.ndarray                  # (count,) per frame receiver, its row in ``receivers``
    coarse: np.ndarray | None = None  # (L,) lobe-only receivers: a group of their own (None)

    def group_of(self, rows: np.ndarray) -> tuple:
        """(tag, members) of a frame group whose receivers are layer ``rows``: the layer's
        receivers of the same kind (lobe-only or not; the renderer never mixes them in a
        group), sorted."""
        if self.coarse is None or not len(rows):
            return None, np.arange(len(self.receivers))
        tag = bool(self.coarse[rows[0]])
        return tag, np.flatnonzero(self.coarse == tag)


@dataclass
class Frame:
    """What the Relighter hands a mode: one tile's receivers and everything they are lit from."""
    params: RenderParams              # this render's (validated)
    receivers: Any                    # SSBO: ``count`` 64-byte receiver records, in Z-order
    materials: Any                    # SSBO: the material table (app.pbgi.gbuffer)
    output: Any                       # SSBO: a vec4 per tile pixel, written by the gather
    count: int                        # receivers
    tile: tuple[int, int, int, int]   # (x0, y0, w, h); receivers carry row-major tile pixels
    camera_rel: np.ndarray            # camera position relative to the BSH origin
    nodes: NodeTextures               # the BSH as textures
    cell_size: float                  # the BSH's leaf cell size
    gather: Gather                    # the final gather every mode shares
    microbuffers: HeldCut             # the micro-buffers and what they hold
    cut_key: tuple                    # identifies the cut this render needs (reuse)
    environment: Callable[[int], Any]  # face size -> the room as an EnvironmentMap from the
                                       # asset centre (built once per cloud, asset and size)
    lobe: Any = None                  # LobeSettings when a receiver may be glossy (app/pbgi/lobe.py)
    lobe_buffers: Any = None          # the Relighter's LobeBuffers (filled per batch)
    leaf_radius: float = 0.0          # the scan's surface disc radius (lobe.surface_radius)
    irradiance: bool = False          # gather E / pi (white Lambertian), not the material
    absent_features: tuple = ()       # BRDF features no material uses (gather.absent_features):
                                      # the gather's variant leaves their code out
    pass_index: int = 0               # the render's pass (Hybrid moves its block grid per pass)
    parts: Any = None                 # SSBO of GATHER_PARTS per tile pixel for the gather, or None
    groups: tuple = ()                # ((start, count, m), ...): consecutive runs of receivers
                                      # with their own micro-buffer size (renderer: lobe-only
                                      # receivers); empty = all ``count`` at ``m``
    layer: Layer | None = None        # the layer the tile belongs to (the viewer), or None
    seed_tile: tuple = (0, 0, 1, 1)   # (tile x0, y0, tile width, image width): a receiver's
                                      # pixel in the image, which seeds its frame's turn
    turned_frames: bool = True        # turn the receivers' frames (microbuffer.set_frame_uniforms)

    @property
    def m(self) -> int:
        return int(self.params.microbuffer)

    def receiver_groups(self) -> tuple:
        return self.groups or ((0, self.count, self.m),)


@dataclass
class Batch:
    """One batch of receivers for a cut finder: rows 0 .. count - 1 of ``microbuffers`` are
    receivers ``first`` .. ``first + count - 1``."""
    microbuffers: MicroBuffers
    receivers: Any                    # SSBO of the tile's receiver records
    first: int
    count: int
    m: int                            # micro-buffer resolution
    nodes: NodeTextures
    cell_size: float
    width: int = 1                    # tile width (the pixel index of a receiver is row-major)
    budget_bytes: float = 1 << 30     # what the finder's own buffers may take
    pass_index: int = 0               # the render's pass
    environment: Any = None           # Frame.environment (Hybrid's block levels), or None
    gather: Any = None                # Frame.gather (the same: the blocks' irradiance), or None
    seed_tile: tuple = (0, 0, 1, 1)   # Frame.seed_tile (microbuffer.set_frame_uniforms)
    turned_frames: bool = True        # Frame.turned_frames


@dataclass
class CutFigures:
    """What a cut finder reports for one batch."""
    visited: np.ndarray               # (count,) BSH nodes each receiver's walk visited
    done: np.ndarray                  # (count,) bool: its walk completed
    tests: np.ndarray                 # (count,) micro-buffer entry tests of its rasteriser
    rounds: int                       # dispatch rounds (passes) the batch took
    cut_short: int                    # receivers whose accepted-node list overflowed
    nbytes: int                       # the finder's own GPU memory as allocated for it
    frames: Any = None                # far-field sharing: per receiver the normal (vec4 SSBO)
                                      # of its micro-buffer's frame; None: its own normal
    pairs: PairFigures | None = None
    share: ShareFigures | None = None


@dataclass
class CutSummary:
    """A render's cut figures: its batches' combined (what RenderStats shows)."""
    nodes_visited: float
    nodes_visited_max: int
    incomplete_receivers: int
    rounds: int
    cut_short: int
    splat_tests: float
    mb_extra: float                   # the largest batch's CutFigures.nbytes, in MB
    pairs: PairFigures | None
    share: ShareFigures | None

    @staticmethod
    def of(batches: list[CutFigures]) -> CutSummary:
        visited = np.concatenate([b.visited for b in batches])
        done = np.concatenate([b.done for b in batches])
        return CutSummary(
            nodes_visited=float(visited.mean()), nodes_visited_max=int(visited.max()),
            incomplete_receivers=int((~done).sum()), rounds=int(sum(b.rounds for b in batches)),
            cut_short=int(sum(b.cut_short for b in batches)),
            splat_tests=float(np.concatenate([b.tests for b in batches]).mean()),
            mb_extra=max(b.nbytes for b in batches) / MB,
            pairs=PairFigures.total([b.pairs for b in batches]),
            share=ShareFigures.total([b.share for b in batches]))

    def apply(self, stats: RenderStats) -> None:
        stats.nodes_visited = self.nodes_visited
        stats.nodes_visited_max = self.nodes_visited_max
        stats.incomplete_receivers = self.incomplete_receivers
        stats.rounds = self.rounds
        stats.cut_short = self.cut_short
        stats.splat_tests = self.splat_tests
        stats.mb_extra = self.mb_extra
        stats.pairs = self.pairs
        stats.share = self.share


class RenderMode(ABC):
    """A way to light the receivers of a tile. Subclasses set ``name`` (its key in
    app.pbgi.modes.MODES) and implement every abstract member."""

    name: ClassVar[str]

    def __init__(self, ctx, params: RenderParams, defines: dict | None = None):
        """``defines``: added to every walk program the mode compiles (None in a render; the
        profile's gpu_layout.WALK_ONLY)."""
        self.ctx = ctx

    @abstractmethod
    def fits(self, params: RenderParams) -> bool:
        """Can this object render with ``params``? False when one of them was fixed at
        construction and changed: the Relighter then releases it and creates another."""

    @abstractmethod
    def render(self, frame: Frame, stats: RenderStats) -> int:
        """Light ``frame.count`` receivers into ``frame.output``; fill this mode's fields of
        ``stats`` (batches, times, cut figures); return the GPU bytes used besides the
        G-buffer's (buffers held by the mode or the Relighter for it)."""

    @abstractmethod
    def release(self) -> None:
        """Free the GL objects the mode holds."""


class CutFinder(ABC):
    """Fills the micro-buffers of one batch of receivers with their cuts: what distinguishes
    the micro-buffer modes (app/pbgi/classic.py, mipmapped.py, farfield.py)."""

    clears_microbuffers: ClassVar[bool]
    """True: ``fill`` writes every entry of its rows, so they need not be emptied first (every
    finder declares it)."""

    @abstractmethod
    def fill(self, batch: Batch) -> CutFigures:
        """Find the cut of every receiver of the batch and rasterise it into its micro-buffer
        (emptied beforehand unless ``clears_microbuffers``). GL refusing memory raises
        AllocationError (or moderngl.Error / MemoryError)."""

    @abstractmethod
    def bytes_per_receiver(self, m: int) -> int:
        """GPU bytes per receiver of a batch besides its micro-buffer (batch sizing)."""

    @abstractmethod
    def reserve_bytes(self, budget_bytes: float) -> int:
        """GPU bytes taken whatever the batch size (subtracted from the budget first)."""

    def begin_group(self, frame: Frame, first: int, count: int, m: int) -> None:
        """Receivers ``first`` .. ``first + count - 1`` of ``frame`` are about to be filled in
        one or more batches at size ``m``: a finder whose result for a receiver depends on its
        neighbours (Hybrid's blocks) decides it here for the whole group, so that where the
        memory budget splits the group does not show in the image - or, for a tile of a layer
        (``frame.layer``), for the whole layer, kept for its next tiles. Default: nothing."""

    @abstractmethod
    def release(self) -> None:
        """Free the GL objects the finder holds."""


class MicroBufferMode(RenderMode):
    """A PBGI mode: per batch of receivers, ``self.cut`` fills their micro-buffers, then the
    gather reads them (see the module docstring). Subclasses pass their CutFinder."""

    def __init__(self, ctx, params: RenderParams, cut: CutFinder):
        super().__init__(ctx, params)     # the cut finder was made with the mode's defines
        self.cut = cut

    def render(self, frame: Frame, stats: RenderStats) -> int:
        """Every receiver group in turn (Frame.groups), each in batches at its own M. Only a
        frame of one group and one batch leaves its cut in the held micro-buffers for the next
        render to reuse."""
        groups = frame.receiver_groups()
        held = frame.microbuffers
        reuse = len(groups) == 1 and held.key == frame.cut_key
        batches: list[CutFigures] = []
        extra = 0
        t_cut = t_gather = 0.0
        per = halvings = 0
        for start, n, m in groups:
            one = self._render_group(frame, stats, start, n, m, reuse, batches)
            if one is None:            # the held cut did not fit one batch: walk after all
                reuse = False
                one = self._render_group(frame, stats, start, n, m, False, batches)
            group_extra, per_g, halvings_g, tc, tg = one
            extra = max(extra, group_extra)
            per, halvings = max(per, per_g), halvings + halvings_g
            t_cut, t_gather = t_cut + tc, t_gather + tg
        if reuse:
            stats.reused_microbuffers = True
        else:
            held.figures = CutSummary.of(batches)
            held.key = (frame.cut_key if len(groups) == 1 and per >= frame.count
                        and not halvings else None)
            held.frames = batches[-1].frames
        held.figures.apply(stats)
        stats.ms_cut, stats.ms_gather = t_cut * 1e3, t_gather * 1e3
        stats.batch_receivers, stats.tile_halvings = per, halvings
        stats.mb_microbuffers = held.buffers.nbytes / MB
        stats.mb_extra_bound = extra / MB
        return held.buffers.nbytes + extra

    def _render_group(self, frame: Frame, stats: RenderStats, start: int, n: int, m: int,
                      reuse: bool, batches: list):
        """Receivers start .. start + n - 1 at micro-buffer size m, batch by batch: cut, lobe
        buffers, gather. Returns (extra bytes, batch size, halvings, cut s, gather s), or None
        when ``reuse`` was asked but the group needs more than one batch."""
        ctx, cut, held = self.ctx, self.cut, frame.microbuffers
        state_per = int(cut.bytes_per_receiver(m))
        budget = frame.params.memory_budget_mb * MB
        reserve = int(cut.reserve_bytes(budget))
        mb_per = bytes_per_receiver(m) + lobe_bytes_per_receiver(frame.lobe)
        per = batch_size(m, max(budget - reserve, 0.0) * mb_per / (mb_per + state_per),
                         int(ctx.info.get("GL_MAX_TEXTURE_SIZE", 16384)), n)
        if reuse and per < n:
            return None
        # the finder's share of the budget, from the first batch size (kept when halving)
        cut_budget = max(budget - mb_per * per, 0.0)
        if not reuse:
            cut.begin_group(frame, start, n, m)
        halvings, first, end = 0, start, start + n
        t_cut = t_gather = 0.0
        # the lobe domain's floor follows this group's cosine micro-buffer (LobeSettings.cosine_m)
        lobe = None if frame.lobe is None else replace(frame.lobe, cosine_m=m)
        while first < end:
            count = min(per, end - first)
            ctx.finish()
            tc = time.perf_counter()
            if not reuse:
                held.key = None
                try:
                    held.buffers.prepare(m, per, 0 if cut.clears_microbuffers else count)
                    batches.append(cut.fill(Batch(
                        held.buffers, frame.receivers, first, count, m, frame.nodes,
                        frame.cell_size, width=frame.tile[2], budget_bytes=cut_budget,
                        pass_index=frame.pass_index, environment=frame.environment,
                        gather=frame.gather, seed_tile=frame.seed_tile,
                        turned_frames=frame.turned_frames)))
                except REFUSED as exc:
                    if per <= 1:
                        raise ScanlightError(None, f"out of GPU memory even for one receiver "
                                                   f"({exc})") from None
                    per, halvings = max(1, per // 2), halvings + 1
                    held.buffers.release()
                    log.warning("GPU memory refused (%s): batch halved to %d receivers", exc, per)
                    continue
                ctx.finish()
            tl = time.perf_counter()
            if lobe is not None:
                lobe_figures = frame.lobe_buffers.fill(
                    lobe, frame.receivers, frame.materials, first, count, per, frame.nodes,
                    frame.cell_size, frame.camera_rel, frame.leaf_radius,
                    absent=frame.absent_features)
                ctx.finish()
                stats.ms_lobe += (time.perf_counter() - tl) * 1e3
                stats.lobe_incomplete += lobe_figures["incomplete"]
                share = count / max(frame.count, 1)   # batch means -> means over all receivers
                stats.lobe_visited += lobe_figures["visited"] * share
                stats.lobe_tests += lobe_figures["tests"] * share
            tg = time.perf_counter()
            frames = held.frames if reuse else batches[-1].frames
            frame.gather.run(frame.receivers, frame.materials, frame.output, first, count, m,
                             frame.camera_rel, mb=held.buffers, nodes=frame.nodes, frames=frames,
                             lobe=lobe, lobe_buffers=frame.lobe_buffers,
                             irradiance=frame.irradiance, absent=frame.absent_features,
                             parts=frame.parts, seed_tile=frame.seed_tile,
                             pass_index=frame.pass_index, turned=frame.turned_frames)
            ctx.finish()
            t_gather += time.perf_counter() - tg
            t_cut += tl - tc
            stats.batches += 1
            first += count
        return reserve + state_per * per, per, halvings, t_cut, t_gather

    def release(self) -> None:
        self.cut.release()
