"""Gathers at arbitrary surface points, not pixels: the asset's surfels (their bounce) and the
scan's points near the asset (differential rendering), app/pbgi/asset_scene.py.

The same Classic walk and gather as a render (app/pbgi/classic.py, shaders/pbgi_gather.glsl),
with receivers made from (position, normal) instead of a G-buffer and a white Lambertian BRDF
(the gather's IRRADIANCE variant): the result per point is E / pi, the diffuse outgoing radiance
per unit albedo. Classic, whatever the view's mode: the points are scattered over the surface,
so Mipmapped's pixel pyramid and Hybrid's pixel blocks have nothing to share, and the bounce is
low-frequency, so a small micro-buffer (``MICROBUFFER``) is enough.

Points are lifted off their surface by ``offset`` along the normal before the walk: a scan
point sits inside its own leaf's sphere (and an asset surfel on its own disc), which would
otherwise cover its horizon.
"""

from __future__ import annotations

import numpy as np

from app.pbgi.classic import ClassicMode
from app.pbgi.gpu_layout import GATHER_OUTPUT, RECEIVER
from app.pbgi.microbuffer import MicroBuffers, entries
from app.pbgi.modebase import Frame, HeldCut, RenderParams
from app.pbgi.stats import RenderStats

MICROBUFFER = 16          # M of the point gathers (diffuse, low-frequency light)


class PointGather:
    def __init__(self, ctx, gather):
        self.ctx = ctx
        self.gather = gather
        self.mode = None
        self.held = HeldCut(MicroBuffers(ctx))
        self.last_stats: RenderStats | None = None

    def run(self, positions_rel: np.ndarray, normals: np.ndarray, nodes, cell_size: float,
            offset: float = 0.0, m: int = MICROBUFFER,
            budget_mb: float | None = None) -> np.ndarray:
        """(n, 3) float32 E / pi at each point (``positions_rel``: relative to the tree's
        origin; ``normals`` unit); ``nodes``: the NodeTextures of the tree to gather from."""
        from app.material import Material
        from app.pbgi.gbuffer import material_table
        from app.io.mesh import any_tangent
        n = len(positions_rel)
        if n == 0:
            return np.zeros((0, 3), np.float32)
        nrm = np.asarray(normals, np.float64)
        nrm = nrm / np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-30)
        rec = RECEIVER.zeros(n)
        rec["position"] = (np.asarray(positions_rel, np.float64) + offset * nrm).astype(np.float32)
        rec["pixel"] = np.arange(n, dtype=np.uint32)
        rec["normal"] = nrm.astype(np.float32)
        rec["material"] = 0
        rec["tangent"] = any_tangent(nrm.astype(np.float32))
        rec["roughness"] = 1.0
        rec["base_color"] = 1.0
        rec["metallic"] = 0.0
        white = Material(base_color=(1.0, 1.0, 1.0), metallic=0.0, roughness=1.0)
        extra = {} if budget_mb is None else {"memory_budget_mb": float(budget_mb)}
        params = RenderParams(mode="classic", microbuffer=int(m), glossy_below=0.0,
                              **extra).validated()
        if self.mode is None:
            self.mode = ClassicMode(self.ctx, params)
        ctx = self.ctx
        bufs = {"receivers": ctx.buffer(rec.tobytes()),
                "materials": ctx.buffer(material_table([white]).tobytes()),
                "output": ctx.buffer(reserve=GATHER_OUTPUT.nbytes * n)}
        bufs["output"].clear()
        stats = RenderStats(mode="classic", microbuffer=int(m), width=n, height=1,
                            tile=(0, 0, n, 1), receivers=n, nodes=nodes.count, bsh_mb=0.0,
                            micropixels=n * m * m, entries=n * entries(m))
        try:
            self.held.key = None
            frame = Frame(params=params, receivers=bufs["receivers"],
                          materials=bufs["materials"], output=bufs["output"], count=n,
                          tile=(0, 0, n, 1), camera_rel=np.zeros(3), nodes=nodes,
                          cell_size=cell_size, gather=self.gather, microbuffers=self.held,
                          cut_key=("points",), environment=None, irradiance=True)
            self.mode.render(frame, stats)
            out = GATHER_OUTPUT.view(bufs["output"].read())
        finally:
            for b in bufs.values():
                b.release()
            self.held.key = None
        self.last_stats = stats
        rad = np.asarray(out["radiance"], np.float32).reshape(n, 3)
        return np.where(np.isfinite(rad), np.maximum(rad, 0.0), 0.0).astype(np.float32)

    def release(self) -> None:
        if self.mode is not None:
            self.mode.release()
        self.held.buffers.release()
        self.mode = None
