"""Hybrid PBGI (paper Section 5.2.2), in two variants behind one mode, chosen by the parallax
tolerance.

Default - far-field sharing (app/pbgi/farfield.py, ``parallax_tolerance`` = eps > 0): the walk
is shared where its *result* is the same for neighbouring receivers. Blocks of up to 8 x 8
receivers with normals within 0.1 rad walk and rasterise the far field (nodes farther than
D = block radius / (eps x 2 / M): they move by < eps micro-pixels across the block) once; each
receiver walks the near field into a copy. This is what makes Hybrid faster than Classic on
llvmpipe, where the exact variant below does about as much work per receiver as Classic.

``parallax_tolerance`` = 0 - the paper's exact Hybrid: refine (node, pixel) pairs in parallel
only while the node is large, Omega(A) > Omega_tr = omega_tr_factor * Omega (Omega = 2 pi / M^2,
eq. 5), and the pixel is not at the finest level; every other pair becomes an item of the second
stream, which a per-receiver depth-first walk with Classic's rules finishes (the engine is
app.pbgi.mipmapped.PairRefiner, the walk shaders/pbgi_finish.glsl with lib/pbgi_cut.glsl, the
same decision and rasteriser code as Classic).

Same cut as Classic (exact variant): the parallel phase only ever (a) culls a node that every
receiver below the pixel would cull, (b) replaces a node by its children where every receiver
below would descend (or cull it, and then its children too: their spheres and cones lie inside
its own), and (c) hands the rest to the finishing walk, which applies Classic's rules per
receiver. So the cut - and with the deterministic tie-break of the micro-buffer write, every
micro-buffer entry - is the one Classic finds, up to float rounding exactly at a cull threshold
(tests/pbgi/test_pbgi_modes.py compares the micro-buffers entry by entry and finds them
identical).
"""

from __future__ import annotations

from app.pbgi.farfield import FarFieldShare
from app.pbgi.mipmapped import PairRefiner
from app.pbgi.modebase import MicroBufferMode, RenderParams


class HybridMode(MicroBufferMode):
    """Hybrid PBGI. ``parallax_tolerance`` > 0: far-field sharing (FarFieldShare) - the far
    field walked once per block of receivers, the near field per receiver; 0: the paper's exact
    Hybrid (PairRefiner: parallel refinement above Omega_tr, per-receiver walks below; the same
    cut as Classic). Both, and the node stop factor, are fixed at construction."""

    name = "hybrid"

    def __init__(self, ctx, params: RenderParams, defines: dict | None = None):
        self.omega_tr_factor = float(params.omega_tr_factor)
        self.parallax_tolerance = float(params.parallax_tolerance)
        self.stop_factor = float(params.stop_factor)
        if self.parallax_tolerance > 0:
            cut = FarFieldShare(ctx, tolerance=self.parallax_tolerance,
                                stop_factor=self.stop_factor, defines=defines)
        else:
            cut = PairRefiner(ctx, omega_tr_factor=self.omega_tr_factor,
                              stop_factor=self.stop_factor, defines=defines)
        super().__init__(ctx, params, cut)

    def fits(self, params: RenderParams) -> bool:
        return (float(params.omega_tr_factor) == self.omega_tr_factor
                and float(params.parallax_tolerance) == self.parallax_tolerance
                and float(params.stop_factor) == self.stop_factor)
