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

``views`` gathers with the points' real materials instead, seen from a few far-away cameras: the
outgoing radiance of a glossy surfel in those directions (the asset's glossy bounce,
app/pbgi/asset_scene.py). The walk runs once; every camera only re-runs the gather on the held
micro-buffers.
"""

from __future__ import annotations

import numpy as np

from app.pbgi.classic import ClassicMode
from app.pbgi.gpu_layout import GATHER_OUTPUT, RECEIVER
from app.pbgi.microbuffer import MicroBuffers, entries
from app.pbgi.modebase import Frame, HeldCut, RenderParams
from app.pbgi.stats import RenderStats

MICROBUFFER = 16          # M of the point gathers (diffuse, low-frequency light)
FAR_VIEW = 1.0e3          # ``views``' cameras, in point-set extents away: V within 1e-3 rad


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
        if len(positions_rel) == 0:
            return np.zeros((0, 3), np.float32)
        return self._gather(positions_rel, normals, nodes, cell_size, offset, m, budget_mb,
                            None, [np.zeros(3)])[0]

    def views(self, positions_rel: np.ndarray, normals: np.ndarray, nodes, cell_size: float,
              materials, material_index: np.ndarray, base_color: np.ndarray,
              directions: np.ndarray, offset: float = 0.0, m: int = MICROBUFFER) -> np.ndarray:
        """(k, n, 3) float32 outgoing radiance of each point with its real material (row
        ``material_index`` of ``materials``, ``base_color`` (n, 3) factor x texture) seen from
        each of the k unit world ``directions`` (a camera that far away: V is the direction
        at every point; 0 where it is below the point's horizon). One walk: the micro-buffers
        depend on the points only, the k gathers reuse them (app/pbgi/modebase.py)."""
        n = len(positions_rel)
        if n == 0:
            return np.zeros((len(directions), 0, 3), np.float32)
        rel = np.asarray(positions_rel, np.float64)
        centre = 0.5 * (rel.min(axis=0) + rel.max(axis=0))
        far = FAR_VIEW * max(float(np.ptp(rel, axis=0).max()), 1e-3)
        cameras = [centre + far * np.asarray(d, np.float64) for d in directions]
        mats = (list(materials), np.asarray(material_index, np.uint32),
                np.asarray(base_color, np.float32))
        return self._gather(positions_rel, normals, nodes, cell_size, offset, m, None, mats,
                            cameras)

    def _gather(self, positions_rel, normals, nodes, cell_size, offset, m, budget_mb, mats,
                cameras) -> np.ndarray:
        """One walk, a gather per camera: (len(cameras), n, 3); ``mats`` None = the white
        Lambertian IRRADIANCE gather, else (materials, index, base colour)."""
        from app.material import Material
        from app.pbgi.gbuffer import material_table
        from app.io.mesh import any_tangent
        n = len(positions_rel)
        nrm = np.asarray(normals, np.float64)
        nrm = nrm / np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-30)
        rec = RECEIVER.zeros(n)
        rec["position"] = (np.asarray(positions_rel, np.float64) + offset * nrm).astype(np.float32)
        rec["pixel"] = np.arange(n, dtype=np.uint32)
        rec["normal"] = nrm.astype(np.float32)
        rec["tangent"] = any_tangent(nrm.astype(np.float32))
        if mats is None:
            table = [Material(base_color=(1.0, 1.0, 1.0), metallic=0.0, roughness=1.0)]
            rec["material"] = 0
            rec["roughness"] = 1.0
            rec["base_color"] = 1.0
            rec["metallic"] = 0.0
        else:
            table, index, base = mats
            rec["material"] = index
            rec["roughness"] = np.array([table[i].roughness for i in index], np.float32)
            rec["metallic"] = np.array([table[i].metallic for i in index], np.float32)
            rec["base_color"] = base
        extra = {} if budget_mb is None else {"memory_budget_mb": float(budget_mb)}
        params = RenderParams(mode="classic", microbuffer=int(m), glossy_below=0.0,
                              **extra).validated()
        if self.mode is None:
            self.mode = ClassicMode(self.ctx, params)
        ctx = self.ctx
        bufs = {"receivers": ctx.buffer(rec.tobytes()),
                "materials": ctx.buffer(material_table(table).tobytes()),
                "output": ctx.buffer(reserve=GATHER_OUTPUT.nbytes * n)}
        out = []
        try:
            self.held.key = None
            for camera in cameras:
                bufs["output"].clear()
                stats = RenderStats(mode="classic", microbuffer=int(m), width=n, height=1,
                                    tile=(0, 0, n, 1), receivers=n, nodes=nodes.count,
                                    bsh_mb=0.0, micropixels=n * m * m, entries=n * entries(m))
                frame = Frame(params=params, receivers=bufs["receivers"],
                              materials=bufs["materials"], output=bufs["output"], count=n,
                              tile=(0, 0, n, 1), camera_rel=np.asarray(camera, np.float64),
                              nodes=nodes, cell_size=cell_size, gather=self.gather,
                              microbuffers=self.held, cut_key=("points",), environment=None,
                              irradiance=mats is None, turned_frames=False)
                self.mode.render(frame, stats)
                rad = np.asarray(GATHER_OUTPUT.view(bufs["output"].read())["radiance"],
                                 np.float32).reshape(n, 3)
                out.append(np.where(np.isfinite(rad), np.maximum(rad, 0.0), 0.0))
                self.last_stats = stats
        finally:
            for b in bufs.values():
                b.release()
            self.held.key = None
        return np.asarray(out, np.float32)

    def release(self) -> None:
        if self.mode is not None:
            self.mode.release()
        self.held.buffers.release()
        self.mode = None
