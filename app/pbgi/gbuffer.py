"""The asset's G-buffer: the mesh rasterised into MRT float textures, then compacted into
*receivers* (object pixels in image order) that every PBGI pass and the gather read.

Why compact: the expensive passes run one invocation per object pixel, never on background
pixels, and batches of receivers are sized from the memory budget. The receiver record is
app/pbgi/gpu_layout.py's RECEIVER: its slot k is render target k (the shader takes its output
locations from the record), target 0's w (coverage) replaced by the pixel index.

Materials: the receiver carries the textured parameters (base colour, metallic, roughness, factor
x texture); the material table only the others (gpu_layout.TEXTURED_PARAMS is the split, and
gen/materials.glsl's receiver_principled the one place the gather combines them).

Positions are uploaded relative to the hierarchy origin (float64 on the CPU), the frame the BSH
node centres use, so a scan far from the world origin keeps millimetre precision in float32.
"""

from __future__ import annotations

import numpy as np

from app.camera import Camera
from app.pbgi.gpu_layout import GBUFFER_VERTEX, RECEIVER, TEXTURED_PARAMS, material_rows
from app.render.context import bind_anchor
from app.render.programs import load_program
from app.render.splat import gl_mat, near_far, relative_view

RECEIVER_FLOATS = RECEIVER.words       # one receiver = RECEIVER.slots vec4 = the render targets
TARGETS = RECEIVER.slots
TEXTURE_UNITS = {"base": 0, "mr": 1, "normal": 2}   # the G-buffer program's material textures


PLASTIC = 1.32471795724474602596     # the plastic number: the R2 low-discrepancy sequence


def r2_point(index: int, start: float = 0.0) -> tuple[float, float]:
    """Point ``index`` of the R2 low-discrepancy sequence (Roberts 2018) in [0, 1)^2, from
    (start, start): evenly spread for any number of points. Passes use it for their pixel
    jitter and for Hybrid's block-grid offset (app/pbgi/farfield.py: grid_offset)."""
    a1, a2 = 1.0 / PLASTIC, 1.0 / (PLASTIC * PLASTIC)
    return float((start + a1 * index) % 1.0), float((start + a2 * index) % 1.0)


def pass_jitter(pass_index: int, passes: int = 1) -> tuple[float, float]:
    """Where in its pixel pass ``pass_index`` of ``passes`` (the passes whose mean makes one
    image: ``render --passes N``, a silhouette's samples, the viewer's idle passes) samples,
    (dx, dy) in pixels from the centre, x to the right, y down; one pass is the centre.

    The points are the first ``passes`` of the R2 sequence (Roberts 2018: evenly spread for any
    count) from the pixel centre, all moved by one vector so that their mean *is* the centre:
    the mean of the passes is then a box-filtered pixel, not a shifted one. Unmoved, the mean of
    the first n points lay a quarter pixel off the centre at n = 2 (0.19 at 4, 0.11 at 8), and
    on a gold sphere 2-8 passes were further from the box-filtered image than one centred pass
    (README, "Passes"). A point may so land up to that far outside its pixel."""
    if not 0 <= pass_index < passes:
        raise ValueError(f"pass {pass_index} is not one of {passes} passes")
    pts = np.array([r2_point(k, 0.5) for k in range(int(passes))])
    d = pts[pass_index] - pts.mean(0)
    return float(d[0]), float(d[1])


def tile_projection(camera: Camera, near: float, far: float, tile, jitter=(0.0, 0.0)) -> np.ndarray:
    """The camera's projection restricted to the pixel rectangle tile = (x0, y0, w, h), row 0 at
    the top: the same rays as the full image, so tiles assemble without seams. ``jitter``
    shifts every pixel's sample by (dx, dy) pixels (x right, y down; pass_jitter)."""
    p = camera.projection(near, far)
    dx, dy = (float(v) for v in jitter)
    if dx or dy:
        t = np.eye(4)
        t[0, 3], t[1, 3] = -2.0 * dx / camera.width, 2.0 * dy / camera.height
        p = t @ p
    if tile is None:
        return p
    x0, y0, w, h = tile
    W, H = camera.width, camera.height
    yb = H - y0 - h                                   # GL rows count from the bottom
    sx, sy = W / w, H / h
    cx, cy = (2 * x0 + w) / W - 1.0, (2 * yb + h) / H - 1.0
    s = np.array([[sx, 0, 0, -cx * sx], [0, sy, 0, -cy * sy], [0, 0, 1, 0], [0, 0, 0, 1]], float)
    return s @ p


def material_table(materials) -> np.ndarray:
    """The material table the gather reads (SSBO_MATERIALS): one gpu_layout.MATERIAL record per
    material - the Disney parameters no texture changes (the textured ones travel with each
    receiver)."""
    return material_rows(materials)


