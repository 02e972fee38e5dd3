"""What a render reports: ``RenderStats``, the one typed record the CLI's ``--stats`` JSON, the
benchmarks (app/bench/table3.py, classic.py) and the viewer (PBGI panel, stats box) read.

Every mode fills the common fields; the micro-buffer modes (classic, mipmapped, hybrid) also the
batching and cut fields, which stay None for the environment map; the pair engine (Mipmapped, the
exact Hybrid) and the far-field sharing (the default Hybrid) add their own figures object.
``to_dict()`` flattens it all into the JSON keys ``scanlight render --stats`` has always written
(fields that do not apply to the mode are left out).

A figures object is per batch as a cut finder reports it and per render in the stats: summed
over the batches, except the fields marked ``peak`` (the largest batch's).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

MB = 1024.0 * 1024.0


def peak(default=0):
    """A figures field that combines over batches as the largest value, not the sum."""
    return field(default=default, metadata={"peak": True})


class Figures:
    """Base of the per-mode figures dataclasses: combine, flatten."""

    def __add__(self, other):
        """This batch's figures combined with another's (sum; peaks: max)."""
        return type(self)(**{f.name: (max(getattr(self, f.name), getattr(other, f.name))
                                      if f.metadata.get("peak") else
                                      getattr(self, f.name) + getattr(other, f.name))
                             for f in fields(self)})

    @classmethod
    def total(cls, items: list):
        """The render's figures from its batches' (None when no batch had any)."""
        items = [i for i in items if i is not None]
        if not items:
            return None
        out = items[0]
        for i in items[1:]:
            out = out + i
        return out

    def to_dict(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}


@dataclass
class PairFigures(Figures):
    """The (node, pixel) pair engine of Mipmapped and the exact Hybrid (app/pbgi/mipmapped.py)."""
    refine_passes: int = 0            # refinement passes (4 dispatches each)
    finish_rounds: int = 0            # dispatch rounds of the finishing walks
    flushes: int = 0                  # times the second stream was finished and emptied
    pairs_processed: int = 0          # (node, pixel) pairs the passes refined
    node_refines: int = 0             # pairs replaced by the node's children
    pixel_splits: int = 0             # pairs replaced by the pixel's children
    culled_shared: int = 0            # pairs culled for every receiver below the pixel
    stream2_items: int = 0            # sub-trees handed to the finishing walk
    decided_shared: int = 0           # nodes accepted for every receiver below the pixel
    pushed_back: int = 0              # pairs put back on a full stack
    disabled_passes: int = 0          # passes run with children disabled (stack short)
    pyramid_pixels: int = 0           # pixels of the G-buffer pyramids
    walk_visited: int = 0             # nodes the finishing walks visited, all receivers
    ms_pyramid: float = 0.0           # building the pyramid
    ms_finish: float = 0.0            # the finishing walks
    ms_refine: float = 0.0            # the refinement passes
    peak_stack_pairs: int = peak()    # most pairs on the stack at once
    peak_stream2_items: int = peak()  # most items in the second stream at once
    stack_capacity: int = peak()      # pairs the stack could hold
    stream2_capacity: int = peak()    # items the second stream could hold
    pyramid_levels: int = peak()      # levels of the G-buffer pyramid
    mb_extra_used: float = peak(0.0)  # the part of the streams, pyramid and state filled (MB)


@dataclass
class ShareFigures(Figures):
    """Hybrid's far-field sharing (app/pbgi/farfield.py)."""
    share_blocks: int = 0             # blocks of receivers that walked the far field once
    share_chunks: int = 0             # chunks the block walks were split into (memory bound)
    share_receivers: int = 0          # receivers that took a block's far field
    share_block_visits: int = 0       # nodes the far-field walks visited, all blocks
    ms_share_blocks: float = 0.0      # choosing the blocks (CPU)
    ms_share_chosen_before: float = 0.0   # of ms_share_blocks: chosen before the cut's timer
                                      # started (CutFinder.begin_group: in ms, not in ms_cut)
    ms_share_far: float = 0.0         # the far-field walks and copies
    ms_share_merge: float = 0.0       # of ms_share_far: the copies into the receivers' rows
    ms_share_near: float = 0.0        # the per-receiver near-field walks
    ms_share_levels: float = 0.0      # the blocks' far-field and cube-map irradiance, the fit
    share_levelled: int = 0           # blocks whose level is not 1 (app/pbgi/block_levels.py)
    share_block_max: int = peak()     # receivers in the largest block


