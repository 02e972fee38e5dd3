"""Point-splat rendering of a cloud (the room background, capture previews, the viewer).

Vertices (SPLAT_VERTEX, one buffer per field) and the target's texels (ROOM_TEXEL) are declared
in app/render/gpu_layout.py, which generates splat.glsl's side of them."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from app.camera import Camera
from app.cloud import PointCloud
from app.render.context import get_context
from app.render.gpu_layout import ROOM_TEXEL, SPLAT_VERTEX
from app.render.programs import load_program


def splat_radius(positions: np.ndarray, sample: int = 20000, seed: int = 0) -> float:
    """A splat radius that closes the gaps: about twice the median nearest-neighbour distance (random samples leave holes at 1x)."""
    if len(positions) < 2:
        return 0.01
    rng = np.random.default_rng(seed)
    idx = rng.choice(len(positions), min(sample, len(positions)), replace=False)
    d, _ = cKDTree(positions).query(positions[idx], k=2)
    spacing = float(np.median(d[:, 1]))
    return max(2.0 * spacing, 1e-6)


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
    return max(far * 1e-4, 1e-3), far


def gl_mat(m: np.ndarray) -> bytes:
    """A numpy row-major matrix as GLSL column-major mat4 bytes."""
    return np.asarray(m, dtype="f4").tobytes(order="F")


class SplatRenderer:
    """Uploads a cloud once; renders it from any camera into an RGBA32F image."""

    def __init__(self, cloud: PointCloud, radius: float | None = None, ctx=None):
        self.ctx = ctx or get_context()
        self.prog = load_program(self.ctx, "splat.glsl")
        self.origin = cloud.positions.mean(axis=0) if len(cloud) else np.zeros(3)
        self.bounds = cloud.bounds() if len(cloud) else (np.zeros(3), np.ones(3))
        self.radius = splat_radius(cloud.positions) if radius is None else float(radius)
        rel = SPLAT_VERTEX.field_array("position", cloud.positions - self.origin)
        self.vbo_pos = self.ctx.buffer(rel.tobytes())
        self.vbo_col = self.ctx.buffer(SPLAT_VERTEX.field_array("color", cloud.colors).tobytes())
        self.vao = self.ctx.vertex_array(self.prog, SPLAT_VERTEX.vertex_content(
            {"position": self.vbo_pos, "color": self.vbo_col}))
        self.count = len(cloud)

    def set_colors(self, colors: np.ndarray) -> None:
        """Swap LDR/HDR/difference colours without re-uploading positions."""
        self.vbo_col.write(SPLAT_VERTEX.field_array("color", colors).tobytes())

    def draw(self, camera: Camera, scale: float = 1.0) -> None:
        """Draw into the currently bound framebuffer (depth test on)."""
        import moderngl
        near, far = near_far(camera, *self.bounds)
        self.prog["u_view"].write(gl_mat(relative_view(camera, self.origin)))
        self.prog["u_proj"].write(gl_mat(camera.projection(near, far)))
        self.prog["u_radius"].value = self.radius
        self.prog["u_pixels_per_unit"].value = camera.height / (2 * np.tan(np.radians(camera.fov_y_deg) / 2))
        self.prog["u_scale"].value = float(scale)
        self.ctx.enable(moderngl.DEPTH_TEST | moderngl.PROGRAM_POINT_SIZE)
        self.vao.render(moderngl.POINTS, vertices=self.count)

    def render(self, camera: Camera, scale: float = 1.0) -> np.ndarray:
        """(H, W, 4) float32 image of ROOM_TEXEL texels (radiance x ``scale``, coverage = 1
        where a splat covers the pixel), row 0 at the top."""
        w, h = camera.width, camera.height
        color = self.ctx.texture((w, h), ROOM_TEXEL.texel_components, dtype=ROOM_TEXEL.texture_dtype)
        depth = self.ctx.depth_texture((w, h))
        fbo = self.ctx.framebuffer([color], depth)
        try:
            fbo.use()
            fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
            self.draw(camera, scale)
            texels = ROOM_TEXEL.view(fbo.read(components=ROOM_TEXEL.texel_components,
                                              dtype=ROOM_TEXEL.texture_dtype))
            img = ROOM_TEXEL.flat(texels).reshape(h, w, ROOM_TEXEL.words)
        finally:
            fbo.release(); color.release(); depth.release()
            from app.render.context import bind_anchor
            bind_anchor()
        return img[::-1].copy()

    def release(self) -> None:
        for obj in (self.vao, self.vbo_pos, self.vbo_col):
            obj.release()
