"""GPU side of the viewport: room splats, the asset G-buffer, and the composite pass.

One instance per context; the window and the offscreen runner use the same one, so a batch
screenshot is exactly what the window shows under its panels. Every frame:

1. the room's point splats into an RGBA32F target with depth (app.render.splat: surface
   splatting, push-pull hole filling, optional eye-dome lighting),
2. the placed asset rasterised into a normal + eye-depth G-buffer (cheap, full resolution),
3. the composite compute pass (shaders/viewer_composite.glsl) blends the room with the GI
   images handed over by app.ui.refine, tone maps, and writes an RGBA8 display image plus the
   linear composite,
   With the A/B compare (app/ui/compare.py) it runs once per side, each dispatch clipped to
   its side's columns, B's with its own GI images (``Side``), and a backdrop (an HDRI's
   panorama) replaces the room behind a side an HDRI lights,
4. the display image is blitted to the target framebuffer (no fragment pass: see the llvmpipe
   note in the project conventions).

Textures are in GL orientation (row 0 at the bottom); numpy images (row 0 at the top) are flipped
on upload and read-back here and nowhere else. Texture and image units, vertex records, texel
records and the composite's work-group size come from app/render/gpu_layout.py, which generates
the shaders' side of them.
"""

from __future__ import annotations

import numpy as np

from app.camera import Camera
from app.render.gpu_layout import (COMPOSITE_TEXEL, COMPOSITE_TILE, GI_TEXEL, GUIDE_TEXEL,
                                   ROOM_TEXEL, VIEW_IMG, VIEW_TEX, VIEWER_VERTEX)
from app.render.programs import load_compute, load_program
from app.render.splat import SplatRenderer, gl_mat, near_far, relative_view
from app.render.tonemap import index as tonemap_index

BACKGROUND = (0.02, 0.02, 0.025)


def _flip(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a[::-1])


def _texels(tex, rec) -> np.ndarray:
    """A texture of ``rec`` texels as (h, w, words) of its storage type, GL orientation."""
    tw, th = tex.size
    return rec.flat(rec.view(tex.read())).reshape(th, tw, rec.words)


class Side:
    """One side of the A/B compare (app/ui/compare.py) where it differs from the viewport's own
    inputs: its GI images (B's layer; None: the viewport's) and its backdrop (the HDRI's
    panorama seen by the camera, in place of the room's splats, behind a depth cleared to the
    far plane; None: the splats)."""

    def __init__(self):
        self.preview_tex = self.full_tex = None
        self.backdrop_tex = self.backdrop_depth = self.backdrop_fbo = None

    def textures(self):
        return [t for t in (self.preview_tex, self.full_tex, self.backdrop_fbo,
                            self.backdrop_tex, self.backdrop_depth) if t is not None]