@dataclass
class RenderStats:
    """One render of one tile (``Relighter.render``). Times in ms, memory in MB (2^20 bytes)."""
    # -- every mode
    mode: str                         # the render mode (app.params.RENDER_MODES)
    microbuffer: int                  # M: micro-pixels per side of a micro-buffer
    width: int                        # tile width (px)
    height: int                       # tile height (px)
    tile: tuple[int, int, int, int]   # (x0, y0, w, h) of the tile in the image
    receivers: int                    # object pixels of the tile (the gather's receivers)
    nodes: int                        # BSH nodes
    bsh_mb: float                     # the BSH's records plus its node textures
    micropixels: int                  # receivers x M^2
    entries: int                      # receivers x micro-buffer entries (rim bands included)
    batches: int = 0                  # batches of receivers gathered
    rounds: int = 0                   # dispatch rounds of the cut finder, all batches
    nodes_visited: float = 0.0        # BSH nodes a receiver's walk visited, mean
    completed: bool = True            # every walk and gather finished, no non-finite pixel
    reused_microbuffers: bool = False  # only the gather ran (the previous render's cut)
    ms_gbuffer: float = 0.0           # G-buffer and receiver list
    ms_cut: float = 0.0               # finding the cuts into the micro-buffers
    ms_gather: float = 0.0            # the final gather
    ms_lobe: float = 0.0              # the glossy receivers' lobe micro-buffers (app/pbgi/lobe.py)
    lobe_receivers: bool = False      # lobe micro-buffers were used (a glossy material)
    lobe_incomplete: int = 0          # receivers whose lobe walk did not complete
    lobe_visited: float = 0.0         # BSH nodes a receiver's lobe walk visited, mean
    lobe_tests: float = 0.0           # lobe micro-pixel ray tests per receiver, mean
    coarse_receivers: int = 0         # receivers whose light is all in the lobe buffers: their
    coarse_microbuffer: int = 0       # cosine micro-buffer is this M (pbgi.lobe_only_microbuffer)
    asset_surfels: int = 0            # the asset's surfels in the tree (0: the room's alone)
    asset_bounces: int = 0            # bounces they carry (diffuse, or glossy for a metal)
    ms_asset: float = 0.0             # building the asset's surfel tree and bounce when this
                                      # render did it (cached otherwise), outside ``ms``
    mb_asset: float = 0.0             # the joined tree's records and node textures
    asset_convex_skipped: bool = False  # asset occlusion was on, but the asset is convex: its
                                      # surfels were left out (Relighter.walks_asset)
    ms: float = 0.0                   # the whole render (every pass)
    passes: int = 1                   # passes averaged (Relighter.render_passes)
    envmap_instead_of: str | None = None  # the mode asked for when the environment map took the
                                      # frame (app/pbgi/nearfield.py: the asset is far from all)
    clearance: float | None = None    # the asset's clearance in radii (when it was looked at)
    edge_pixels: int = 0              # silhouette pixels sampled edge_samples times (render)
    edge_samples: int = 1             # samples of those pixels (the others: passes)
    hdri: str | None = None           # the HDRI that lit the asset instead of the scan (its file)
    absent_features: tuple = ()       # BRDF features the gather variant left out (no material
                                      # uses them; pbgi.shader_variants)
    render_scale: float = 1.0         # GI rendered at this fraction of the output resolution
    out_width: int | None = None      # the output's size when render_scale < 1 (width/height:
    out_height: int | None = None     # the low-resolution render's)
    ms_upsample: float = 0.0          # the guide G-buffers and the upsampling (inside ``ms``)
    upsample_unfilled: int = 0        # asset pixels no low-resolution sample reached (black)
    mb: float = 0.0                   # GPU memory: the larger of the G-buffer and the rest
    nonfinite_pixels: int = 0         # pixels that came out NaN or Inf (set to 0)
    gather_cut_short: int = 0         # pixels whose gather stopped early
    # -- the micro-buffer modes (classic, mipmapped, hybrid); None for the environment map
    nodes_visited_max: int | None = None      # the most BSH nodes one receiver's walk visited
    incomplete_receivers: int | None = None   # receivers whose walk did not complete
    cut_short: int | None = None              # receivers whose cut list overflowed
    splat_tests: float | None = None          # micro-buffer entry tests per receiver, mean
    batch_receivers: int | None = None        # receivers per batch (after halvings)
    tile_halvings: int | None = None          # times GL refused memory and the batch halved
    mb_microbuffers: float | None = None      # the micro-buffers
    mb_extra: float | None = None             # the cut finder's own memory as allocated, its
                                              # largest batch (Table 3's "extra memory")
    mb_extra_bound: float | None = None       # what the batch sizing set aside for it
    pairs: PairFigures | None = None          # Mipmapped, exact Hybrid
    share: ShareFigures | None = None         # Hybrid's far-field sharing
    # -- the environment map
    envmap_face: int | None = None            # cube-map face size (px)

    def to_dict(self) -> dict:
        """The ``--stats`` JSON: flat, the figures objects' fields inline, None left out."""
        out = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if v is None:
                continue
            if isinstance(v, Figures):
                out.update(v.to_dict())
            elif isinstance(v, tuple):
                out[f.name] = list(v)
            else:
                out[f.name] = v
        return out
