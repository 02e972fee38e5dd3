"""An HDRI lighting the asset (app/pbgi/hdri.py): the panorama's directions land on the right
cube-map texels, a sun's energy survives the resampling, the white furnace holds, a rotation turns
the light, and the background shows the panorama."""

from __future__ import annotations

import numpy as np
import pytest

from tests.support import scenes as S
from tests.support.scenes import albedo_of_cos, view_cos
from app.camera import Camera
from app.errors import ScanlightError
from app.pbgi import brdf
from app.pbgi.envmap import EnvironmentMap
from app.pbgi.hdri import hdri_backdrop, hdri_faces, make_hdri
from app.pbgi.renderer import Relighter, RenderParams
from app.render.equirect import direction_to_uv

CAM = S.look((0.0, 0.0, 1.6), (0.0, 0.0, 0.0), 32, 45)
FURNACE_CAM = S.look((0.0, 0.2, 1.6), (0.0, 0.0, 0.0), 24, 45)   # test_pbgi_render's


def _pano_of(f, w=256):
    """A panorama whose pixel in direction d holds f(d) (exact at the pixel centres)."""
    h = w // 2
    lon = ((np.arange(w) + 0.5) / w - 0.5) * 2 * np.pi
    lat = (0.5 - (np.arange(h) + 0.5) / h) * np.pi
    lo, la = np.meshgrid(lon, lat)
    d = np.stack([np.cos(la) * np.sin(lo), np.sin(la), -np.cos(la) * np.cos(lo)], axis=-1)
    return f(d.reshape(-1, 3)).reshape(h, w, 3).astype(np.float32)


def _colour(d):
    return 0.5 + 0.5 * d      # smooth, different in every direction and channel


def test_the_pixel_directions_match_the_lookup():
    """_pano_of's own directions, through direction_to_uv, land on their pixel centres."""
    w, h = 64, 32
    pano = _pano_of(lambda d: d, w)
    x, y = direction_to_uv(pano.reshape(-1, 3).astype(np.float64), w, h)
    xs, ys = np.meshgrid(np.arange(w), np.arange(h))
    assert np.allclose(x, xs.ravel(), atol=1e-3) and np.allclose(y, ys.ravel(), atol=1e-3)


