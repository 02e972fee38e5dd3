"""The G-buffer: positions against ray casting, material factors x textures, normal maps, tiles,
and the environment map's cube faces."""

from __future__ import annotations

import numpy as np

from tests.support import scenes as S
from app.camera import Camera
from app.cloud import PointCloud
from app.material import Material
from app.pbgi.envmap import EnvironmentMap, fill_holes
from app.pbgi.gbuffer import GBuffer, tile_projection
from app.render.splat import SplatRenderer

ORIGIN = np.array([100.0, -50.0, 20.0])       # far from 0: positions are relative to it


def _quad_gbuffer(ctx, material, size=0.8):
    gb = GBuffer(ctx)
    gb.upload(S.quad(ORIGIN + (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), size), ORIGIN)
    cam = Camera(ORIGIN + (0.1, -0.05, 1.5), ORIGIN + (0.1, -0.05, 0.0), fov_y_deg=30,
                 width=16, height=12)
    return gb, cam, gb.render(cam, [material])


def test_positions_match_ray_casting(ctx):
    gb, cam, out = _quad_gbuffer(ctx, Material())
    rec = out["receivers"]
    pix = np.ascontiguousarray(rec[:, 3]).view(np.uint32)
    origin, dirs = cam.pixel_rays()
    d = dirs.reshape(-1, 3)[pix]
    t = (ORIGIN[2] - origin[2]) / d[:, 2]                      # plane z = ORIGIN.z
    expect = origin + t[:, None] * d - ORIGIN
    assert len(rec) > 50
    assert np.allclose(rec[:, 0:3], expect, atol=1e-4)
    assert np.allclose(rec[:, 4:7], (0, 0, 1), atol=1e-5)      # flat quad: the geometric normal
    hits = np.abs(origin[0] + t * d[:, 0] - ORIGIN[0]) < 0.39
    assert hits.all()


def test_factors_times_textures(ctx):
    h, w = 4, 4
    base = np.zeros((h, w, 3), np.float32)
    base[...] = (0.5, 0.25, 1.0)
    mr = np.zeros((h, w, 3), np.float32)
    mr[..., 1], mr[..., 2] = 0.5, 0.25                          # G = roughness, B = metallic
    mat = Material(base_color=(0.8, 0.8, 0.4), roughness=0.6, metallic=0.8,
                   base_color_texture=base, metallic_roughness_texture=mr)
    _, _, out = _quad_gbuffer(ctx, mat)
    rec = out["receivers"]
    assert np.allclose(rec[:, 12:15], (0.4, 0.2, 0.4), atol=1e-4)
    assert np.allclose(rec[:, 11], 0.3, atol=1e-4)              # roughness 0.6 x 0.5
    assert np.allclose(rec[:, 15], 0.2, atol=1e-4)              # metallic 0.8 x 0.25


def test_normal_map_tilts_the_shading_normal(ctx):
    """A constant tangent-space normal (sin 30 deg along +u) tilts the normal towards the
    tangent; the tangent stays orthogonal to it."""
    q = S.quad((0, 0, 0), (0, 0, 1), 1.0)
    t_world = q.tangents[0, :3].astype(float)
    tilt = np.array([np.sin(np.radians(30)), 0.0, np.cos(np.radians(30))])
    nmap = np.broadcast_to((tilt * 0.5 + 0.5).astype(np.float32), (4, 4, 3)).copy()
    _, _, out = _quad_gbuffer(ctx, Material(normal_texture=nmap))
    n = out["receivers"][:, 4:7].astype(float)
    expect = tilt[0] * t_world + tilt[2] * np.array([0, 0, 1.0])
    assert np.allclose(n, expect, atol=2e-3)
    assert np.allclose(np.einsum("ij,ij->i", n, out["receivers"][:, 8:11]), 0, atol=1e-4)


def test_shading_normals_face_the_viewer(ctx):
    """Seen from behind, an open quad's normal is flipped; normals never face away (n.v >= 0.01)."""
    gb = GBuffer(ctx)
    gb.upload(S.quad((0, 0, 0), (0, 0, 1), 1.0), np.zeros(3))
    cam = Camera((0.2, 0.1, -1.5), (0, 0, 0), fov_y_deg=30, width=8, height=8)
    rec = gb.render(cam, [Material()])["receivers"]
    v = cam.position - rec[:, 0:3]
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    assert np.allclose(rec[:, 4:7], (0, 0, -1), atol=1e-5)
    assert (np.einsum("ij,ij->i", rec[:, 4:7], v) >= 0.0099).all()


def test_tile_projection_selects_the_same_rays():
    cam = Camera((0, 0, 3), (0, 0, 0), fov_y_deg=50, width=40, height=30)
    full = cam.projection(0.1, 10)
    sub = tile_projection(cam, 0.1, 10, (10, 5, 20, 10))
    _, dirs = cam.pixel_rays()
    view = cam.view()
    for y, x in ((5, 10), (14, 29), (9, 17)):
        d = view[:3, :3] @ dirs[y, x]                            # eye space
        clip = sub @ np.r_[d * 2.0, 1.0]
        ndc = clip[:2] / clip[3]
        px = (ndc[0] + 1) / 2 * 20 + 10 - 0.5
        py = (1 - ndc[1]) / 2 * 10 + 5 - 0.5
        assert np.allclose((px, py), (x, y), atol=1e-6)
    assert np.allclose(tile_projection(cam, 0.1, 10, None), full)


def test_fill_holes_keeps_covered_pixels_and_fills_the_rest():
    rng = np.random.default_rng(0)
    img = np.zeros((16, 16, 4), np.float32)
    img[..., :3] = rng.random((16, 16, 3))
    covered = rng.random((16, 16)) > 0.3
    img[..., 3] = covered
    out = fill_holes(img)
    assert np.allclose(out[covered], img[..., :3][covered])
    assert (out[~covered] > 0).all()
    const = np.zeros((8, 8, 4), np.float32)
    const[..., :3], const[::3, ::2, 3] = 2.5, 1.0
    assert np.allclose(fill_holes(const), 2.5)


def test_cube_map_faces_look_where_they_should(ctx):
    """Sample the cube map in random directions from a compute shader: the radiance equals the
    colour-coded wall position the direction hits (ray-box intersection, computed here)."""
    c0 = S.box_room(0.03)
    cloud = PointCloud(c0.positions, c0.normals, (c0.positions + [2, 1, 2]).astype("f4"))
    centre = np.array([0.0, 1.0, 0.0])
    env = EnvironmentMap.of_splats(ctx, SplatRenderer(cloud, ctx=ctx), centre, 64)
    rng = np.random.default_rng(1)
    d = rng.normal(size=(300, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    hi, lo = np.array([1.0, 2.0, 1.0]) - centre, np.array([-1.0, 0.0, -1.0]) - centre
    with np.errstate(divide="ignore"):
        t = np.min(np.where(d > 0, hi / d, np.where(d < 0, lo / d, np.inf)), axis=1)
    expect = centre + t[:, None] * d + [2, 1, 2]
    got = S.sample_cube_map(ctx, env.texture, d)
    err = np.abs(got - expect).max(axis=1)
    assert np.median(err) < 0.05 and np.percentile(err, 95) < 0.1
