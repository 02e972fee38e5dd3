"""The relighting renderer: the one entry point the viewer, the CLI and the benchmarks share.

    r = Relighter()                       # ctx defaults to app.render.context.get_context()
    r.set_cloud(cloud)                    # builds the BSH (cached), uploads it
    r.set_asset(mesh)                     # a placed mesh (app.io.formats.placed_mesh)
    res = r.render(camera, materials, RenderParams(mode="classic", microbuffer=24))
    res.image  # (h, w, 4) float32 linear radiance, alpha 1 on object pixels; res.stats

A render is: G-buffer -> receivers (object pixels, in Z-order) -> the mode lights them into the
output (``RenderMode.render``, app/pbgi/modebase.py) -> image and ``RenderStats``. The modes are
a closed list (app/pbgi/modes.py); the three PBGI modes share the node layout, the micro-buffer,
the batching and the gather and differ only in their cut finder; the environment map is the same
gather lit by a cube map. The Relighter holds what they share: the BSH and its node textures,
the G-buffer, the micro-buffers (and which cut they hold), the gather, the cube map.

The tree the modes walk is the room's joined with the asset's surfels (``pbgi.asset_occlusion``,
app/pbgi/asset_scene.py: the asset occludes and lights itself), built once per asset placement,
cloud and materials outside the frame's time; ``differential`` gives the asset's shadow and
bounce on the scan for ``background``.

Material edits change only the material table (and the G-buffer's factors): when the previous
render's micro-buffers are still valid (same cloud, asset, camera, tile, size, mode and normal
maps, all receivers in one batch), only the G-buffer and the gather run again. A render asked
for ``parts`` also returns the gather kept apart per BRDF factor, from which the viewer
recombines an edit of base colour, metallic, specular, sheen or clearcoat amount without any
render (app/pbgi/gather_parts.py).
"""

from __future__ import annotations

import hashlib
import time
from dataclasses import dataclass, replace

import numpy as np

from app.errors import ScanlightError
from app.io.limits import MAX_RADIANCE
from app.pbgi.gmip import z_order  # receivers in Z-order: batches are compact squares
from app.pbgi.gpu_layout import GATHER_OUTPUT, GATHER_PARTS, RECEIVER, WALK_ONLY
from app.pbgi.hierarchy import recolor
from app.pbgi.microbuffer import MIN_SIZE, MicroBuffers, entries
from app.pbgi.lobe import (LobeBuffers, LobeSettings, lobe_only_receivers, lobe_walk_tuning,
                           needs_lobe, surface_radius)
from app.pbgi.modebase import Frame, HeldCut, Layer, RenderMode, RenderParams
from app.pbgi.modes import create_mode
from app.pbgi.nodetex import NodeTextures
from app.pbgi.stats import MB, RenderStats

__all__ = ["Relighter", "RenderParams", "RenderResult", "RenderStats", "recolor"]


@dataclass
class RenderResult:
    image: np.ndarray                 # (h, w, 4) float32 linear radiance, alpha = coverage
    stats: RenderStats
    parts: np.ndarray | None = None   # (h, w) GATHER_PARTS records when asked (render(parts=))


def _fingerprint(*arrays) -> str:
    h = hashlib.blake2b(digest_size=16)
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(str((a.dtype, a.shape)).encode())
        h.update(a.data)
    return h.hexdigest()


_BSH_CACHE: dict[str, object] = {}


_RADIUS_CACHE: dict = {}       # geometry fingerprint -> the scan's surface radius (one cloud)


