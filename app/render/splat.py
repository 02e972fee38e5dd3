"""Surface splatting of a cloud (the room background, capture previews, the viewer).

Each point is a disc in the plane of its normal, its radius from the local point spacing
(``local_radii``). ``SplatRenderer.render``/``render_to`` run two raster passes of
shaders/splat.glsl, a depth pass (the front surface) and an additive pass in which every splat
within ``DEPTH_EPS`` x its radius of that surface adds weight x colour with a Gaussian weight,
then app/render/splat_fill.py normalises, fills small holes (push-pull) and optionally applies
eye-dome lighting. ``draw`` is the one-pass opaque variant (no blending, no hole filling).

Vertices (SPLAT_VERTEX, one buffer per field) and the target's texels (ROOM_TEXEL) are declared
in app/render/gpu_layout.py, which generates splat.glsl's side of them."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from app.camera import Camera
from app.cloud import PointCloud
from app.render.context import get_context
from app.render.gpu_layout import ROOM_TEXEL, SPLAT_TEX, SPLAT_VERTEX
from app.render.programs import load_program
from app.render.splat_fill import GUARD_PX, MAX_HOLE_PX, SplatFill

LOCAL_NEIGHBOURS = 4           # a point's radius: the distance to its 4th nearest neighbour ...
LOCAL_RADIUS_SCALE = 1.0       # ... times this (0.7 left gaps of 10+ px at 1280x800 close up)
RADIUS_CLAMP = (0.5, 2.0)      # ... kept within these multiples of the global radius
MIN_COS = 0.4                  # discs seen more edge-on are tilted towards the camera to this
DEPTH_EPS = 1.0                # splats within this x radius behind the front surface blend
MAX_POINT_PX = 255.0           # largest sprite asked of the GL (llvmpipe: 255)


def splat_radius(positions: np.ndarray, sample: int = 20000, seed: int = 0) -> float:
    """A splat radius that closes the gaps: about twice the median nearest-neighbour distance (random samples leave holes at 1x)."""
    if len(positions) < 2:
        return 0.01
    rng = np.random.default_rng(seed)
    idx = rng.choice(len(positions), min(sample, len(positions)), replace=False)
    d, _ = cKDTree(positions).query(positions[idx], k=2)
    spacing = float(np.median(d[:, 1]))
    return max(2.0 * spacing, 1e-6)


def local_radii(positions: np.ndarray, base: float, k: int | None = None) -> np.ndarray:
    """Per-point radius relative to ``base`` (the global radius): the distance to the k-th
    nearest neighbour x LOCAL_RADIUS_SCALE, clamped to RADIUS_CLAMP x base, so a sparse wall
    gets larger discs and a dense one smaller discs (one global radius leaves holes where the
    scan is sparse and blurs it where it is dense)."""
    n, k = len(positions), k or LOCAL_NEIGHBOURS
    if n <= k:
        return np.ones(n, np.float32)
    d, _ = cKDTree(positions).query(positions, k=k + 1)
    r = LOCAL_RADIUS_SCALE * d[:, k]
    return np.clip(r / base, *RADIUS_CLAMP).astype(np.float32)


def relative_view(camera: Camera, origin: np.ndarray) -> np.ndarray:
    """The camera's view matrix for positions expressed relative to ``origin`` (float64)."""
    shifted = Camera(camera.position - origin, camera.look_at - origin, camera.up,
                     camera.fov_y_deg, camera.width, camera.height)
    return shifted.view()


def near_far(camera: Camera, lo: np.ndarray, hi: np.ndarray) -> tuple[float, float]:
    """Near/far planes that enclose the box lo..hi as seen from the camera."""
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                        for z in (lo[2], hi[2])])
    far = float(np.linalg.norm(corners - camera.position, axis=1).max()) * 1.01 + 1e-3
    near = max(far * 1e-4, 1e-3)
    return near, max(far, 2.0 * near)   # a box round the eye (one point): far must pass near


def guard_camera(camera: Camera, guard: int) -> Camera:
    """``camera`` with ``guard`` more pixels on each side at the same pixel size (a wider field
    of view): the splats just outside the image then take part in its hole filling."""
    h = camera.height + 2 * guard
    fov = 2 * np.degrees(np.arctan(np.tan(np.radians(camera.fov_y_deg) / 2) * h / camera.height))
    return Camera(camera.position, camera.look_at, camera.up, fov, camera.width + 2 * guard, h)


