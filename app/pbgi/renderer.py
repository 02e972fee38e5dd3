"""The relighting renderer: the one entry point the viewer, the CLI and the benchmarks share.

    r = Relighter()                       # ctx defaults to app.render.context.get_context()
    r.set_cloud(cloud)                    # builds the BSH (cached), uploads it
    r.set_asset(mesh)                     # a placed mesh (app.io.formats.placed_mesh)
    res = r.render(camera, materials, RenderParams(mode="classic", microbuffer=24))
    res.image  # (h, w, 4) float32 linear radiance, alpha 1 on object pixels; res.stats

A render is: G-buffer -> receivers (object pixels) -> per batch of receivers sized from the
memory budget: find the cut into micro-buffers (the mode) -> gather with the Disney BRDF (shared).
Modes share the node layout, the micro-buffer and the gather; they differ only in the cut finder.
Material edits change only the material table (and the G-buffer's factors): when the previous
render's micro-buffers are still valid (same cloud, asset, camera, tile, size, mode and normal
maps, all receivers in one batch), only the G-buffer and the gather run again.
"""

from __future__ import annotations

import hashlib
import logging
import time
import sys
from dataclasses import dataclass, field, replace

import numpy as np

from app.errors import ScanlightError
from app.params import RENDER_KEYS, param_record
from app.pbgi.microbuffer import (MAX_SIZE, MIN_SIZE, MicroBuffers, batch_size,
                                  bytes_per_receiver, entries)
from app.pbgi.gmip import z_order  # receivers in Z-order: batches are compact squares
from app.pbgi.nodetex import NodeTextures

log = logging.getLogger(__name__)

MODES = ("classic", "mipmapped", "hybrid", "envmap")
# Cut finders of the PBGI modes: mode -> (module, class, {constructor keyword: RenderParams
# field}). The protocol (app.pbgi.classic.ClassicCut is the reference):
#   fill(mb, receivers, first, count, m, nodes, cell_size) -> dict with per-receiver "visited"
#       and "done" arrays; optional "rounds", "cut_short", "tests" (per receiver) and "extra"
#       (a dict of numbers, summed over batches into the stats);
#   needs_tile = True: fill also gets width= (the tile width) and budget_bytes=;
#   bytes_per_receiver(m): per-receiver memory besides the micro-buffer (batch sizing);
#   reserve_bytes(budget): memory taken whatever the batch size (subtracted from the budget);
#   clears_microbuffers = True: fill writes every entry of its rows, so they are not emptied first;
#   GL refusing memory: fill raises its module's AllocationError (or MemoryError); the
#       renderer halves the batch and retries (stats "tile_halvings").
CUT_FINDERS = {
    "classic": ("app.pbgi.classic", "ClassicCut", {}),
    "mipmapped": ("app.pbgi.mipmapped", "MipmappedCut", {}),
    "hybrid": ("app.pbgi.hybrid", "HybridCut", {"omega_tr_factor": "omega_tr_factor",
                                                "parallax_tolerance": "parallax_tolerance"}),
}


def _available(module: str) -> bool:
    import importlib.util
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


IMPLEMENTED = tuple(m for m, (mod, _, _) in CUT_FINDERS.items() if _available(mod)) + ("envmap",)


MB = 1024.0 * 1024.0


@param_record(*RENDER_KEYS)
class RenderParams:
    """What one render takes: the ``pbgi.*`` rows of app/params.py named in RENDER_KEYS (mode,
    microbuffer, omega_tr_factor, parallax_tolerance, memory_budget_mb, envmap_face), with the
    table's defaults and ranges. ``validated()`` returns a checked copy or raises ScanlightError.
    """


@dataclass
class RenderResult:
    image: np.ndarray
    stats: dict = field(default_factory=dict)


def _fingerprint(*arrays) -> str:
    h = hashlib.blake2b(digest_size=16)
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(str((a.dtype, a.shape)).encode())
        h.update(a.data)
    return h.hexdigest()