class GBuffer:
    """Uploads a placed mesh once; rasterises it for any camera/tile into receivers."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.prog = load_program(ctx, "gbuffer.glsl")
        self.vao = None
        self._buffers = []
        self.ranges: list[tuple[int, int, int]] = []    # (material id, first index, count)
        self._textures: dict[int, object] = {}          # id(array) -> GL texture
        self.mesh = None
        self.origin = None
        self.bounds = None

    # -- geometry ---------------------------------------------------------------------------
    def upload(self, mesh, origin) -> None:
        """(Re-)upload the mesh with positions relative to ``origin``; faces sorted by material
        so one draw call per material binds that material's textures."""
        self.release_geometry()
        self.mesh, self.origin = mesh, np.asarray(origin, dtype=np.float64)
        pos = (mesh.positions.astype(np.float64) - self.origin).astype(np.float32)
        uv = mesh.uvs if mesh.uvs is not None else np.zeros((len(pos), 2), np.float32)
        vbo = GBUFFER_VERTEX.zeros(len(pos))
        vbo["position"], vbo["normal"], vbo["uv"], vbo["tangent"] = (pos, mesh.normals, uv,
                                                                     mesh.tangents)
        order = np.argsort(mesh.material_ids, kind="stable")
        idx = mesh.indices[order].astype("u4")
        mids = mesh.material_ids[order]
        starts = np.flatnonzero(np.r_[True, mids[1:] != mids[:-1]]) if len(mids) else np.zeros(0, int)
        ends = np.r_[starts[1:], len(mids)]
        self.ranges = [(int(mids[s]), int(s) * 3, int(e - s) * 3) for s, e in zip(starts, ends)]
        vb = self.ctx.buffer(vbo.tobytes())
        ib = self.ctx.buffer(idx.tobytes() if len(idx) else b"\0" * 12)
        self._buffers = [vb, ib]
        self.vao = self.ctx.vertex_array(
            self.prog, [(vb, GBUFFER_VERTEX.vertex_format(),
                         *(f"in_{f.name}" for f in GBUFFER_VERTEX.fields))],
            index_buffer=ib, index_element_size=4)
        self.bounds = mesh.bounds() if mesh.n_faces else (np.zeros(3), np.ones(3))

    def _texture(self, array):
        key = id(array)
        tex = self._textures.get(key)
        if tex is None:
            a = np.ascontiguousarray(array, dtype="f4")
            if a.ndim == 2:
                a = a[..., None]
            h, w, c = a.shape
            tex = self.ctx.texture((w, h), c, a.tobytes(), dtype="f4")
            tex.build_mipmaps()
            tex.repeat_x = tex.repeat_y = True
            self._textures[key] = (tex, array)      # keep the array alive: its id is the key
            return tex
        return tex[0]

    # -- rasterise --------------------------------------------------------------------------
    def render(self, camera: Camera, materials, tile=None, jitter=(0.0, 0.0)) -> dict:
        """Rasterise (each pixel sampled at its centre + ``jitter`` pixels); returns receivers
        (n, RECEIVER_FLOATS) float32 in image order (row 0 at the top; ``RECEIVER.view`` reads
        them as records), ``coverage`` (h, w) bool and the tile size."""
        import moderngl
        x0, y0, w, h = tile if tile is not None else (0, 0, camera.width, camera.height)
        ctx = self.ctx
        colors = [ctx.texture((w, h), 4, dtype="f4") for _ in range(TARGETS)]
        depth = ctx.depth_texture((w, h))
        fbo = ctx.framebuffer(colors, depth)
        try:
            fbo.use()
            fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
            if self.vao is not None and self.ranges:
                lo, hi = self.bounds
                lo = np.asarray(lo, float) - self.origin
                hi = np.asarray(hi, float) - self.origin
                near, far = near_far(Camera(camera.position - self.origin, camera.look_at - self.origin,
                                            camera.up, camera.fov_y_deg, camera.width, camera.height),
                                     lo, hi)
                near = max(near, 1e-4)
                self.prog["u_view"].write(gl_mat(relative_view(camera, self.origin)))
                self.prog["u_proj"].write(gl_mat(tile_projection(camera, near, far, tile, jitter)))
                self.prog["u_camera"].value = tuple((camera.position - self.origin).tolist())
                ctx.enable(moderngl.DEPTH_TEST)
                ctx.disable(moderngl.CULL_FACE)
                for mid, first, count in self.ranges:
                    self._set_material(mid, materials[mid] if mid < len(materials) else materials[-1])
                    self.vao.render(moderngl.TRIANGLES, vertices=count, first=first)
            planes = [np.frombuffer(fbo.read(components=4, dtype="f4", attachment=k), "f4")
                      .reshape(h, w, 4)[::-1] for k in range(TARGETS)]
        finally:
            fbo.release()
            depth.release()
            for c in colors:
                c.release()
            bind_anchor()
        cover = planes[0][..., 3] > 0.5
        ys, xs = np.nonzero(cover)
        rec = np.empty((len(ys), RECEIVER_FLOATS), dtype=np.float32)
        sw = RECEIVER.slot_words
        for k in range(TARGETS):                  # slot k of every receiver = render target k
            rec[:, sw * k:sw * (k + 1)] = planes[k][ys, xs]
        RECEIVER.view(rec)["pixel"] = (ys * w + xs).astype(np.uint32)
        return {"receivers": rec, "coverage": cover, "width": w, "height": h,
                "bytes": RECEIVER.nbytes * w * h + 4 * w * h}

    def _set_material(self, mid: int, m) -> None:
        prog = self.prog
        prog["u_material_id"].value = float(mid)
        for name in TEXTURED_PARAMS:       # the factors the textures multiply (u_base_color, ...)
            v = getattr(m, name)
            prog[f"u_{name}"].value = (tuple(float(c) for c in v) if name == "base_color"
                                       else float(v))
        for name, arr in (("base", m.base_color_texture), ("mr", m.metallic_roughness_texture),
                          ("normal", m.normal_texture)):
            unit = TEXTURE_UNITS[name]
            has = arr is not None and self.mesh.uvs is not None
            prog[f"u_has_{name}_tex"].value = has
            if has:
                self._texture(arr).use(location=unit)
            if f"u_{name}_tex" in prog:
                prog[f"u_{name}_tex"].value = unit

    def release_geometry(self) -> None:
        if self.vao is not None:
            self.vao.release()
        for b in self._buffers:
            b.release()
        self.vao, self._buffers, self.ranges = None, [], []

    def release(self) -> None:
        self.release_geometry()
        for tex, _ in self._textures.values():
            tex.release()
        self._textures.clear()