def test_cube_map_texels_hold_the_panorama_in_their_direction(ctx):
    """Sampled in random directions from a compute shader, the HDRI's cube map returns the
    panorama's radiance in that direction (rotated by 30 degrees): the faces' orientation and
    their upload agree with the equirectangular convention."""
    rot = 30.0
    env = EnvironmentMap(ctx, hdri_faces(make_hdri(_pano_of(_colour), rot), 64), np.zeros(3))
    rng = np.random.default_rng(2)
    d = rng.normal(size=(400, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    c, s = np.cos(np.radians(-rot)), np.sin(np.radians(-rot))
    d_pano = np.c_[c * d[:, 0] + s * d[:, 2], d[:, 1], -s * d[:, 0] + c * d[:, 2]]
    expect = _colour(d_pano)
    got = S.sample_cube_map(ctx, env.texture, d)
    err = np.abs(got - expect).max(axis=1)
    assert np.median(err) < 0.01 and err.max() < 0.04, (np.median(err), err.max())
    env.release()


def _solid_angles(face: int) -> np.ndarray:
    t = (np.arange(face) + 0.5) / face * 2 - 1
    u, v = np.meshgrid(t, t)
    return (2.0 / face) ** 2 / (1 + u * u + v * v) ** 1.5


def test_a_small_sun_keeps_its_energy():
    """A 4 x 2-pixel sun 10^4 times brighter than the sky of a 2048 x 1024 panorama: the cube
    faces (32 px) integrate to the panorama's within 1% (one bilinear lookup per texel would hit
    or miss the sun: 8 x 8 lookups per texel were still 1.4% off)."""
    w, h = 2048, 1024
    pano = np.full((h, w, 3), 0.1, np.float32)
    pano[300:302, 1400:1404] = 1e4
    lat = (0.5 - (np.arange(h) + 0.5) / h) * np.pi
    omega = (2 * np.pi / w) * (np.pi / h) * np.cos(lat)
    expect = float((pano[..., 0] * omega[:, None]).sum())
    faces = hdri_faces(make_hdri(pano), 32)
    got = sum(float((f[..., 0] * _solid_angles(32)).sum()) for f in faces)
    assert abs(got / expect - 1) < 0.01, (got, expect)


@pytest.fixture(scope="module")
def lit():
    """The white furnace's sphere, in a scan 5x brighter than the HDRI: what lights it shows."""
    r = Relighter()
    r.set_cloud(S.furnace_shell(4000, radius=2.0, radiance=5.0))
    r.set_asset(S.sphere((0.0, 0.0, 0.0), 0.5, subdivisions=4))
    yield r
    r.release()


@pytest.mark.parametrize("mode", ["classic", "hybrid", "envmap"])
def test_white_furnace_under_a_constant_hdri(lit, mode):
    """A constant HDRI of radiance 1: every pixel is the BRDF's directional albedo (numpy), in
    every mode (an HDRI is gathered through the environment map whatever the mode), and not the
    scan's 5."""
    mat = S.diffuse(0.5, roughness=0.5)
    lit.set_hdri(make_hdri(np.ones((64, 128, 3), np.float32), source="constant"))
    try:
        res = lit.render(FURNACE_CAM, [mat], RenderParams(mode=mode, microbuffer=24))
    finally:
        lit.set_hdri(None)
    assert res.stats.completed and res.stats.mode == "envmap" and res.stats.hdri == "constant"
    pix, cos_v = view_cos(lit, FURNACE_CAM, mat)
    got = res.image.reshape(-1, 4)[pix, :3]
    expect = albedo_of_cos(brdf.pack_params(mat), cos_v)
    assert np.abs(got / expect[:, None] - 1).max() < 0.02


def test_rotating_the_hdri_turns_the_light(lit):
    """Red light from +x, blue from -x: the sphere's right side (+x, seen from +z) is red; the
    HDRI rotated by 180 degrees gives the mirror image; by 90 degrees (counter-clockwise seen
    from above) the red light comes from -z, behind the sphere, and the blue from the camera's
    side: the sphere turns blue, the same on its left and right."""
    mat = S.diffuse(0.8, roughness=0.5)
    pano = _pano_of(lambda d: np.where(d[:, :1] > 0, [[1.0, 0.0, 0.0]], [[0.0, 0.0, 1.0]]))
    imgs = {}
    for rot in (0.0, 180.0, 90.0):
        lit.set_hdri(make_hdri(pano, rot))
        imgs[rot] = lit.render(CAM, [mat], RenderParams(mode="envmap")).image
    lit.set_hdri(None)
    a, b = imgs[0.0], imgs[180.0]
    cov = a[..., 3] > 0.99
    right, left = cov.copy(), cov.copy()
    right[:, :20], left[:, 12:] = False, False   # away from the terminator in the middle
    assert a[right, 0].mean() > 2 * a[right, 2].mean()
    assert a[left, 2].mean() > 2 * a[left, 0].mean()
    mirrored = b[:, ::-1]
    both = cov & (mirrored[..., 3] > 0.99)
    assert np.abs(a[both, :3] - mirrored[both, :3]).max() < 0.05 * a[both, :3].max()
    c = imgs[90.0]
    assert c[cov, 2].mean() > 4 * c[cov, 0].mean()
    assert np.abs(c[both, :3] - c[:, ::-1][both, :3]).max() < 0.05 * c[both, :3].max()


def test_the_background_is_the_panorama(lit):
    cam = Camera((0, 0, 0), (0, 0, -1), fov_y_deg=60, width=16, height=8)
    pano = _pano_of(_colour)
    lit.set_hdri(make_hdri(pano))
    try:
        bg = lit.background(cam)
    finally:
        lit.set_hdri(None)
    _, rays = cam.pixel_rays()
    assert bg.shape == (8, 16, 4) and (bg[..., 3] == 1).all()
    assert np.abs(bg[..., :3] - _colour(rays.reshape(-1, 3)).reshape(8, 16, 3)).max() < 0.02
    assert np.array_equal(bg, hdri_backdrop(make_hdri(pano), cam))


@pytest.mark.parametrize("shape, why", [((64, 64, 3), "twice as wide"),
                                        ((1, 2, 3), "twice as wide"),
                                        ((32, 64), "RGB")])
def test_bad_hdris_are_refused(shape, why):
    with pytest.raises(ScanlightError, match=why):
        make_hdri(np.ones(shape, np.float32), source="x.exr")


def test_black_or_nan_hdris_are_refused():
    with pytest.raises(ScanlightError, match="black"):
        make_hdri(np.zeros((8, 16, 3), np.float32))
    bad = np.ones((8, 16, 3), np.float32)
    bad[0, 0, 0] = np.nan
    with pytest.raises(ScanlightError, match="NaN"):
        make_hdri(bad)
