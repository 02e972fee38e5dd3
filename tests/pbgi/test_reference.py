"""CPU reference renderer (app/pbgi/reference.py) against analytic cases: white furnace, the
irradiance of a disc, occlusion by a nearer disc; exact nearest-hit and determinism."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad

from app.pbgi.brdf import directional_albedo, pack_params
from app.pbgi.reference import (estimate_disc_radius, lambert_brdf, nearest_disc_hit,
                                reference_render)

UP, DOWN = np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, -1.0])


def _fibonacci_sphere(n, radius=1.0):
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    phi = np.pi * (1 + 5 ** 0.5) * i
    s = np.sqrt(1 - z * z)
    return radius * np.stack([s * np.cos(phi), s * np.sin(phi), z], -1)


def _room(L=1.5, n=1500):
    """A closed sphere of inward-facing discs of constant radiance L."""
    pos = _fibonacci_sphere(n)
    return pos, -pos, np.full((n, 3), L)


def _receivers(n, normal=UP, view=UP, position=(0.0, 0.0, 0.0), **params):
    return {"position": np.tile(position, (n, 1)), "normal": np.tile(normal, (n, 1)),
            "view": np.tile(view, (n, 1)), "params": pack_params(**params)}


def _pooled(out, err):
    """Mean over pixels and its standard error (pixels are independent estimates)."""
    return out.mean(axis=0), np.sqrt((err ** 2).sum(axis=0)) / len(out)


def test_room_is_closed():
    """Every direction from inside the furnace hits a front face: no gaps between discs."""
    pos, nrm, _ = _room()
    r = estimate_disc_radius(pos)
    rng = np.random.default_rng(0)
    d = rng.normal(size=(5000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = rng.uniform(-0.3, 0.3, (5000, 3))
    idx, t, front = nearest_disc_hit(o, d, pos, nrm, r)
    assert np.all(idx >= 0) and np.all(front) and np.all((t > 0.4) & (t < 1.6))


def test_white_furnace_lambert():
    """Closed room of radiance L, Lambertian receiver of albedo a: L_o = a L for every normal
    and position inside (cosine sampling makes each sample exactly a L when nothing leaks)."""
    pos, nrm, col = _room(L=1.5)
    rng = np.random.default_rng(1)
    n = 12
    normals = rng.normal(size=(n, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    a = np.array([0.2, 0.5, 0.9])
    gb = {"position": rng.uniform(-0.3, 0.3, (n, 3)), "normal": normals, "view": normals,
          "params": pack_params(base_color=a)}
    out = reference_render(gb, pos, nrm, col, n_samples=256, seed=3, brdf=lambert_brdf)
    np.testing.assert_allclose(out, np.tile(a * 1.5, (n, 1)), rtol=1e-9)


@pytest.mark.parametrize("sampling", ["cosine", "mixture"])
def test_white_furnace_disney_lambert_limit(sampling):
    """Disney at the Lambert limit (roughness 1, specular/metallic/sheen/clearcoat/subsurface 0)
    with V = N: albedo = base (1 + 6/168) + integral of (1 - sqrt((1+mu)/2))^5 mu / (1 + mu)
    (see tests/pbgi/test_brdf.py), so L_o = L x that, within 4 standard errors and 2%."""
    pos, nrm, col = _room(L=2.0)
    base = np.array([0.2, 0.5, 0.8])
    gb = _receivers(16, base_color=base, roughness=1.0, specular=0.0, metallic=0.0, sheen=0.0,
                    clearcoat=0.0, subsurface=0.0)
    out, err = reference_render(gb, pos, nrm, col, n_samples=512, seed=0, sampling=sampling,
                                return_stderr=True)
    mean, se = _pooled(out, err)
    s = quad(lambda m: (1 - np.sqrt((1 + m) / 2)) ** 5 * m / (1 + m), 0, 1)[0]
    expected = 2.0 * (base * (1 + 6 / 168) + s)
    assert np.all(np.abs(mean - expected) < 4 * se + 1e-9)
    assert np.all(np.abs(mean - expected) < 0.02 * expected)


@pytest.mark.parametrize("sampling", ["cosine", "mixture"])
def test_white_furnace_glossy_anisotropic_rotated_frame(sampling):
    """Anisotropic rough metal in a rotated frame (normal, tangent and view all rotated): in
    the furnace L_o = L x directional albedo of the local view direction, which
    app.pbgi.brdf.directional_albedo computes in the canonical frame."""
    from scipy.spatial.transform import Rotation
    pos, nrm, col = _room(L=1.0)
    R = Rotation.from_euler("xyz", [0.7, -1.1, 2.0]).as_matrix()
    th = np.radians(40.0)
    v_loc = np.array([np.sin(th) * np.cos(0.5), np.sin(th) * np.sin(0.5), np.cos(th)])
    kw = dict(base_color=[0.9, 0.6, 0.3], metallic=1.0, roughness=0.4, anisotropic=0.5)
    gb = _receivers(16, normal=R @ UP, view=R @ v_loc, **kw)
    gb["tangent"] = np.tile(R @ np.array([1.0, 0.0, 0.0]), (16, 1))
    out, err = reference_render(gb, pos, nrm, col, n_samples=1024, seed=0, sampling=sampling,
                                return_stderr=True)
    mean, se = _pooled(out, err)
    alb, alb_se = directional_albedo(pack_params(**kw), v_loc, 16384, seed=1, return_stderr=True)
    assert np.all(np.abs(mean - alb) < 4 * np.hypot(se, alb_se))


@pytest.mark.parametrize("r,h", [(1.0, 1.0), (0.5, 2.0)])
def test_single_disc_overhead_irradiance(r, h):
    """A one-sided disc of radiance L, radius r, facing the receiver at height h on its axis:
    E = L pi r^2 / (r^2 + h^2), so a Lambertian receiver of albedo a reflects a L r^2/(r^2+h^2)."""
    a, L = 0.8, 3.0
    gb = _receivers(16, base_color=[a, a, a])
    out, err = reference_render(gb, [[0, 0, h]], [DOWN], [[L, L, L]], disc_radius=r,
                                n_samples=4096, seed=5, brdf=lambert_brdf, return_stderr=True)
    mean, se = _pooled(out, err)
    expected = a * L * r * r / (r * r + h * h)
    assert np.all(np.abs(mean - expected) < 4 * se)
    assert np.all(se < 0.02 * expected)  # the test has the power to see a 10% error


def test_disc_sidedness():
    """Seen from behind, a disc is black ("black", default), the same as its front ("emit"), or
    invisible ("cull"; the background shows through)."""
    gb = _receivers(4, base_color=[1, 1, 1])
    kw = dict(disc_radius=1.0, n_samples=1024, seed=1, brdf=lambert_brdf)
    back = reference_render(gb, [[0, 0, 1]], [UP], [[2, 2, 2]], **kw)
    assert np.all(back == 0)
    front = reference_render(gb, [[0, 0, 1]], [DOWN], [[2, 2, 2]], **kw)
    emit = reference_render(gb, [[0, 0, 1]], [UP], [[2, 2, 2]], backface="emit", **kw)
    np.testing.assert_array_equal(emit, front)
    # Lambert albedo 1 under a uniform background of 0.5 reflects exactly 0.5 per sample.
    culled = reference_render(gb, [[0, 0, 1]], [UP], [[2, 2, 2]], backface="cull",
                              background=0.5, **kw)
    np.testing.assert_allclose(culled, 0.5, rtol=1e-12)
    blocked = reference_render(gb, [[0, 0, 1]], [UP], [[2, 2, 2]], background=0.5, **kw)
    assert np.all(blocked < 0.3)  # the black back face hides half the sky (cone 1/2)


def test_occlusion_by_a_nearer_disc():
    """Emitter (radius 1 at height 2, radiance 1) behind a smaller blocker (radius 0.25 at
    height 1) inside its cone: the blocker removes its own cone, r_b^2/(r_b^2 + h_b^2), and
    adds its own radiance if it faces the receiver. Nearest-hit is what makes this right."""
    gb = _receivers(16, base_color=[1, 1, 1])
    e_cone = 1.0 / (1.0 + 4.0)                 # r^2/(r^2+h^2) of the emitter
    b_cone = 0.0625 / (0.0625 + 1.0)           # of the blocker
    kw = dict(disc_radius=np.array([1.0, 0.25]), n_samples=2048, seed=2, brdf=lambert_brdf,
              return_stderr=True)
    for blocker_normal, lb, expected in ((UP, 0.0, e_cone - b_cone),           # back: black
                                         (DOWN, 3.0, e_cone - b_cone + 3.0 * b_cone)):
        out, err = reference_render(gb, [[0, 0, 2], [0, 0, 1]], [DOWN, blocker_normal],
                                    [[1, 1, 1], [lb, lb, lb]], **kw)
        mean, se = _pooled(out, err)
        assert np.all(np.abs(mean - expected) < 4 * se)
    # A blocker behind the emitter changes nothing, bit for bit.
    only, _ = reference_render(gb, [[0, 0, 2]], [DOWN], [[1, 1, 1]], **dict(kw, disc_radius=1.0))
    behind, _ = reference_render(gb, [[0, 0, 2], [0, 0, 3]], [DOWN, DOWN],
                                 [[1, 1, 1], [5, 5, 5]], **kw)
    np.testing.assert_array_equal(only, behind)


def test_nearest_disc_hit_is_exact():
    """Against a per-ray, per-disc Python loop on a random clutter of overlapping discs."""
    rng = np.random.default_rng(4)
    c = rng.uniform(-1, 1, (60, 3))
    n = rng.normal(size=(60, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    r = rng.uniform(0.05, 0.4, 60)
    o = rng.uniform(-1.5, 1.5, (300, 3))
    d = rng.normal(size=(300, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    idx, t, front = nearest_disc_hit(o, d, c, n, r, chunk_elems=500)
    assert (idx >= 0).sum() > 50
    for k in range(len(o)):
        best, bj = np.inf, -1
        for j in range(len(c)):
            den = d[k] @ n[j]
            if abs(den) < 1e-12:
                continue
            tj = ((c[j] - o[k]) @ n[j]) / den
            if tj > 0 and np.linalg.norm(o[k] + tj * d[k] - c[j]) <= r[j] and tj < best:
                best, bj = tj, j
        assert idx[k] == bj
        if bj >= 0:
            assert t[k] == pytest.approx(best, rel=1e-9)
            assert front[k] == (d[k] @ n[bj] < 0)


def test_estimate_disc_radius_on_a_grid():
    h = 0.05
    g = np.stack(np.meshgrid(np.arange(20), np.arange(20), indexing="ij"), -1).reshape(-1, 2) * h
    pts = np.concatenate([g, np.zeros((len(g), 1))], 1)
    assert estimate_disc_radius(pts) == pytest.approx(h)


def test_determinism_shapes_and_mask():
    pos, nrm, col = _room(L=1.0, n=600)
    rng = np.random.default_rng(6)
    H, W = 4, 5
    normals = rng.normal(size=(H, W, 3))
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    mask = np.ones((H, W), bool)
    mask[0, 0] = False
    normals[0, 0] = np.nan  # empty G-buffer pixels may hold garbage
    gb = {"position": rng.uniform(-0.2, 0.2, (H, W, 3)), "normal": normals, "view": normals,
          "tangent": np.tile([1.0, 0.0, 0.0], (H, W, 1)), "mask": mask,
          "params": pack_params(roughness=0.3, anisotropic=0.5, metallic=0.5)}
    a = reference_render(gb, pos, nrm, col, n_samples=64, seed=11)
    assert a.shape == (H, W, 3) and np.all(a[0, 0] == 0) and np.all(a[mask] > 0)
    np.testing.assert_array_equal(a, reference_render(gb, pos, nrm, col, n_samples=64, seed=11))
    perm = rng.permutation(len(pos))
    np.testing.assert_array_equal(
        a, reference_render(gb, pos[perm], nrm[perm], col[perm], n_samples=64, seed=11))
    b = reference_render(gb, pos, nrm, col, n_samples=64, seed=12)
    assert not np.array_equal(a, b)
    flat = {k: (v.reshape(-1, *v.shape[2:]) if k != "params" else v) for k, v in gb.items()}
    np.testing.assert_array_equal(a.reshape(-1, 3),
                                  reference_render(flat, pos, nrm, col, n_samples=64, seed=11))


@pytest.mark.parametrize("sampling", ["cosine", "mixture"])
def test_view_below_the_shading_normal_is_black_not_nan(sampling):
    """Normal maps can tilt the shading normal away from the eye: f = 0 there, never NaN."""
    pos, nrm, col = _room(L=1.0, n=400)
    gb = _receivers(3, normal=UP, view=np.array([0.6, 0.0, -0.8]), roughness=0.0, metallic=1.0,
                    clearcoat=1.0)
    out = reference_render(gb, pos, nrm, col, n_samples=64, sampling=sampling)
    assert np.all(out == 0.0)