class ViewportRenderer:
    def __init__(self, ctx):
        import moderngl
        self.moderngl = moderngl
        self.ctx = ctx
        from app.ui import composite as twin
        # the upsampling's weights come from gen/joint_bilateral.glsl (app/pbgi/upsample.py); the
        # tone mappers' indices and the false-colour bands from the registry (gen/tonemap.glsl)
        weights = {"ROOM_DEPTH_SCALE": repr(float(twin.ROOM_DEPTH_SLACK[0])),
                   "ROOM_DEPTH_BIAS": repr(float(twin.ROOM_DEPTH_SLACK[1]))}
        self.room_cs = load_compute(ctx, "viewer_composite.glsl", weights)
        self.asset_cs = load_compute(ctx, "viewer_composite.glsl", dict(weights, ASSET_PASS=1))
        self.label_cs = load_compute(ctx, "viewer_composite.glsl", dict(weights, LABEL_PASS=1))
        self.gbuf_prog = load_program(ctx, "viewer_gbuffer.glsl")
        self.size = (0, 0)
        self.splat: SplatRenderer | None = None
        self.base_radius = 0.01
        self.asset_vao = None
        self._asset_buffers = []
        self.asset_origin = np.zeros(3)
        self.asset_bounds = None
        self.preview_tex = self._gi_texture((1, 1), GI_TEXEL.zeros(1).tobytes())
        self.full_tex = self._gi_texture((1, 1), GI_TEXEL.zeros(1).tobytes())
        self.label_tex = ctx.texture((1, 1), 4, bytes(4))
        self.label_size = (0, 0)
        self._targets = []
        self.scene_bounds = (np.zeros(3), np.ones(3))
        self.side_a, self.side_b = Side(), Side()   # A keeps the viewport's GI images
        self._side_labels = []                        # (texture, (w, h)) of A's and B's labels

    # -- resources -------------------------------------------------------------------------------
    def _texture(self, size, rec, data=None):
        """A texture of ``rec`` texels, read texel by texel (nearest)."""
        tex = self.ctx.texture(size, rec.texel_components, data, dtype=rec.texture_dtype)
        tex.filter = (self.moderngl.NEAREST, self.moderngl.NEAREST)
        return tex

    def _gi_texture(self, size, data=None):
        return self._texture(size, GI_TEXEL, data)

    def resize(self, width: int, height: int) -> None:
        if (width, height) == self.size:
            return
        for obj in self._targets:
            obj.release()
        ctx, mgl = self.ctx, self.moderngl
        w, h = max(int(width), 1), max(int(height), 1)
        self.size = (w, h)
        self.room_tex = self._texture((w, h), ROOM_TEXEL)
        self.room_depth = ctx.depth_texture((w, h))
        self.room_depth.compare_func = ""
        self.room_fbo = ctx.framebuffer([self.room_tex], self.room_depth)
        self.gbuf_tex = self._texture((w, h), GUIDE_TEXEL)
        self.gbuf_depth = ctx.depth_texture((w, h))
        self.gbuf_fbo = ctx.framebuffer([self.gbuf_tex], self.gbuf_depth)
        self.linear_tex = self._texture((w, h), COMPOSITE_TEXEL)
        self.display_tex = ctx.texture((w, h), 4)
        self.display_fbo = ctx.framebuffer([self.display_tex])
        for t in (self.room_depth, self.display_tex):
            t.filter = (mgl.NEAREST, mgl.NEAREST)
        self._targets = [self.room_fbo, self.room_tex, self.room_depth, self.gbuf_fbo,
                         self.gbuf_tex, self.gbuf_depth, self.display_fbo, self.linear_tex,
                         self.display_tex]

    def set_cloud(self, cloud) -> None:
        if self.splat is not None:
            self.splat.release()
        self.splat = SplatRenderer(cloud, ctx=self.ctx)
        self.base_radius = self.splat.radius

    def set_colors(self, colors: np.ndarray, categorical: bool | None = None) -> None:
        """New splat colours; ``categorical`` (None: as before): they are labels, never mixed
        (the provenance view)."""
        self.splat.set_colors(colors)
        if categorical is not None:
            self.splat.categorical = bool(categorical)

    def set_asset(self, mesh) -> None:
        """Upload the placed mesh (world space) for the G-buffer; None removes the asset."""
        for b in self._asset_buffers:
            b.release()
        self._asset_buffers, self.asset_vao, self.asset_bounds = [], None, None
        if mesh is None or mesh.n_faces == 0:
            return
        lo, hi = mesh.bounds()
        self.asset_bounds = (np.asarray(lo, np.float64), np.asarray(hi, np.float64))
        self.asset_origin = (self.asset_bounds[0] + self.asset_bounds[1]) / 2
        pos = mesh.positions.astype(np.float64) - self.asset_origin
        vbo = self.ctx.buffer(VIEWER_VERTEX.field_array("position", pos).tobytes())
        nbo = self.ctx.buffer(VIEWER_VERTEX.field_array("normal", mesh.normals).tobytes())
        ibo = self.ctx.buffer(np.ascontiguousarray(mesh.indices, "u4").tobytes())
        self.asset_vao = self.ctx.vertex_array(
            self.gbuf_prog, VIEWER_VERTEX.vertex_content({"position": vbo, "normal": nbo}),
            index_buffer=ibo, index_element_size=4)
        self._asset_buffers = [self.asset_vao, vbo, nbo, ibo]

    def set_label(self, rgba: np.ndarray | None) -> None:
        """A small RGBA8 text image (row 0 at the top) shown over the asset; None hides it."""
        if rgba is None:
            self.label_size = (0, 0)
            return
        h, w = rgba.shape[:2]
        if self.label_tex.size != (w, h):
            self.label_tex.release()
            self.label_tex = self.ctx.texture((w, h), 4)
        self.label_tex.write(_flip(rgba.astype(np.uint8)).tobytes())
        self.label_size = (w, h)

    # -- GI images from app.ui.refine ------------------------------------------------------------
    def upload_preview(self, img: np.ndarray, side: Side | None = None) -> None:
        """Into the viewport's preview image, or ``side``'s (B's GI layer)."""
        t = side or self
        h, w = img.shape[:2]
        if t.preview_tex is None or t.preview_tex.size != (w, h):
            if t.preview_tex is not None:
                t.preview_tex.release()
            t.preview_tex = self._gi_texture((w, h))
        t.preview_tex.write(_flip(img.astype("f4")).tobytes())

    def upload_full(self, img: np.ndarray, rects=None, side: Side | None = None) -> None:
        """Whole image when ``rects`` is None, else only those (x, y, w, h) top-left rectangles;
        into the viewport's full image or ``side``'s."""
        t = side or self
        h, w = img.shape[:2]
        if t.full_tex is None or t.full_tex.size != (w, h):
            if t.full_tex is not None:
                t.full_tex.release()
            t.full_tex = self._gi_texture((w, h))
            rects = None
        if rects is None:
            t.full_tex.write(_flip(img.astype("f4")).tobytes())
            return
        for x, y, rw, rh in rects:
            block = img[y:y + rh, x:x + rw].astype("f4")
            t.full_tex.write(_flip(block).tobytes(), viewport=(x, h - y - rh, rw, rh))

    def set_backdrop(self, side: Side, rgb: np.ndarray | None) -> None:
        """``side`` shows ``rgb`` ((H, W, 3+) linear, row 0 at the top, the viewport's size)
        instead of the room's splats, nothing in front of the asset; None: the splats again."""
        if rgb is None:
            for t in (side.backdrop_fbo, side.backdrop_tex, side.backdrop_depth):
                if t is not None:
                    t.release()
            side.backdrop_tex = side.backdrop_depth = side.backdrop_fbo = None
            return
        w, h = self.size
        if side.backdrop_tex is None or side.backdrop_tex.size != (w, h):
            self.set_backdrop(side, None)
            side.backdrop_tex = self._texture((w, h), ROOM_TEXEL)
            side.backdrop_depth = self.ctx.depth_texture((w, h))
            side.backdrop_depth.compare_func = ""
            side.backdrop_fbo = self.ctx.framebuffer([side.backdrop_tex], side.backdrop_depth)
        side.backdrop_fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        img = np.ones((h, w, 4), np.float32)          # coverage 1: the panorama everywhere
        img[..., :3] = np.asarray(rgb, np.float32)[..., :3]
        side.backdrop_tex.write(_flip(img).tobytes())

    def set_side_labels(self, images) -> None:
        """A's and B's labels (RGBA8 text images, row 0 at the top); () removes them."""
        for tex, _ in self._side_labels:
            tex.release()
        self._side_labels = []
        for rgba in images:
            h, w = rgba.shape[:2]
            tex = self.ctx.texture((w, h), 4, _flip(rgba.astype(np.uint8)).tobytes())
            self._side_labels.append((tex, (w, h)))

    @property
    def side_label_sizes(self):
        return [size for _, size in self._side_labels]

    def draw_side_labels(self, rects) -> None:
        """Blend the side labels over the display image at ``rects`` (top-left x, y, w, h)."""
        w, h = self.size
        cs = self.label_cs
        self.display_tex.bind_to_image(VIEW_IMG.DISPLAY, read=True, write=True)
        for (tex, _), (x, y, lw, lh) in zip(self._side_labels, rects):
            gl = (x, h - y - lh, lw, lh)
            x0, y0 = max(gl[0], 0), max(gl[1], 0)
            x1, y1 = min(gl[0] + lw, w), min(gl[1] + lh, h)
            if x1 <= x0 or y1 <= y0:
                continue
            tex.use(location=VIEW_TEX.LABEL)
            self._run_rect(cs, x0, y0, x1, y1, {"u_size": (w, h), "u_label_rect": gl})

    def _run_rect(self, cs, x0, y0, x1, y1, values: dict) -> None:
        """One compute pass of ``cs`` over the pixels [x0, x1) x [y0, y1) (GL rows), with the
        uniforms of ``values`` it has."""
        for key, val in values.items():
            if key in cs:
                cs[key].value = val
        cs["u_offset"].value = (x0, y0)
        cs["u_extent"].value = (x1 - x0, y1 - y0)
        cs.run(-(-(x1 - x0) // COMPOSITE_TILE), -(-(y1 - y0) // COMPOSITE_TILE))
        self.ctx.memory_barrier()

    # -- passes ----------------------------------------------------------------------------------
    def draw_room(self, camera: Camera, splat_scale: float = 1.0, eye_dome: bool = False,
                  fast: bool = False) -> None:
        """The room backdrop into room_tex / room_depth, as ``render --background`` draws it
        (SplatRenderer.render_to: surface splatting, hole filling, optional eye-dome lighting);
        filled holes keep the cleared depth (the composite puts the asset in front there).
        ``fast``: the cheap opaque sprites while the camera moves (SplatRenderer.render_to)."""
        self.room_fbo.use()
        self.room_fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        if self.splat is not None:
            self.splat.radius = self.base_radius * float(splat_scale)
            self.ctx.enable_only(self.moderngl.NOTHING)
            self.splat.render_to(camera, self.room_tex, self.room_depth, eye_dome=eye_dome,
                                 fast=fast)
            self.ctx.enable_only(self.moderngl.NOTHING)
            self.room_fbo.use()

    def draw_gbuffer(self, camera: Camera) -> None:
        self.gbuf_fbo.use()
        self.gbuf_fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        if self.asset_vao is None:
            return
        lo, hi = self.asset_bounds
        near, far = near_far(camera, lo, hi)
        self.gbuf_prog["u_view"].write(gl_mat(relative_view(camera, self.asset_origin)))
        self.gbuf_prog["u_proj"].write(gl_mat(camera.projection(near, far)))
        self.ctx.enable_only(self.moderngl.DEPTH_TEST)
        self.asset_vao.render(self.moderngl.TRIANGLES)

    def composite(self, camera: Camera, exposure: float, tonemap: str, raw_room: bool,
                  unavailable: bool, asset_rect=None, label_rect=None, room: bool = True,
                  false_colour: bool = False, side: Side | None = None, columns=None,
                  divider: int = -1) -> None:
        """Run the composite passes. Rectangles are (x, y, w, h) with row 0 at the TOP;
        ``room=False`` re-runs only the asset rectangle (after a GI update) and the label.
        ``tonemap`` is a name of app.render.tonemap.TONEMAPPERS; ``false_colour`` shows the
        EV bands (app.render.tonemap.false_colour) instead, except on raw (false-colour) room
        colours. The A/B compare runs it once per side: ``side`` (its GI images and
        backdrop, app/ui/compare.py), ``columns`` (x0, x1): only those columns are written,
        ``divider``: the column of the divider line (-1: none)."""
        w, h = self.size
        side = side or self.side_a
        gi = side if side.full_tex is not None else self
        if self.splat is not None:
            near, far = near_far(camera, *self.splat.bounds)
        else:
            near, far = 0.01, 100.0
        if side.backdrop_tex is not None:
            side.backdrop_tex.use(location=VIEW_TEX.ROOM)
            side.backdrop_depth.use(location=VIEW_TEX.ROOM_DEPTH)
            raw_room = False
        else:
            self.room_tex.use(location=VIEW_TEX.ROOM)
            self.room_depth.use(location=VIEW_TEX.ROOM_DEPTH)
        self.gbuf_tex.use(location=VIEW_TEX.GBUF)
        gi.preview_tex.use(location=VIEW_TEX.PREVIEW)
        gi.full_tex.use(location=VIEW_TEX.FULL)
        self.label_tex.use(location=VIEW_TEX.LABEL)
        self.linear_tex.bind_to_image(VIEW_IMG.LINEAR, read=False, write=True)
        self.display_tex.bind_to_image(VIEW_IMG.DISPLAY, read=True, write=True)
        gl_label = None
        if label_rect and self.label_size[0]:
            lx, ly, lw, lh = label_rect
            gl_label = (lx, h - ly - lh, lw, lh)
        values = {
            "u_size": (w, h), "u_preview_size": gi.preview_tex.size,
            "u_full_size": gi.full_tex.size, "u_near": near, "u_far": far,
            "u_divider": int(divider),
            "u_exposure": float(exposure), "u_tonemap": tonemap_index(tonemap),
            "u_false_colour": int(false_colour),
            "u_raw_room": int(raw_room), "u_unavailable": int(unavailable),
            "u_background": BACKGROUND, "u_label_rect": gl_label or (0, 0, 0, 0),
        }   # the samplers' units are their layout(binding = VIEW_TEX_*)

        c0, c1 = (0, w) if columns is None else columns

        def run(cs, rect_gl):
            x, y, rw, rh = rect_gl
            x0, y0 = max(x, 0, c0), max(y, 0)
            x1, y1 = min(x + rw, w, c1), min(y + rh, h)
            if x1 <= x0 or y1 <= y0:
                return
            self._run_rect(cs, x0, y0, x1, y1, values)

        if room:
            run(self.room_cs, (0, 0, w, h))
        if asset_rect is not None and self.asset_vao is not None:
            ax, ay, aw, ah = asset_rect
            run(self.asset_cs, (ax, h - ay - ah, aw, ah))
        if gl_label is not None:
            run(self.label_cs, gl_label)

    def blit(self, target) -> None:
        """Copy the display image into ``target`` (a framebuffer of the same size)."""
        self.ctx.copy_framebuffer(target, self.display_fbo)

    # -- read-back -------------------------------------------------------------------------------
    def read_display(self) -> np.ndarray:
        """(H, W, 3) uint8 sRGB, row 0 at the top."""
        w, h = self.size
        a = np.frombuffer(self.display_tex.read(), np.uint8).reshape(h, w, 4)
        return _flip(a[..., :3])

    def read_linear(self) -> np.ndarray:
        """(H, W, 4) float32 linear composite, alpha = asset; row 0 at the top."""
        return _flip(_texels(self.linear_tex, COMPOSITE_TEXEL))

    def read_inputs(self) -> dict:
        """Every input of the composite as numpy (GL orientation), for the numpy twin: the
        texel images as (h, w, words) arrays, columns as their records lay them out."""
        w, h = self.size
        depth = np.frombuffer(self.room_depth.read(), "f4").reshape(h, w).copy()
        return {"room": _texels(self.room_tex, ROOM_TEXEL).copy(), "room_depth": depth,
                "gbuf": _texels(self.gbuf_tex, GUIDE_TEXEL).copy(),
                "preview": _texels(self.preview_tex, GI_TEXEL).copy(),
                "full": _texels(self.full_tex, GI_TEXEL).copy()}

    def release(self) -> None:
        for obj in self._targets + self._asset_buffers + [self.preview_tex, self.full_tex,
                                                          self.label_tex]:
            obj.release()
        for side in (self.side_a, self.side_b):
            for obj in side.textures():
                obj.release()
        self.set_side_labels(())
        if self.splat is not None:
            self.splat.release()
