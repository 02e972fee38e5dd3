"""Small analytic scenes for the PBGI tests (not a test module: imported by tests/pbgi/test_pbgi_*.py)."""

from __future__ import annotations

import numpy as np

from app.camera import Camera
from app.cloud import PointCloud
from app.io.mesh import build_mesh, make_sphere_mesh, transform_mesh
from app.material import Material
from app.pbgi import brdf


def furnace_shell(n: int = 20000, radius: float = 2.0, radiance: float = 1.0, seed: int = 0):
    """A closed sphere of inward-facing points of one constant radiance: the white furnace."""
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    return PointCloud(v * radius, (-v).astype(np.float32), np.full((n, 3), radiance, np.float32),
                      hdr=True, source="test:furnace")


def _grid(origin, u, v, spacing, rng):
    nu = max(1, int(round(np.linalg.norm(u) / spacing)))
    nv = max(1, int(round(np.linalg.norm(v) / spacing)))
    a = (np.arange(nu)[:, None] + rng.random((nu, nv))) / nu
    b = (np.arange(nv)[None, :] + rng.random((nu, nv))) / nv
    return (np.asarray(origin, float) + a.reshape(-1, 1) * np.asarray(u, float)
            + b.reshape(-1, 1) * np.asarray(v, float))


# Box room: x, z in [-1, 1], y in [0, 2]; (origin, u, v, inward normal, radiance)
ROOM_WALLS = (
    ((-1, 0, -1), (2, 0, 0), (0, 0, 2), (0, 1, 0), (0.30, 0.25, 0.20)),    # floor
    ((-1, 2, -1), (0, 0, 2), (2, 0, 0), (0, -1, 0), (0.50, 0.50, 0.50)),   # ceiling
    ((-1, 0, -1), (0, 2, 0), (0, 0, 2), (1, 0, 0), (0.60, 0.10, 0.10)),    # x = -1, red
    ((1, 0, -1), (0, 0, 2), (0, 2, 0), (-1, 0, 0), (0.10, 0.50, 0.10)),    # x = +1, green
    ((-1, 0, -1), (2, 0, 0), (0, 2, 0), (0, 0, 1), (0.20, 0.20, 0.60)),    # z = -1, blue
    ((-1, 0, 1), (0, 2, 0), (2, 0, 0), (0, 0, -1), (0.40, 0.40, 0.30)),    # z = +1
)
LIGHT = ((-0.25, 2.0, -0.25), (0.5, 0, 0), (0, 0, 0.5), 20.0)  # on the ceiling


def box_room(spacing: float = 0.05, light: float = LIGHT[3], seed: int = 0,
             panel_spacing: float | None = None, panel_drop: float = 0.05) -> PointCloud:
    """A closed box of coloured walls with a bright square light in the middle of the ceiling.

    With ``panel_spacing`` the light is instead a separate, finer-sampled panel hanging
    ``panel_drop`` below the ceiling (emitting downwards): no coplanar ceiling points compete
    with it, and its edges are sharp at the panel's own sampling.
    """
    rng = np.random.default_rng(seed)
    pos, nrm, col = [], [], []
    lo, u, v, _ = LIGHT
    if panel_spacing is not None:
        p = _grid((lo[0], lo[1] - panel_drop, lo[2]), u, v, panel_spacing, rng)
        pos.append(p)
        nrm.append(np.broadcast_to(np.array([0.0, -1.0, 0.0]), p.shape))
        col.append(np.full(p.shape, light))
        light = None
    for o, a, b, n, c in ROOM_WALLS:
        p = _grid(o, a, b, spacing, rng)
        rad = np.broadcast_to(np.asarray(c, float), p.shape).copy()
        if n == (0, -1, 0) and light is not None:  # ceiling: the light square
            inside = ((p[:, 0] >= lo[0]) & (p[:, 0] <= lo[0] + u[0])
                      & (p[:, 2] >= lo[2]) & (p[:, 2] <= lo[2] + v[2]))
            rad[inside] = light
        pos.append(p)
        nrm.append(np.broadcast_to(np.asarray(n, float), p.shape))
        col.append(rad)
    return PointCloud(np.concatenate(pos), np.concatenate(nrm).astype(np.float32),
                      np.concatenate(col).astype(np.float32), hdr=True, source="test:box-room")


def sphere_in_box_room(spacing: float = 0.1):
    """A Relighter holding box_room(spacing) and a 0.3 m sphere at (0, 0.8, 0): the small scene
    many tests light."""
    from app.pbgi.renderer import Relighter
    r = Relighter()
    r.set_cloud(box_room(spacing))
    r.set_asset(sphere((0.0, 0.8, 0.0), 0.3, subdivisions=3))
    return r