def gl_mat(m: np.ndarray) -> bytes:
    """A numpy row-major matrix as GLSL column-major mat4 bytes."""
    return np.asarray(m, dtype="f4").tobytes(order="F")


class SplatRenderer:
    """Uploads a cloud once; renders it from any camera into an RGBA32F image.

    ``radius`` is the global radius (settable: the viewer scales it); each point's disc is that
    times its ``local_radii`` factor. Given explicitly, every point gets exactly ``radius``.
    ``categorical``: the colours are labels (the viewer's provenance view), so none may mix:
    the front disc shows alone (no blending) and holes take one neighbour's colour."""

    def __init__(self, cloud: PointCloud, radius: float | None = None, ctx=None):
        self.ctx = ctx or get_context()
        self.progs = [load_program(self.ctx, "splat.glsl",
                                   {"SPLAT_PASS": k, "MIN_COS": repr(MIN_COS)}) for k in range(4)]
        self.prog = self.progs[0]
        self.origin = cloud.positions.mean(axis=0) if len(cloud) else np.zeros(3)
        self.bounds = cloud.bounds() if len(cloud) else (np.zeros(3), np.ones(3))
        self.radius = splat_radius(cloud.positions) if radius is None else float(radius)
        factors = (local_radii(cloud.positions, self.radius) if radius is None
                   else np.ones(len(cloud), np.float32))
        rel = SPLAT_VERTEX.field_array("position", cloud.positions - self.origin)
        self.vbo_pos = self.ctx.buffer(rel.tobytes())
        self.vbo_col = self.ctx.buffer(SPLAT_VERTEX.field_array("color", cloud.colors).tobytes())
        self.vbo_nrm = self.ctx.buffer(SPLAT_VERTEX.field_array("normal", cloud.normals).tobytes())
        self.vbo_rad = self.ctx.buffer(SPLAT_VERTEX.field_array("radius", factors).tobytes())
        content = SPLAT_VERTEX.vertex_content({"position": self.vbo_pos, "color": self.vbo_col,
                                               "normal": self.vbo_nrm, "radius": self.vbo_rad})
        # the FAST pass (3) never reads the normal: its compiler drops in_normal
        self.vaos = [self.ctx.vertex_array(p, content, skip_errors=k == 3)
                     for k, p in enumerate(self.progs)]
        self.vao = self.vaos[0]
        self.count = len(cloud)
        self.fill = SplatFill(self.ctx)
        self.categorical = False
        self.max_point = MAX_POINT_PX
        try:
            gl_max = float(self.ctx.info["GL_ALIASED_POINT_SIZE_RANGE"][1])
            self.max_point = min(MAX_POINT_PX, gl_max)
        except (KeyError, TypeError, IndexError):
            pass

    def set_colors(self, colors: np.ndarray) -> None:
        """Swap LDR/HDR/difference colours without re-uploading positions."""
        self.vbo_col.write(SPLAT_VERTEX.field_array("color", colors).tobytes())

    def _uniforms(self, prog, camera: Camera, size, scale: float) -> None:
        near, far = near_far(camera, *self.bounds)
        values = {"u_radius": self.radius, "u_viewport": tuple(float(v) for v in size),
                  "u_max_point": self.max_point, "u_near": near, "u_scale": float(scale),
                  "u_eps": DEPTH_EPS}
        prog["u_view"].write(gl_mat(relative_view(camera, self.origin)))
        prog["u_proj"].write(gl_mat(camera.projection(near, far)))
        for key, val in values.items():
            if key in prog:
                prog[key].value = val

    def draw(self, camera: Camera, scale: float = 1.0) -> None:
        """Draw opaque discs into the currently bound framebuffer (depth test on); no blending
        and no hole filling (``render_to`` does those)."""
        import moderngl
        self._uniforms(self.prog, camera, (camera.width, camera.height), scale)
        self.ctx.enable(moderngl.DEPTH_TEST | moderngl.PROGRAM_POINT_SIZE)
        self.vao.render(moderngl.POINTS, vertices=self.count)

    def render_to(self, camera: Camera, color_tex, depth_tex=None, scale: float = 1.0,
                  eye_dome: bool = False, hole_px: int = MAX_HOLE_PX,
                  fast: bool = False) -> None:
        """The full backdrop into ``color_tex`` (RGBA32F, ROOM_TEXEL: radiance x ``scale``,
        coverage 1 where a splat or a filled hole is) and, when given, ``depth_tex`` (the front
        splats' window depth; filled holes keep the cleared 1.0). Both of the camera's size.
        ``fast``: the viewer's backdrop while its camera moves - camera-facing opaque sprites
        without the ray-disc test, the blending or the hole filling (several times cheaper at
        window sizes; the full backdrop follows when it stops)."""
        import moderngl
        ctx = self.ctx
        g = GUARD_PX
        wide = guard_camera(camera, g)
        size = (wide.width, wide.height)
        self.fill.targets(size)
        try:
            if depth_tex is not None:   # the camera's own front depth, for the caller
                depth_fbo = ctx.framebuffer(depth_attachment=depth_tex)
                self._depth_pass(camera, depth_fbo, scale, 3 if fast else 1)
                depth_fbo.release()
            if fast:
                self.fill.opaque_fbo.use()
                self.fill.opaque_fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
                ctx.enable_only(moderngl.DEPTH_TEST | moderngl.PROGRAM_POINT_SIZE)
                self._uniforms(self.progs[3], wide, size, scale)
                self.vaos[3].render(moderngl.POINTS, vertices=self.count)
                hole_px = 0
            elif self.categorical:        # labels: the front disc alone, weight 1
                self.fill.opaque_fbo.use()
                self.fill.opaque_fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
                ctx.enable_only(moderngl.DEPTH_TEST | moderngl.PROGRAM_POINT_SIZE)
                self._uniforms(self.progs[0], wide, size, scale)
                self.vaos[0].render(moderngl.POINTS, vertices=self.count)
            else:
                # 1. visibility: the front surface's depth
                self._depth_pass(wide, self.fill.depth_fbo, scale)
                # 2. accumulation of the splats on that surface (depth read, not attached)
                self.fill.accum_fbo.use()
                self.fill.accum_fbo.clear(0.0, 0.0, 0.0, 0.0)
                ctx.enable_only(moderngl.BLEND | moderngl.PROGRAM_POINT_SIZE)
                ctx.blend_func = moderngl.ONE, moderngl.ONE
                ctx.blend_equation = moderngl.FUNC_ADD
                self.fill.depth.use(location=SPLAT_TEX.FRONT)    # the sampler's layout(binding)
                self._uniforms(self.progs[2], wide, size, scale)
                self.vaos[2].render(moderngl.POINTS, vertices=self.count)
        finally:
            ctx.blend_func = moderngl.DEFAULT_BLENDING
            ctx.enable_only(moderngl.NOTHING)
        # 3. normalise, fill small holes, eye-dome lighting; crop the guard band
        self.fill.resolve(color_tex, eye_dome=eye_dome, hole_px=hole_px, guard=g,
                          pick=self.categorical)

    def _depth_pass(self, camera: Camera, fbo, scale: float, program: int = 1) -> None:
        import moderngl
        fbo.use()
        fbo.clear(depth=1.0)
        self.ctx.enable_only(moderngl.DEPTH_TEST | moderngl.PROGRAM_POINT_SIZE)
        self._uniforms(self.progs[program], camera, fbo.size, scale)
        self.vaos[program].render(moderngl.POINTS, vertices=self.count)

    def render(self, camera: Camera, scale: float = 1.0, eye_dome: bool = False,
               hole_px: int = MAX_HOLE_PX, fast: bool = False) -> np.ndarray:
        """(H, W, 4) float32 image of ROOM_TEXEL texels (radiance x ``scale``, coverage = 1
        where a splat covers the pixel or a small hole was filled), row 0 at the top."""
        w, h = camera.width, camera.height
        color = self.ctx.texture((w, h), ROOM_TEXEL.texel_components,
                                 dtype=ROOM_TEXEL.texture_dtype)
        try:
            self.render_to(camera, color, None, scale, eye_dome, hole_px, fast)
            texels = ROOM_TEXEL.view(color.read())
            img = ROOM_TEXEL.flat(texels).reshape(h, w, ROOM_TEXEL.words)
        finally:
            color.release()
            from app.render.context import bind_anchor
            bind_anchor()
        return img[::-1].copy()

    def release(self) -> None:
        for obj in (*self.vaos, self.vbo_pos, self.vbo_col, self.vbo_nrm, self.vbo_rad,
                    *self.progs):
            obj.release()
        self.fill.release()