def recolor(hierarchy, colors: np.ndarray) -> np.ndarray:
    """Node records with colours recomputed from new point colours on the same tree.

    Every node's colour is the mean of the points below it (app.pbgi.hierarchy); in depth-first
    order a subtree is the index range [i, skip(i)), so prefix sums of per-leaf colour sums give
    every subtree sum at once.
    """
    nodes = hierarchy.nodes.copy()
    m = len(nodes)
    leaf_sum = np.zeros((m, 3))
    np.add.at(leaf_sum, hierarchy.point_node, np.asarray(colors, dtype=np.float64))
    prefix = np.zeros((m + 1, 3))
    np.cumsum(leaf_sum, axis=0, out=prefix[1:])
    skip = nodes["skip"].astype(np.int64)
    sums = prefix[skip] - prefix[np.arange(m)]
    from app.pbgi.layout import COUNT_MASK
    count = (nodes["count_flags"] & COUNT_MASK).astype(np.float64)
    nodes["color"] = (sums / np.maximum(count, 1.0)[:, None]).astype(np.float32)
    return nodes


_BSH_CACHE: dict[str, object] = {}


class Relighter:
    def __init__(self, ctx=None):
        from app.pbgi.gather import Gather
        from app.pbgi.gbuffer import GBuffer
        from app.render.context import get_context
        self.ctx = ctx or get_context()
        self.gbuffer = GBuffer(self.ctx)
        self.gather = Gather(self.ctx)
        self.cut_finders = {}
        self.microbuffers = MicroBuffers(self.ctx)
        self.cloud = None
        self.hierarchy = None
        self.nodes_buf = None
        self.node_tex = None
        self.node_count = 0
        self.mesh = None
        self._cloud_version = 0
        self._asset_version = 0
        self._splat = None
        self._env = None
        self._env_key = None
        self._mb_key = None
        self._mb_stats = {}
        self._mb_frames = None
        self.last_receivers = None

    # -- inputs -----------------------------------------------------------------------------
    def set_cloud(self, cloud, hierarchy=None) -> None:
        """Build (or reuse) the BSH of ``cloud`` and upload it. Calling again with the same
        points and new colours (the HDR expansion's result) only recomputes node colours."""
        from app.pbgi.bsh_cache import load_or_build
        if len(cloud) == 0:
            raise ScanlightError(cloud.source, "the point cloud is empty")
        geo_key = _fingerprint(cloud.positions, cloud.normals)
        col_key = _fingerprint(cloud.colors)
        if hierarchy is None:
            cached = _BSH_CACHE.get(geo_key)
            if cached is not None and cached[0] == col_key:
                hierarchy = cached[1]
            elif cached is not None:
                h = cached[1]
                from dataclasses import replace
                hierarchy = replace(h, nodes=recolor(h, cloud.colors))
            else:
                hierarchy = load_or_build(cloud)   # cached beside the cloud's file, if any
            _BSH_CACHE.clear()                      # keep one cloud: BSHs are large
            _BSH_CACHE[geo_key] = (col_key, hierarchy)
        old_origin = None if self.hierarchy is None else self.hierarchy.origin
        self.cloud, self.hierarchy = cloud, hierarchy
        if self.nodes_buf is not None:
            self.nodes_buf.release()
        self.nodes_buf = self.ctx.buffer(np.ascontiguousarray(hierarchy.nodes).tobytes())
        self.node_count = len(hierarchy.nodes)
        if self.node_tex is not None:
            self.node_tex.release()
        self.node_tex = NodeTextures(self.ctx, self.nodes_buf, self.node_count)
        self._cloud_version += 1
        if self._splat is not None:
            self._splat.release()
            self._splat = None
        if self._env is not None:
            self._env.release()
            self._env, self._env_key = None, None
        if self.mesh is not None and (old_origin is None or
                                      not np.array_equal(old_origin, hierarchy.origin)):
            self.gbuffer.upload(self.mesh, hierarchy.origin)

    def set_asset(self, mesh) -> None:
        if mesh.n_faces == 0:
            raise ScanlightError(mesh.source, "the asset has no triangles")
        self.mesh = mesh
        self._asset_version += 1
        origin = self.hierarchy.origin if self.hierarchy is not None else np.zeros(3)
        self.gbuffer.upload(mesh, origin)
        if self._env is not None:
            self._env.release()
            self._env, self._env_key = None, None

    @property
    def origin(self) -> np.ndarray:
        return self.hierarchy.origin

    def object_centre(self) -> np.ndarray:
        lo, hi = self.mesh.bounds()
        return 0.5 * (np.asarray(lo, float) + np.asarray(hi, float))

    def splat_renderer(self):
        from app.render.splat import SplatRenderer
        if self._splat is None:
            self._splat = SplatRenderer(self.cloud, ctx=self.ctx)
        return self._splat

    def background(self, camera) -> np.ndarray:
        """The room's point splats from ``camera``, (h, w, 4), alpha 1 where a splat covers."""
        return self.splat_renderer().render(camera)

    def environment(self, face: int):
        from app.pbgi.envmap import EnvironmentMap
        key = (self._cloud_version, self._asset_version, int(face))
        if self._env_key != key:
            if self._env is not None:
                self._env.release()
            self._env = EnvironmentMap(self.ctx, self.splat_renderer(), self.object_centre(), face)
            self._env_key = key
        return self._env

    # -- render -----------------------------------------------------------------------------
    def _cut(self, mode: str, params: RenderParams):
        return self.cut_finder(replace(params, mode=mode))

    def cut_finder(self, params: RenderParams):
        """The cut finder of a PBGI mode (created once; Hybrid's again when its factor changes)."""
        import importlib
        module, cls, kwargs = CUT_FINDERS[params.mode]
        kw = {k: getattr(params, v) for k, v in kwargs.items()}
        held = self.cut_finders.get(params.mode)
        if held is None or getattr(held, "_scanlight_kw", kw) != kw:
            if held is not None and hasattr(held, "release"):
                held.release()
            held = getattr(importlib.import_module(module), cls)(self.ctx, **kw)
            held._scanlight_kw = kw
            self.cut_finders[params.mode] = held
        return held

    def render(self, camera, materials=None, params: RenderParams | None = None,
               tile=None) -> RenderResult:
        params = (params or RenderParams()).validated()
        if self.hierarchy is None or self.mesh is None:
            raise ScanlightError(None, "render needs a cloud (set_cloud) and an asset (set_asset)")
        materials = list(self.mesh.materials if materials is None else materials)
        if not materials:
            raise ScanlightError(None, "render needs at least one material")
        if len(materials) == 1 and len(self.mesh.materials) > 1:
            materials = materials * len(self.mesh.materials)
        if len(materials) < len(self.mesh.materials):
            raise ScanlightError(None, f"the asset has {len(self.mesh.materials)} materials, "
                                       f"got {len(materials)}")
        W, H = camera.width, camera.height
        x0, y0, w, h = (int(v) for v in (tile if tile is not None else (0, 0, W, H)))
        if w < 1 or h < 1 or x0 < 0 or y0 < 0 or x0 + w > W or y0 + h > H:
            raise ScanlightError(None, f"tile {tuple(tile)} is outside the {W}x{H} image")
        tile = (x0, y0, w, h)
        m = int(params.microbuffer)
        ctx = self.ctx
        from app.pbgi.gbuffer import material_table

        ctx.finish()
        t0 = time.perf_counter()
        gb = self.gbuffer.render(camera, materials, tile)
        rec = gb["receivers"]
        rec = rec[np.argsort(z_order(np.ascontiguousarray(rec[:, 3]).view(np.uint32), w),
                             kind="stable")]
        self.last_receivers = rec          # in the order of the micro-buffer rows (debugging)
        n = len(rec)
        t1 = time.perf_counter()
        stats = {"mode": params.mode, "microbuffer": m, "width": w, "height": h,
                 "tile": list(tile), "receivers": n, "nodes": self.node_count,
                 "bsh_mb": (self.hierarchy.nodes.nbytes + self.node_tex.nbytes) / MB,
                 "batches": 0, "rounds": 0, "nodes_visited": 0.0, "completed": True,
                 "reused_microbuffers": False, "ms_gbuffer": (t1 - t0) * 1e3, "ms_cut": 0.0,
                 "ms_gather": 0.0, "micropixels": n * m * m, "entries": n * entries(m)}
        image = np.zeros((h, w, 4), dtype=np.float32)
        if n == 0:
            stats.update(ms=(t1 - t0) * 1e3, mb=gb["bytes"] / MB)
            return RenderResult(image, stats)

        bufs = {"receivers": ctx.buffer(rec.tobytes()),
                "materials": ctx.buffer(material_table(materials).tobytes()),
                "output": ctx.buffer(reserve=16 * w * h)}
        bufs["output"].clear()
        extra = sum(b.size for b in bufs.values())
        cam_rel = camera.position - self.origin
        try:
            if params.mode == "envmap":
                extra += self._gather_envmap(params, bufs, n, m, cam_rel, stats)
            else:
                key = (self._cloud_version, self._asset_version, params.mode, m, tile,
                       params.omega_tr_factor, params.parallax_tolerance,
                       tuple(camera.position.tolist()), tuple(camera.look_at.tolist()),
                       tuple(camera.up.tolist()), camera.fov_y_deg, W, H, n,
                       tuple(id(mt.normal_texture) for mt in materials))
                extra += self._cut_and_gather(params, bufs, n, m, cam_rel, key, tile, stats)
            t2 = time.perf_counter()
            out = np.frombuffer(bufs["output"].read(), dtype=np.float32).reshape(h, w, 4)
        finally:
            for b in bufs.values():
                b.release()
        cover = gb["coverage"]
        image[..., :3] = out[..., :3]
        image[..., 3] = cover.astype(np.float32)
        gather_short = int((out[..., 3][cover] < 0).sum())
        bad = ~np.isfinite(image[..., :3])
        if bad.any():
            image[..., :3][bad] = 0.0
        stats["nonfinite_pixels"] = int(bad.any(axis=-1).sum())
        stats["gather_cut_short"] = gather_short
        stats["completed"] = (stats.get("incomplete_receivers", 0) == 0 and gather_short == 0
                              and stats["nonfinite_pixels"] == 0)
        stats.update(ms=(t2 - t0) * 1e3, mb=max(extra, gb["bytes"]) / MB)
        return RenderResult(image, stats)

    def _gather_envmap(self, params, bufs, n, m, cam_rel, stats) -> int:
        env = self.environment(params.envmap_face)
        self.ctx.finish()
        tg = time.perf_counter()
        self.gather.run(bufs["receivers"], bufs["materials"], bufs["output"], 0, n, m, cam_rel,
                        env=env)
        self.ctx.finish()
        stats["ms_gather"] = (time.perf_counter() - tg) * 1e3
        stats["envmap_face"] = env.face_size
        return env.nbytes

    def _cut_and_gather(self, params, bufs, n, m, cam_rel, key, tile, stats) -> int:
        """Per batch of receivers: empty the micro-buffers, find the cut (the mode), gather.
        Batches are sized from the memory budget; GL refusing memory halves them. Returns the
        extra GPU bytes (micro-buffers, the cut finder's state and reserve)."""
        import moderngl
        ctx = self.ctx
        cut = self.cut_finder(params)
        state_per = int(getattr(cut, "bytes_per_receiver", lambda m: 16)(m))
        budget = params.memory_budget_mb * MB
        reserve = int(getattr(cut, "reserve_bytes", lambda b: 0)(budget))
        mb_per = bytes_per_receiver(m)
        per = batch_size(m, max(budget - reserve, 0.0) * mb_per / (mb_per + state_per),
                         int(ctx.info.get("GL_MAX_TEXTURE_SIZE", 16384)), n)
        refused = (MemoryError, moderngl.Error) + tuple(   # the finder's modules' AllocationError
            {getattr(sys.modules.get(c.__module__), "AllocationError", None)
             for c in type(cut).__mro__} - {None})
        reuse = per >= n and self._mb_key == key
        extra_kw = ({"width": tile[2], "budget_bytes": max(budget - mb_per * per, 0.0)}
                    if getattr(cut, "needs_tile", False) else {})
        results, halvings, first = [], 0, 0
        t_cut = t_gather = 0.0
        while first < n:
            count = min(per, n - first)
            ctx.finish()
            tc = time.perf_counter()
            if not reuse:
                self._mb_key = None
                try:
                    # a finder that writes every entry itself needs no emptied buffers
                    self.microbuffers.prepare(
                        m, per, 0 if getattr(cut, "clears_microbuffers", False) else count)
                    res = cut.fill(self.microbuffers, bufs["receivers"], first, count, m,
                                   self.node_tex, self.hierarchy.cell_size, **extra_kw)
                except refused as exc:
                    if per <= 1:
                        raise ScanlightError(None, f"out of GPU memory even for one receiver "
                                                   f"({exc})") from None
                    per, halvings = max(1, per // 2), halvings + 1
                    self.microbuffers.release()
                    log.warning("GPU memory refused (%s): batch halved to %d receivers", exc, per)
                    continue
                results.append(res)
                ctx.finish()
            tg = time.perf_counter()
            frames = results[-1].get("frames") if results and not reuse else self._mb_frames
            self.gather.run(bufs["receivers"], bufs["materials"], bufs["output"], first, count,
                            m, cam_rel, mb=self.microbuffers, nodes=self.node_tex, frames=frames)
            ctx.finish()
            t_gather += time.perf_counter() - tg
            t_cut += tg - tc
            stats["batches"] += 1
            first += count
        if reuse:
            stats.update(self._mb_stats)
            stats["reused_microbuffers"] = True
        else:
            visited = np.concatenate([r["visited"] for r in results])
            done = np.concatenate([r["done"] for r in results])
            self._mb_stats = {"nodes_visited": float(visited.mean()),
                              "nodes_visited_max": int(visited.max()),
                              "incomplete_receivers": int((~done).sum()),
                              "rounds": int(sum(r.get("rounds", 0) for r in results)),
                              "cut_short": int(sum(r.get("cut_short", 0) for r in results))}
            if all("tests" in r for r in results):
                self._mb_stats["splat_tests"] = float(np.concatenate(
                    [r["tests"] for r in results]).mean())
            for r in results:                      # mode-specific figures, summed over batches
                for k, v in r.get("extra", {}).items():
                    if isinstance(v, (int, float, np.number)) and not isinstance(v, bool):
                        self._mb_stats[k] = self._mb_stats.get(k, 0) + v
                for k, v in r.get("peaks", {}).items():   # ... and peaks, the largest batch's
                    self._mb_stats[k] = max(self._mb_stats.get(k, 0), v)
            # the cut finder's own memory as allocated (its largest batch; Table 3's "extra")
            self._mb_stats["mb_extra"] = max(r.get("bytes", 0) for r in results) / MB
            stats.update(self._mb_stats)
            self._mb_key = key if per >= n else None
            self._mb_frames = results[-1].get("frames") if results else None
        extra = reserve + state_per * per
        stats.setdefault("mb_extra", extra / MB)
        stats.update(ms_cut=t_cut * 1e3, ms_gather=t_gather * 1e3, batch_receivers=per,
                     tile_halvings=halvings, mb_microbuffers=self.microbuffers.nbytes / MB,
                     mb_extra_bound=extra / MB)
        return self.microbuffers.nbytes + extra

    def release(self) -> None:
        self.gbuffer.release()
        self.microbuffers.release()
        for c in self.cut_finders.values():
            c.release()
        for obj in (self.nodes_buf, self.node_tex, self._splat, self._env):
            if obj is not None:
                obj.release()
        self.nodes_buf = self.node_tex = self._splat = self._env = None