def local_spacing(positions, k: int = 4) -> np.ndarray:
    """Per point, the distance to its k-th neighbour: disc radii for the reference that follow
    the local sampling (a finer light panel gets smaller discs)."""
    from scipy.spatial import cKDTree
    d, _ = cKDTree(positions).query(positions, k=k + 1)
    return d[:, k]


def sphere(centre=(0.0, 0.0, 0.0), radius: float = 0.5, subdivisions: int = 4):
    m = np.eye(4) * 2.0 * radius
    m[3, 3] = 1.0
    m[:3, 3] = centre
    return transform_mesh(make_sphere_mesh(subdivisions), m)


def quad(centre, normal, size: float = 0.2):
    """A square facing ``normal`` (two triangles, counter-clockwise seen from the normal side)."""
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    t = np.cross(n, [0.0, 1.0, 0.0] if abs(n[1]) < 0.9 else [1.0, 0.0, 0.0])
    t /= np.linalg.norm(t)
    b = np.cross(n, t)
    c = np.asarray(centre, float)
    h = size / 2
    pos = np.array([c - h * t - h * b, c + h * t - h * b, c + h * t + h * b, c - h * t + h * b])
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    return build_mesh(pos, [[0, 1, 2], [0, 2, 3]], np.tile(n, (4, 1)), uv, source="test:quad")


def diffuse(albedo: float = 0.5, roughness: float = 0.5) -> Material:
    return Material(base_color=(albedo,) * 3, roughness=roughness, specular=0.0)


def look(position, at, size: int = 24, fov: float = 40.0) -> Camera:
    return Camera(position, at, fov_y_deg=fov, width=size, height=size)


def reference_gbuffer(relighter, camera, material: Material, tile=None) -> dict:
    """The receivers of a render as a G-buffer for app.pbgi.reference (world coordinates)."""
    from app.pbgi.brdf import pack_params
    from app.pbgi.gpu_layout import receiver_params
    gb = relighter.gbuffer.render(camera, [material], tile)
    rec = gb["receivers"].astype(np.float64)
    pos = rec[:, 0:3] + relighter.origin
    view = camera.position - pos
    # the gather's rule: base colour, metallic and roughness (textured) from the receiver
    params = receiver_params(np.repeat(pack_params(material)[None], len(rec), axis=0),
                             gb["receivers"])
    pixel = np.ascontiguousarray(gb["receivers"][:, 3]).view(np.uint32)
    return {"position": pos, "normal": rec[:, 4:7], "view": view / np.linalg.norm(view, axis=1,
            keepdims=True), "tangent": rec[:, 8:11], "params": params, "pixel": pixel,
            "width": gb["width"]}


def albedo_of_cos(params, cos_v: np.ndarray) -> np.ndarray:
    """The BRDF's directional albedo (numpy, Monte Carlo) at view angles cos_v, interpolated
    from a table: an isotropic material's albedo depends on the view angle only."""
    grid = np.linspace(0.02, 1.0, 50)
    v = np.stack([np.sqrt(1 - grid ** 2), np.zeros_like(grid), grid], axis=1)
    table = brdf.directional_albedo(params, v, n_samples=1 << 14)[:, 0]
    return np.interp(cos_v, grid, table)


def view_cos(r, cam, mat):
    rec = r.gbuffer.render(cam, [mat])["receivers"]
    pos = rec[:, 0:3].astype(np.float64) + r.origin
    v = cam.position - pos
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    pix = np.ascontiguousarray(rec[:, 3]).view(np.uint32)
    return pix, np.einsum("ij,ij->i", v, rec[:, 4:7])


def sample_cube_map(ctx, texture, directions: np.ndarray) -> np.ndarray:
    """(N, 3) RGB of a cube texture looked up (textureLod, level 0) in (N, 3) directions by a
    compute shader: what the gather sees, independent of how the faces were made."""
    cs = ctx.compute_shader("""#version 430
        layout(local_size_x = 1) in;
        uniform samplerCube u_env;
        layout(std430, binding = 0) buffer D { vec4 d[]; };
        void main() { uint i = gl_GlobalInvocationID.x; d[i] = textureLod(u_env, d[i].xyz, 0.0); }""")
    d = np.asarray(directions, np.float64)
    buf = ctx.buffer(np.c_[d, np.zeros(len(d))].astype("f4").tobytes())
    try:
        buf.bind_to_storage_buffer(0)
        texture.use(0)
        cs["u_env"] = 0
        cs.run(len(d))
        return np.frombuffer(buf.read(), "f4").reshape(-1, 4)[:, :3].copy()
    finally:
        buf.release()
        cs.release()
