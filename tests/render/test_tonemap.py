"""Display transform: numpy (app/render/tonemap.py) vs GLSL (shaders/lib/tonemap.glsl), and
robustness to the values real HDR captures carry (negatives, 65504, huge, Inf, NaN)."""

from __future__ import annotations

import numpy as np
import pytest

from app.errors import ScanlightError
from app.render import tonemap as T
from tests.support import TEST_SHADERS


@pytest.fixture(scope="module")
def gl_tonemap(ctx):
    from app.render.programs import load_compute
    prog = load_compute(ctx, TEST_SHADERS / "tonemap_eval.glsl")

    def run(rgb, stops=0.0):
        rgb = np.asarray(rgb, np.float32).reshape(-1, 3)
        n = len(rgb)
        data = np.zeros((n, 4), np.float32)
        data[:, :3] = rgb
        b_in, b_out = ctx.buffer(data.tobytes()), ctx.buffer(reserve=n * 16)
        b_in.bind_to_storage_buffer(0)
        b_out.bind_to_storage_buffer(1)
        prog["u_count"].value = n
        prog["u_exposure_stops"].value = stops
        prog.run((n + 63) // 64)
        out = np.frombuffer(b_out.read(), np.float32).reshape(n, 4).copy()
        b_in.release()
        b_out.release()
        assert np.all(out[:, 3] == 1.0)
        return out[:, :3]

    return run


def _colours(n=30000, seed=0):
    """Log-uniform HDR colours from 1e-6 to 1e5, a share of greys, zeros and negatives."""
    rng = np.random.default_rng(seed)
    c = 10 ** rng.uniform(-6, 5, (n, 3))
    c[: n // 10] = c[: n // 10, :1]  # greys
    c[n // 10: n // 5] *= np.where(rng.random((n // 10, 3)) < 0.3, -1, 1)
    c[-10:] = 0.0
    return c.astype(np.float32)


def test_glsl_matches_numpy(gl_tonemap):
    """Float32 vs float64 of a smooth map: 2e-6 absolute on [0, 1] output (a few float32 ulps of
    pow/exp2 near 1), and 8-bit codes equal except where the value sits within 1e-5 of a
    rounding boundary."""
    c = _colours()
    for stops in (0.0, -3.5, 2.0):
        g = gl_tonemap(c, stops)
        f = T.tonemap(c, stops)
        np.testing.assert_allclose(g, f, atol=2e-6, rtol=0)
        q_g, q_f = np.round(g * 255), np.round(f.astype(np.float64) * 255)
        near_boundary = np.abs((f * 255) % 1 - 0.5) < 1e-5 * 255
        assert np.all((q_g == q_f) | near_boundary)


def test_extreme_inputs_map_to_finite_unit_range(gl_tonemap):
    c = np.array([[1e6, 1e6, 1e6], [1e6, 0.0, 0.0], [-1.0, -5.0, -1e6], [-1.0, 0.5, 2.0],
                  [65504.0, 65504.0, 1.0], [3.0e38, 1.0, 0.0], [np.inf, 0.0, 1.0],
                  [np.nan, 0.5, 0.5], [-np.inf, np.nan, np.inf]], np.float32)
    for stops in (0.0, 10.0, -10.0):
        for out in (T.tonemap(c, stops), gl_tonemap(c, stops)):
            assert np.all(np.isfinite(out)) and out.min() >= 0.0 and out.max() <= 1.0
    out = T.tonemap(c)
    assert out[0].min() > 0.999                      # huge white -> white
    assert np.all(out[2] == 0.0)                     # negatives are no light
    np.testing.assert_allclose(out[7], T.tonemap([[0.0, 0.5, 0.5]])[0])  # NaN channel -> 0
    np.testing.assert_allclose(gl_tonemap(c)[:6], out[:6], atol=2e-6)
    u8 = T.tonemap_to_srgb8(c)
    assert u8.dtype == np.uint8
    assert u8[0].tolist() == [255, 255, 255] and u8[2].tolist() == [0, 0, 0]


def test_neutral_leaves_base_colours_and_compresses_highlights():
    """Below the compression start (peak - offset < 0.76) the map is c - offset exactly, with
    offset = 0.04 when min >= 0.08; above it the peak maps to 1 - 0.24^2 / (p + 0.24 - 0.76)."""
    c = np.array([[0.5, 0.3, 0.1], [0.7, 0.7, 0.7]])
    np.testing.assert_allclose(T.pbr_neutral(c), c - 0.04, rtol=1e-12)
    p = 5.0
    out = T.pbr_neutral([[p + 0.04, 0.2, 0.2]])[0]
    new_peak = 1 - 0.24 ** 2 / (p + 0.24 - 0.76)
    g = 1 - 1 / (0.15 * (p - new_peak) + 1)
    assert out[0] == pytest.approx(new_peak)            # the peak channel lands on new_peak
    assert out[1] == pytest.approx(((0.2 - 0.04) * new_peak / p) * (1 - g) + new_peak * g)
    mono = T.pbr_neutral(np.linspace(0, 1e4, 2001)[:, None] * np.ones(3))[:, 0]
    assert np.all(np.diff(mono) >= 0) and mono[-1] < 1.0  # monotone, never reaches 1


def test_exposure_is_stops_and_srgb_encoding():
    c = np.array([[0.1, 0.2, 0.3]])
    np.testing.assert_allclose(T.tonemap(c, 1.0), T.tonemap(2 * c, 0.0), rtol=1e-6)
    np.testing.assert_allclose(T.srgb_encode([0.0, 0.0031308, 0.5, 1.0]),
                               [0.0, 0.04044994, 0.7353570, 1.0], atol=1e-6)
    u8 = T.tonemap_to_srgb8(np.full((4, 5, 3), 0.5), 0.0)  # 0.5 - 0.04 -> sRGB 0.7111 -> 181
    assert u8.shape == (4, 5, 3) and np.all(u8 == 181)


def test_srgb8_alpha_and_bad_shapes():
    rgba = np.array([[[0.5, 0.5, 0.5, 0.25], [2.0, 2.0, 2.0, 7.0]]])
    u8 = T.tonemap_to_srgb8(rgba, 0.0)
    assert u8.shape == (1, 2, 4) and u8[0, 0, 3] == 64 and u8[0, 1, 3] == 255
    with pytest.raises(ScanlightError):
        T.tonemap_to_srgb8(np.zeros((4, 4, 2)))
    with pytest.raises(ScanlightError):
        T.tonemap_to_srgb8(np.zeros((4, 3)), float("nan"))