class Relighter:
    def __init__(self, ctx=None):
        from app.pbgi.gather import Gather
        from app.pbgi.gbuffer import GBuffer
        from app.render.context import get_context
        self.ctx = ctx or get_context()
        self.gbuffer = GBuffer(self.ctx)
        self.gather = Gather(self.ctx)
        self.modes: dict[str, RenderMode] = {}      # one per name, see mode_for
        self.microbuffers = MicroBuffers(self.ctx)
        self._held = HeldCut(self.microbuffers)
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
        self.hdri = None                   # app/pbgi/hdri.py: lights the asset instead of the scan
        self.last_receivers = None
        self._lobe = None                  # LobeBuffers, made on the first glossy render
        self._lobe_tuning = None           # LobeWalkTuning: None = the GL renderer's own
        self._walks_only = False           # see walks_only
        self._geo_key = None               # the cloud's geometry fingerprint
        self._asset_scene = None           # AssetScene, made on the first render with the asset
        self._splat_colors = None          # what the splats show: None = the scan's colours
        self._clearance = None             # ((geometry, asset version), nearfield.Clearance)
        self._kdtree = None                # (geometry key, cKDTree of the scan's points)
        self._convex = None                # (asset version, nearfield.mesh_is_convex)
        # A convex asset's surfels stay out of its own render (see walks_asset); False keeps
        # them (the benchmark's "with" side, tests)
        self.convex_shortcut = True
        self.upsampler = None              # app/pbgi/upsample.py's pass on this context, made
                                           # by the first render_upsampled below scale 1
        self._layer_gb = None              # the last ``layer``'s G-buffer and keys (render)

    # -- inputs -----------------------------------------------------------------------------
    def set_cloud(self, cloud, hierarchy=None) -> None:
        """Build (or reuse) the BSH of ``cloud`` and upload it. Calling again with the same
        points and new colours (the HDR expansion's result) only recomputes node colours."""
        from app.pbgi.bsh_cache import load_or_build
        if len(cloud) == 0:
            raise ScanlightError(cloud.source, "the point cloud is empty")
        # radiance is finite and non-negative (load_cloud repairs files: app.io.clean); checked
        # here for every path, the recolouring of a cached tree included, not only the BSH build
        # and at most MAX_RADIANCE (float32 sums of 3e38 overflowed to Inf)
        bad = ~np.isfinite(cloud.colors).all(axis=1)
        neg = (cloud.colors < 0).any(axis=1)
        with np.errstate(invalid="ignore"):
            huge = (cloud.colors > MAX_RADIANCE).any(axis=1) & ~bad
        if bad.any() or neg.any() or huge.any():
            above = f" and {int(huge.sum())} above {MAX_RADIANCE:g}" if huge.any() else ""
            raise ScanlightError(cloud.source, f"{int(bad.sum())} points have NaN or Inf colours "
                                               f"and {int(neg.sum())} negative ones{above}: "
                                               "radiance must be finite and non-negative, at "
                                               f"most {MAX_RADIANCE:g}")
        geo_key = _fingerprint(cloud.positions, cloud.normals)
        col_key = _fingerprint(cloud.colors)
        if hierarchy is None:
            cached = _BSH_CACHE.get(geo_key)
            if cached is not None and cached[0] == col_key:
                hierarchy = cached[1]
            elif cached is not None:
                h = cached[1]
                hierarchy = replace(h, nodes=recolor(h, cloud.colors))
            else:
                hierarchy = load_or_build(cloud)   # cached beside the cloud's file, if any
            _BSH_CACHE.clear()                      # keep one cloud: BSHs are large
            _BSH_CACHE[geo_key] = (col_key, hierarchy)
        old_origin = None if self.hierarchy is None else self.hierarchy.origin
        self.cloud, self.hierarchy = cloud, hierarchy
        self._geo_key = geo_key
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
        self._splat_colors = None
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

    def set_hdri(self, hdri) -> None:
        """Light the asset with an HDRI (app/pbgi/hdri.py) instead of the scan, or with the scan
        again (None). An HDRI is distant light: every render gathers it through the environment
        map (exact for it), whatever ``params.mode`` asks, and the background shows it."""
        self.hdri = hdri
        if self._env is not None:
            self._env.release()
            self._env, self._env_key = None, None

    def materials_for(self, materials=None) -> list:
        """One material per material of the asset: its own (None), or ``materials``, a single
        one standing for all of them."""
        materials = list(self.mesh.materials if materials is None else materials)
        if not materials:
            raise ScanlightError(None, "render needs at least one material")
        if len(materials) == 1 and len(self.mesh.materials) > 1:
            materials = materials * len(self.mesh.materials)
        if len(materials) < len(self.mesh.materials):
            raise ScanlightError(None, f"the asset has {len(self.mesh.materials)} materials, "
                                       f"got {len(materials)}")
        return materials

    def clearance(self):
        """The asset's clearance in the scan (app/pbgi/nearfield.py), computed once per cloud
        geometry and asset."""
        from scipy.spatial import cKDTree

        from app.pbgi.nearfield import clearance
        key = (self._geo_key, self._asset_version)
        if self._clearance is None or self._clearance[0] != key:
            if self._kdtree is None or self._kdtree[0] != self._geo_key:
                self._kdtree = (self._geo_key, cKDTree(np.asarray(self.cloud.positions,
                                                                  np.float64)))
            self._clearance = (key, clearance(None, self.mesh, self._kdtree[1]))
        return self._clearance[1]

    def asset_convex(self) -> bool:
        """Is the asset convex (app/pbgi/nearfield.py: mesh_is_convex)? Once per asset."""
        from app.pbgi.nearfield import mesh_is_convex
        if self._convex is None or self._convex[0] != self._asset_version:
            self._convex = (self._asset_version, bool(mesh_is_convex(self.mesh)))
        return self._convex[1]

    def walks_asset(self, params: RenderParams) -> bool:
        """Does a render with ``params`` walk the tree joined with the asset's surfels?

        Only when they can change the asset's pixels: asset occlusion on, a micro-buffer mode,
        and an asset that is not convex. Every point of a convex surface has the rest of the
        surface on or behind its tangent plane, so its surfels neither hide the room from any
        of its receivers nor light them (tests/pbgi/test_asset_scene.py shows the render with
        them within 1.5% of the one without); walking them only cost time - 2x in Hybrid on the
        demo sphere, whose far-field blocks all meet the asset as near field. The scan's
        receivers of the differential still meet the asset (``differential``)."""
        params = params.validated()
        if not params.asset_occlusion or params.mode == "envmap" or self.mesh is None:
            return False
        return not (self.convex_shortcut and self.asset_convex())

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

    def _splats_showing(self, differential=None):
        """The splat renderer with the scan's colours, or with a Differential's applied."""
        splat = self.splat_renderer()
        want = None if differential is None else id(differential)
        if self._splat_colors != want:
            splat.set_colors(self.cloud.colors if differential is None
                             else differential.colors(self.cloud.colors))
            self._splat_colors = want
        return splat

    def background(self, camera, differential=None, eye_dome: bool = False) -> np.ndarray:
        """The room's point splats from ``camera``, (h, w, 4), alpha 1 where a splat covers or
        a small hole was filled (app/render/splat.py: surface splatting + push-pull); with a
        ``differential`` (``Relighter.differential``) the asset's shadow and bounce on the scan
        are in it; ``eye_dome``: eye-dome lighting on the splats (``view.eye_dome``). With an
        HDRI lighting the asset (``set_hdri``), the panorama seen by ``camera`` instead."""
        if self.hdri is not None:
            from app.pbgi.hdri import hdri_backdrop
            return hdri_backdrop(self.hdri, camera)
        return self._splats_showing(differential).render(camera, eye_dome=eye_dome)

    @property
    def asset_scene(self):
        from app.pbgi.asset_scene import AssetScene
        if self._asset_scene is None:
            self._asset_scene = AssetScene(self.ctx, self.gather, self._room_environment)
        return self._asset_scene

    def _room_environment(self, face: int | None = None):
        """A new cube map of the scan's own colours seen from the asset's centre: the
        environment-map baseline's (``environment``) and the asset's mirror bounce's
        (app/pbgi/asset_scene.py, at the default face size); its owner releases it."""
        from app.pbgi.envmap import DEFAULT_FACE, EnvironmentMap
        return EnvironmentMap.of_splats(self.ctx, self._splats_showing(None),
                                        self.object_centre(), face or DEFAULT_FACE)

    def scene_nodes(self, materials=None, params: RenderParams | None = None):
        """The tree a render with ``params`` walks: the room and the asset's surfels
        (app/pbgi/asset_scene.py, coloured with the bounce), or None when
        ``params.asset_occlusion`` is off (the room's tree alone)."""
        params = (params or RenderParams()).validated()
        if not params.asset_occlusion:
            return None
        materials = list(self.mesh.materials if materials is None else materials)
        return self.asset_scene.nodes(self.hierarchy, self._cloud_version, self.mesh,
                                      self._asset_version, materials, params)

    def _differential_args(self, materials, params) -> tuple:
        params = (params or RenderParams()).validated()
        if self.hierarchy is None or self.mesh is None:
            raise ScanlightError(None, "differential rendering needs a cloud and an asset")
        if not params.asset_occlusion:
            params = replace(params, asset_occlusion=True)
        materials = list(self.mesh.materials if materials is None else materials)
        return (self.cloud, self._cloud_version, self.hierarchy, self.node_tex,
                self._cloud_version, self.mesh, self._asset_version, materials, params)

    def differential(self, materials=None, params: RenderParams | None = None):
        """The asset's shadow and bounce on the scan's points near it
        (app/pbgi/asset_scene.py: Differential), for ``background(camera, differential)``."""
        return self.asset_scene.differential(*self._differential_args(materials, params))

    def differential_steps(self, materials=None, params: RenderParams | None = None,
                           chunk: int = 256):
        """The same as a generator of the fraction done (the viewer's progressive version)."""
        return self.asset_scene.differential_steps(*self._differential_args(materials, params),
                                                   chunk=chunk)

    def differential_key(self, materials=None, params: RenderParams | None = None) -> tuple:
        """Changes exactly when ``differential`` would give another result."""
        args = self._differential_args(materials, params)
        return self.asset_scene.differential_key(args[1], args[2], *args[4:])

    def asset_scene_ready(self, materials=None, params: RenderParams | None = None) -> bool:
        """Would a render with ``params`` find the asset's tree and bounce built? (The viewer
        renders without them while the user drags, rather than wait for a rebuild per frame.)"""
        params = (params or RenderParams()).validated()
        if not self.walks_asset(params):
            return True
        if self._asset_scene is None:
            return False
        materials = list(self.mesh.materials if materials is None else materials)
        return self._asset_scene.ready(self._cloud_version, self.mesh, self._asset_version,
                                       materials, params)

    def environment(self, face: int):
        from app.pbgi.envmap import EnvironmentMap
        key = (self._cloud_version, self._asset_version, int(face),
               None if self.hdri is None else self.hdri.key)
        if self._env_key != key:
            if self._env is not None:
                self._env.release()
            if self.hdri is not None:
                from app.pbgi.hdri import hdri_faces
                self._env = EnvironmentMap(self.ctx, hdri_faces(self.hdri, int(face)),
                                           self.object_centre())
            else:
                self._env = self._room_environment(face)
            self._env_key = key
        return self._env

    # -- render -----------------------------------------------------------------------------
    def mode_for(self, params: RenderParams) -> RenderMode:
        """The mode object ``params.mode`` renders with: created once, again when a parameter
        it fixed at construction changed (``RenderMode.fits``)."""
        held = self.modes.get(params.mode)
        if held is None or not held.fits(params):
            if held is not None:
                held.release()
            held = self.modes[params.mode] = create_mode(
                params.mode, self.ctx, params, defines=self._walk_defines)
        return held

    def forget_microbuffers(self) -> None:
        """The next render finds its cut again even if the micro-buffers hold it (timings)."""
        self._held.key = None

    def render(self, camera, materials=None, params: RenderParams | None = None,
               tile=None, pass_index: int = 0, pixels=None,
               parts: bool = False, layer=None, passes: int | None = None) -> RenderResult:
        """Relight the asset seen by ``camera`` (``tile``: a part of the image).
        ``pass_index`` moves each pixel's sample inside the pixel and re-jitters the lobe
        micro-buffers (app/pbgi/lobe.py): the mean of several passes is anti-aliased and
        averages the lobes' noise (``render_passes``). ``passes``: how many passes are averaged
        with this one (gbuffer.pass_jitter centres their samples on the pixel together); a pass
        other than 0 must say it, pass 0 alone is the centre.
        ``parts``: also return each pixel's gather split by BRDF factor (``RenderResult.parts``,
        app/pbgi/gather_parts.py), which a later edit of base colour, metallic, specular, sheen
        or clearcoat amount recombines instead of gathering again (the viewer).
        ``layer``: a rectangle (x0, y0, w, h) holding ``tile``, of which this call is one tile
        (the viewer's refinement): the layer's G-buffer is rasterised once for all its tiles of a
        pass, and Hybrid chooses its blocks over the whole layer and keeps each block's walk for
        the tiles that share it (app/pbgi/farfield.py, "Layers"), so the tiles add up to one
        render of the layer and their edges show nowhere."""
        params = (params or RenderParams()).validated()
        if passes is None and pass_index != 0:
            raise ValueError(f"pass {pass_index} needs the number of passes it is averaged with")
        if self.hierarchy is None or self.mesh is None:
            raise ScanlightError(None, "render needs a cloud (set_cloud) and an asset (set_asset)")
        materials = self.materials_for(materials)
        asked, clear = params.mode, None
        if self.hdri is not None:          # distant light: the environment map is exact for it
            params = replace(params, mode="envmap")
        if params.mode != "envmap" and params.envmap_beyond > 0:
            from app.pbgi.nearfield import near_field_needed
            clear = self.clearance()
            if near_field_needed(params, materials, clear) is None:
                params = replace(params, mode="envmap")
        W, H = camera.width, camera.height
        x0, y0, w, h = (int(v) for v in (tile if tile is not None else (0, 0, W, H)))
        if W < 1 or H < 1:
            raise ScanlightError(None, f"the camera's image of {W}x{H} pixels is empty")
        if w < 1 or h < 1 or x0 < 0 or y0 < 0 or x0 + w > W or y0 + h > H:
            raise ScanlightError(None, f"tile {(x0, y0, w, h)} is outside the {W}x{H} image")
        tile = (x0, y0, w, h)
        if layer is not None:
            lx, ly, lw, lh = (int(v) for v in layer)
            if not (0 <= lx <= x0 and 0 <= ly <= y0 and x0 + w <= lx + lw <= W
                    and y0 + h <= ly + lh <= H):
                raise ScanlightError(None, f"tile {tile} is not inside the layer {tuple(layer)} "
                                           f"of the {W}x{H} image")
            layer = (lx, ly, lw, lh) if pixels is None else None
        m = m_lobe = int(params.microbuffer)       # the lobe buffers follow the M asked for
        small = max(int(params.lobe_only_microbuffer), MIN_SIZE)
        coarse_m = (params.mode != "envmap" and params.glossy_below > 0.0
                    and int(params.lobe_only_microbuffer) > 0 and small < m)
        ctx = self.ctx
        from app.pbgi.gather import absent_features
        from app.pbgi.gbuffer import material_table, pass_jitter
        jitter = pass_jitter(pass_index, passes or 1)

        # the asset's surfels in the tree: built (and bounced) once per asset, cloud and
        # materials, outside the frame's time (stats.ms_asset says what it took when it ran)
        nodes, node_count, asset_first, scene_key = (self.node_tex, self.node_count,
                                                     self.node_count, None)
        scene = self.scene_nodes(materials, params) if self.walks_asset(params) else None
        ms_asset = 0.0
        if scene is not None:
            nodes, node_count, asset_first, scene_key = (scene.textures, scene.count,
                                                         scene.asset_first, scene.key)
            ms_asset = self.asset_scene.seconds * 1e3
        ctx.finish()
        t0 = time.perf_counter()
        if layer is not None:              # one G-buffer for all the layer's tiles of a pass
            view = (self._cloud_version, self._asset_version, params, layer,
                    tuple(camera.position.tolist()), tuple(camera.look_at.tolist()),
                    tuple(camera.up.tolist()), camera.fov_y_deg, W, H, jitter,
                    scene_key)
            key = view + (material_table(materials).tobytes(),
                          tuple(id(mt.normal_texture) for mt in materials))
            if self._layer_gb is None or self._layer_gb["key"] != key:
                lgb = self.gbuffer.render(camera, materials, layer, jitter)
                lv = RECEIVER.view(lgb["receivers"])
                # what Hybrid's blocks depend on: the view and the receivers' geometry, not
                # their materials - the viewer recolours in the middle of a pass and goes on
                self._layer_gb = {"key": key, "gb": lgb, "coarse": None, "shape": view + (
                    _fingerprint(lv["position"], lv["normal"]),)}
            gb = _tile_of(self._layer_gb["gb"], x0 - layer[0], y0 - layer[1], w, h)
        else:
            gb = self.gbuffer.render(camera, materials, tile, jitter)
        rec, rows = gb["receivers"], gb.get("rows")
        if pixels is not None:             # only these pixels' receivers (silhouette samples)
            rec = rec[np.asarray(pixels, bool).reshape(-1)[RECEIVER.view(rec)["pixel"]]]
        order = np.argsort(z_order(RECEIVER.view(rec)["pixel"], w), kind="stable")
        rec = rec[order]
        rows = rows[order] if rows is not None else None
        n = len(rec)
        groups, coarse_n, layer_coarse = (), 0, None
        if coarse_m and n:                 # lobe-only receivers: a coarse cosine micro-buffer
            v = RECEIVER.view(rec)
            coarse = lobe_only_receivers(v["metallic"], v["roughness"], params.glossy_below)
            coarse_n = int(coarse.sum())
            if coarse_n == n:              # one group: the whole frame at the small M
                m = small
                params = replace(params, microbuffer=m)
            elif coarse_n:                 # two runs, each still in Z-order
                rec = np.concatenate([rec[~coarse], rec[coarse]])
                rows = np.concatenate([rows[~coarse], rows[coarse]]) if rows is not None else None
                groups = ((0, n - coarse_n, m), (n - coarse_n, coarse_n, small))
            if layer is not None:          # the layer's own split, for its groups of blocks
                if self._layer_gb["coarse"] is None:
                    lv = RECEIVER.view(self._layer_gb["gb"]["receivers"])
                    mask = lobe_only_receivers(lv["metallic"], lv["roughness"],
                                               params.glossy_below)
                    self._layer_gb["coarse"] = (mask, _fingerprint(mask))
                layer_coarse = self._layer_gb["coarse"][0]
        self.last_receivers = rec          # in the order of the micro-buffer rows (debugging)
        runs = groups or ((0, n, m),)      # (start, count, M) of every run of receivers
        t1 = time.perf_counter()
        stats = RenderStats(mode=params.mode, microbuffer=m, width=w, height=h, tile=tile,
                            receivers=n, nodes=node_count,
                            bsh_mb=(self.hierarchy.nodes.nbytes + self.node_tex.nbytes) / MB,
                            micropixels=sum(c * k * k for _, c, k in runs),
                            entries=sum(c * entries(k) for _, c, k in runs),
                            coarse_receivers=coarse_n, coarse_microbuffer=small if coarse_n else 0,
                            ms_gbuffer=(t1 - t0) * 1e3)
        if self.hdri is not None:
            stats.hdri = self.hdri.source or "(in memory)"
        if clear is not None:
            stats.clearance = clear.ratio
            if params.mode != asked:
                stats.envmap_instead_of = asked
        stats.asset_convex_skipped = bool(scene is None and params.asset_occlusion
                                          and params.mode != "envmap")
        if scene is not None:
            stats.asset_surfels = int(params.asset_surfels)
            stats.asset_bounces = int(params.asset_bounces)
            stats.ms_asset = ms_asset
            stats.mb_asset = self.asset_scene.nbytes / MB
        image = np.zeros((h, w, 4), dtype=np.float32)
        if n == 0:
            stats.ms, stats.mb = (t1 - t0) * 1e3, gb["bytes"] / MB
            from app.pbgi.gather_parts import empty
            return RenderResult(image, stats, empty((h, w)) if parts else None)

        bufs = {"receivers": ctx.buffer(rec.tobytes()),
                "materials": ctx.buffer(material_table(materials).tobytes()),
                "output": ctx.buffer(reserve=GATHER_OUTPUT.nbytes * w * h)}
        bufs["output"].clear()
        if parts:
            bufs["parts"] = ctx.buffer(reserve=GATHER_PARTS.nbytes * w * h)
            bufs["parts"].clear()
        extra = sum(b.size for b in bufs.values())
        # everything the cut depends on: the micro-buffers hold this render's cut if it matches
        cut_key = (self._cloud_version, self._asset_version, params.mode, m, tile,
                   params.omega_tr_factor, params.parallax_tolerance,
                   tuple(camera.position.tolist()), tuple(camera.look_at.tolist()),
                   tuple(camera.up.tolist()), camera.fov_y_deg, W, H, n, jitter,
                   tuple(id(mt.normal_texture) for mt in materials), scene_key,
                   None if pixels is None else hash(np.asarray(pixels, bool).tobytes()),
                   groups, layer,      # Hybrid's blocks are the layer's
                   int(pass_index))    # frames turn per pass (microbuffer.set_frame_uniforms)
        lobe = None
        if params.glossy_below > 0.0 and needs_lobe(materials, params.glossy_below):
            lobe = replace(LobeSettings.for_microbuffer(m_lobe, params.glossy_below, pass_index),
                           seed_tile=(x0, y0, w, W))
            if self._lobe is None:
                self._lobe = LobeBuffers(ctx, self.lobe_tuning,
                                         defines=self._walk_defines)
            stats.lobe_receivers = True
        stats.absent_features = absent_features(materials) if params.shader_variants else ()
        try:
            frame = Frame(params=params, receivers=bufs["receivers"],
                          materials=bufs["materials"], output=bufs["output"], count=n,
                          tile=tile, camera_rel=camera.position - self.origin,
                          nodes=nodes, cell_size=self.hierarchy.cell_size,
                          gather=self.gather, microbuffers=self._held, cut_key=cut_key,
                          environment=self.environment, lobe=lobe, lobe_buffers=self._lobe,
                          leaf_radius=self.leaf_radius if lobe is not None else 0.0,
                          absent_features=stats.absent_features, groups=groups,
                          pass_index=int(pass_index), parts=bufs.get("parts"),
                          seed_tile=(x0, y0, w, W),
                          layer=None if layer is None else Layer(
                              self._layer_gb["shape"] + (
                                  None if layer_coarse is None else self._layer_gb["coarse"][1],),
                              layer[2], RECEIVER.view(self._layer_gb["gb"]["receivers"]), rows,
                              layer_coarse))
            extra += self.mode_for(params).render(frame, stats)
            if lobe is not None:
                extra += self._lobe.nbytes
            t2 = time.perf_counter()
            out = GATHER_OUTPUT.view(bufs["output"].read()).reshape(h, w)
            split = (GATHER_PARTS.view(bytearray(bufs["parts"].read())).reshape(h, w)
                     if parts else None)
        finally:
            for b in bufs.values():
                b.release()
        cover = gb["coverage"]
        image[..., :3] = out["radiance"]
        image[..., 3] = cover.astype(np.float32)
        bad = ~np.isfinite(image[..., :3])
        if bad.any():
            image[..., :3][bad] = 0.0
        stats.nonfinite_pixels = int(bad.any(axis=-1).sum())
        stats.gather_cut_short = int((out["status"][cover] < 0).sum())
        stats.completed = (not stats.incomplete_receivers and stats.gather_cut_short == 0
                           and stats.lobe_incomplete == 0
                           and stats.nonfinite_pixels == 0)
        stats.ms, stats.mb = (t2 - t0) * 1e3, max(extra, gb["bytes"]) / MB
        if split is not None and bad.any():
            from app.pbgi.gather_parts import PART_NAMES
            for name in PART_NAMES:
                split[name][bad.any(axis=-1)] = 0.0
        return RenderResult(image, stats, split)

    @property
    def leaf_radius(self) -> float:
        """The cloud's surface_radius (app/pbgi/lobe.py: the disc each point is for the lobe
        ray casts), computed on the first glossy render of a cloud's geometry, not at load."""
        if _RADIUS_CACHE.get("key") != self._geo_key:
            _RADIUS_CACHE.update(key=self._geo_key, radius=surface_radius(self.cloud.positions))
        return _RADIUS_CACHE["radius"]

    @property
    def lobe_tuning(self):
        """The lobe walk's LobeWalkTuning (app/pbgi/lobe.py): the GL renderer's own unless set
        (``bench profile --lobe-tuning`` compares them on one device). The image is the same
        either way; setting it drops the lobe buffers made with the other."""
        return self._lobe_tuning or lobe_walk_tuning(self.ctx.info.get("GL_RENDERER", ""))

    @lobe_tuning.setter
    def lobe_tuning(self, tuning) -> None:
        self._lobe_tuning = tuning
        if self._lobe is not None and self._lobe.tuning != self.lobe_tuning:
            self._lobe.release()
            self._lobe = None

    @property
    def walks_only(self) -> bool:
        """Render with the walks alone: no accepted node is rasterised or ray cast
        (gpu_layout.WALK_ONLY), so each render's cut and lobe times are its walks' and
        ``bench profile`` can tell them from the rasterisation. The micro-buffers stay empty
        and the image is meaningless. Setting it drops the modes and lobe buffers made the
        other way."""
        return self._walks_only

    @walks_only.setter
    def walks_only(self, on: bool) -> None:
        if bool(on) == self._walks_only:
            return
        self._walks_only = bool(on)
        for mode in self.modes.values():
            mode.release()
        self.modes.clear()
        if self._lobe is not None:
            self._lobe.release()
            self._lobe = None
        self.forget_microbuffers()

    @property
    def _walk_defines(self):
        """What every walk program is compiled with: WALK_ONLY under ``walks_only``."""
        return WALK_ONLY if self._walks_only else None

    @property
    def lobe_buffers(self):
        """The last render's lobe micro-buffers (app/pbgi/lobe.py; None before any glossy
        material): rows in the order of ``last_receivers`` (tests, debugging)."""
        return self._lobe

    def render_passes(self, camera, materials=None, params: RenderParams | None = None,
                      passes: int = 1, tile=None, progress=None,
                      edge_samples: int = 1) -> RenderResult:
        """The mean of ``passes`` renders (pass_index 0 .. passes - 1, their samples centred
        together by gbuffer.pass_jitter): anti-aliased pixels (alpha is the covered fraction
        and the radiance is premultiplied by it) and the lobe buffers' noise averaged.
        ``edge_samples`` above ``passes``: the pixels a silhouette crosses
        (app/pbgi/antialias.py) are then rendered ``edge_samples`` times more, gathering only
        their receivers, as that many passes -
        exactly what ``passes=edge_samples`` gives them (pass_jitter centres a set of passes'
        samples only all together, so the first passes' samples are not reused for them).
        ``progress(done, render_steps(passes, edge_samples))`` after each render. Stats: the
        first pass's, with the times and flags of all."""
        from app.pbgi.antialias import silhouette_pixels
        passes = max(int(passes), 1)
        samples = max(passes, int(edge_samples))
        steps = render_steps(passes, samples)
        acc, edge_acc, first, ms, completed, done = None, None, None, 0.0, True, 0
        edges = None

        def one(k, n, pixels):
            nonlocal first, ms, completed, done
            res = self.render(camera, materials, params, tile=tile, pass_index=k,
                              pixels=pixels, passes=n)
            first = res.stats if first is None else first
            ms += res.stats.ms
            completed &= res.stats.completed
            done += 1
            if progress is not None:
                progress(done, steps)
            return res.image.astype(np.float64)

        for k in range(passes):
            img = one(k, passes, None)
            acc = img if acc is None else acc + img
        if samples > passes:              # the silhouettes only, as `samples` passes
            edges = silhouette_pixels(acc[..., 3] / passes, self._last_depth(camera, tile))
            if edges.any():
                edge_acc = sum(one(k, samples, edges) for k in range(samples))
        image = acc / passes
        stats = replace(first, ms=ms, completed=completed, passes=passes)
        if edge_acc is not None:
            image[edges] = edge_acc[edges] / samples
            stats.edge_pixels, stats.edge_samples = int(edges.sum()), samples
        return RenderResult(image.astype(np.float32), stats)

    def _last_depth(self, camera, tile=None) -> np.ndarray:
        """Distance from the camera of the last render's receivers, per tile pixel (inf where
        none): the silhouettes inside the asset are where it jumps."""
        x0, y0, w, h = tile if tile is not None else (0, 0, camera.width, camera.height)
        depth = np.full(w * h, np.inf)
        rec = self.last_receivers
        if rec is not None and len(rec):
            pos = rec[:, 0:3].astype(np.float64) + self.origin
            depth[RECEIVER.view(rec)["pixel"]] = np.linalg.norm(pos - camera.position, axis=1)
        return depth.reshape(h, w)

    def release(self) -> None:
        self.gbuffer.release()
        self.microbuffers.release()
        for mode in self.modes.values():
            mode.release()
        for obj in (self.nodes_buf, self.node_tex, self._splat, self._env, self._lobe,
                    self._asset_scene):
            if obj is not None:
                obj.release()
        self.nodes_buf = self.node_tex = self._splat = self._env = self._lobe = None
        self._asset_scene = self._layer_gb = None


def render_steps(passes: int, edge_samples: int = 1) -> int:
    """The render calls of ``Relighter.render_passes`` (its progress total): the passes, then
    the silhouettes' samples when they are more (fewer calls when no silhouette is found)."""
    passes, samples = max(int(passes), 1), int(edge_samples)
    return passes + (samples if samples > passes else 0)


def _tile_of(gb: dict, ox: int, oy: int, w: int, h: int) -> dict:
    """The part of a layer's G-buffer (GBuffer.render) that a tile at (ox, oy) in it covers,
    as the G-buffer of the tile itself; ``rows``: each receiver's row in the layer's."""
    rec = gb["receivers"]
    ys, xs = np.divmod(RECEIVER.view(rec)["pixel"].astype(np.int64), gb["width"])
    rows = np.flatnonzero((xs >= ox) & (xs < ox + w) & (ys >= oy) & (ys < oy + h))
    out = rec[rows]
    RECEIVER.view(out)["pixel"] = ((ys[rows] - oy) * w + xs[rows] - ox).astype(np.uint32)
    return {"receivers": out, "rows": rows, "coverage": gb["coverage"][oy:oy + h, ox:ox + w],
            "width": w, "height": h, "bytes": gb["bytes"]}
