"""Display transform: numpy (app/render/tonemap.py) vs GLSL (shaders/lib/tonemap.glsl) for every
tone mapper of the registry and the false-colour view, each tone mapper against published
reference values, and robustness to the values real HDR captures carry (negatives, 65504, huge,
Inf, NaN)."""

from __future__ import annotations

import numpy as np
import pytest

from app.errors import ScanlightError
from app.render import tonemap as T
from tests.support import TEST_SHADERS


@pytest.fixture(scope="module")
def gl_tonemap(ctx):
    from app.render.programs import load_compute
    prog = load_compute(ctx, TEST_SHADERS / "tonemap_eval.glsl")   # gen/tonemap.glsl: defines

    def run(rgb, stops=0.0, tonemapper=T.DEFAULT):
        """``tonemapper`` None: the false-colour view."""
        rgb = np.asarray(rgb, np.float32).reshape(-1, 3)
        n = len(rgb)
        data = np.zeros((n, 4), np.float32)
        data[:, :3] = rgb
        b_in, b_out = ctx.buffer(data.tobytes()), ctx.buffer(reserve=n * 16)
        b_in.bind_to_storage_buffer(0)
        b_out.bind_to_storage_buffer(1)
        prog["u_count"].value = n
        prog["u_exposure_stops"].value = stops
        prog["u_tonemap"].value = -1 if tonemapper is None else T.index(tonemapper)
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


# float32 (GLSL) vs float64 (numpy) of each smooth map, absolute on the [0, 1] sRGB output
# (measured on llvmpipe: PBR Neutral 9.1e-7, ACES 7.9e-7, AgX 7.4e-6, clamp 2.4e-7): a few float32
# ulps of pow/exp2 near 1, for ACES the cancellation in its output matrix (1.60475 r - 0.53108 g
# ...) seen through the sRGB slope near black, for AgX a polynomial summing terms of size ~40 to a
# value of ~1 before the 2.2 and sRGB curves. About twice the measured error.
GLSL_ATOL = {"pbr-neutral": 2e-6, "aces": 2e-6, "agx": 2e-5, "clamp": 1e-6}


def test_every_tone_mapper_has_a_glsl_tolerance():
    assert set(GLSL_ATOL) == set(T.NAMES)


@pytest.mark.parametrize("name", T.NAMES)
def test_glsl_matches_numpy(gl_tonemap, name):
    """Each tone mapper on 30000 HDR colours at three exposures: GLSL = numpy within
    GLSL_ATOL[name], and 8-bit codes equal except where the value sits within that tolerance of
    a rounding boundary."""
    c = _colours()
    atol = GLSL_ATOL[name]
    for stops in (0.0, -3.5, 2.0):
        g = gl_tonemap(c, stops, name)
        f = T.tonemap(c, stops, name)
        np.testing.assert_allclose(g, f, atol=atol, rtol=0)
        q_g, q_f = np.round(g * 255), np.round(f.astype(np.float64) * 255)
        near_boundary = np.abs((f * 255) % 1 - 0.5) < atol * 255
        assert np.all((q_g == q_f) | near_boundary)


@pytest.mark.parametrize("name", T.NAMES)
def test_extreme_inputs_map_to_finite_unit_range(gl_tonemap, name):
    c = np.array([[1e6, 1e6, 1e6], [1e6, 0.0, 0.0], [-1.0, -5.0, -1e6], [-1.0, 0.5, 2.0],
                  [65504.0, 65504.0, 1.0], [3.0e38, 1.0, 0.0], [np.inf, 0.0, 1.0],
                  [np.nan, 0.5, 0.5], [-np.inf, np.nan, np.inf], [0.0, 0.0, 0.0],
                  [1e-6, 1e-6, 1e-6], [1e30, 1e30, 1e30], [-0.0, 1e-30, 1e30]], np.float32)
    for stops in (0.0, 10.0, -10.0):
        for out in (T.tonemap(c, stops, name), gl_tonemap(c, stops, name)):
            assert np.all(np.isfinite(out)) and out.min() >= 0.0 and out.max() <= 1.0
    out = T.tonemap(c, 0.0, name)
    assert out[0].min() > 0.97                       # huge white -> (near) white
    assert np.all(out[2] <= out[9] + 1e-7)           # negatives are no light: as black
    np.testing.assert_allclose(out[7], T.tonemap([[0.0, 0.5, 0.5]], 0.0, name)[0])  # NaN -> 0
    np.testing.assert_allclose(gl_tonemap(c, 0.0, name), out, atol=GLSL_ATOL[name])
    u8 = T.tonemap_to_srgb8(c, 0.0, name)
    assert u8.dtype == np.uint8 and u8[2].tolist() == u8[9].tolist()


@pytest.mark.parametrize("name", T.NAMES)
def test_tone_mappers_are_monotone_on_grey_and_each_channel(name):
    """Brighter in, never darker out: a grey ramp from 1e-6 to 1e6 (every output channel), and
    one channel ramped over a fixed other two: that channel, except for AgX, whose outset takes
    up to 6e-5 off a channel at the top of its range as the colour goes to white (its "path to
    white", by design). (Not the luminance: PBR Neutral compresses all channels once one passes
    0.76, so ramping blue alone dims red and green - the Khronos design too.)"""
    ramp = np.logspace(-6, 6, 4001)
    grey = T.tonemap(ramp[:, None] * np.ones(3), 0.0, name)
    assert np.all(np.diff(grey, axis=0) >= -1e-7)
    for ch in range(3):
        c = np.full((len(ramp), 3), 0.3)
        c[:, ch] = ramp
        out = T.tonemap(c, 0.0, name)
        assert np.all(np.diff(out[:, ch]) >= (-1e-4 if name == "agx" else -1e-7))


def test_registry_is_closed_and_backward_compatible():
    assert T.NAMES == ("pbr-neutral", "aces", "agx", "clamp") and T.DEFAULT == "pbr-neutral"
    assert [T.index(n) for n in T.NAMES] == [0, 1, 2, 3]
    d = T.glsl_defines()
    assert [d["TONEMAP_" + n.upper().replace("-", "_")] for n in T.NAMES] == ["0", "1", "2", "3"]
    c = np.array([[0.1, 0.5, 3.0], [0.02, 0.02, 0.02]])
    np.testing.assert_array_equal(T.tonemap_to_srgb8(c, 1.0),
                                  T.tonemap_to_srgb8(c, 1.0, "pbr-neutral"))
    np.testing.assert_array_equal(T.tonemap(c), T.tonemap(c, 0.0, "pbr-neutral"))
    with pytest.raises(ScanlightError, match="unknown tone mapper 'filmic'"):
        T.tonemap(c, 0.0, "filmic")


def test_clamp_is_linear_clipped_then_srgb():
    c = np.array([[0.0, 0.0031308, 0.5], [1.0, 7.0, 0.214041]])
    np.testing.assert_allclose(T.tonemap(c, 0.0, "clamp"),
                               [[0.0, 0.04044994, 0.7353570], [1.0, 1.0, 0.5]], atol=1e-6)


# Stephen Hill's ACES fit as published (BakingLab, ACES.hlsl), transcribed element by element:
# ACESInputMat, RRTAndODTFit, ACESOutputMat, saturate. mul(M, v) with row-major M.
_HILL_IN = ((0.59719, 0.35458, 0.04823), (0.07600, 0.90834, 0.01566), (0.02840, 0.13383, 0.83777))
_HILL_OUT = ((1.60475, -0.53108, -0.07367), (-0.10208, 1.10813, -0.00605),
             (-0.00327, -0.07276, 1.07602))


def _hill_hlsl(rgb):
    v = [sum(_HILL_IN[r][k] * rgb[k] for k in range(3)) for r in range(3)]
    v = [(x * (x + 0.0245786) - 0.000090537) / (x * (0.983729 * x + 0.4329510) + 0.238081)
         for x in v]
    return [min(max(sum(_HILL_OUT[r][k] * v[k] for k in range(3)), 0.0), 1.0) for r in range(3)]


def test_aces_is_hills_fit():
    """Against the published HLSL on known inputs, and its values pinned: 0.18 grey -> 0.10559
    display-linear, 1.0 -> 0.61912, the curve's limit is 1 / 0.983729 (clipped to 1)."""
    inputs = [(0.18, 0.18, 0.18), (1.0, 1.0, 1.0), (1.0, 0.0, 0.0), (0.5, 0.2, 0.05),
              (10.0, 10.0, 10.0), (0.0, 0.0, 0.0), (0.02, 0.3, 4.0)]
    got = T.aces(np.array(inputs))
    np.testing.assert_allclose(got, [_hill_hlsl(c) for c in inputs], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(got[:3], [[0.10559125, 0.10559125, 0.10559019],
                                         [0.61911543, 0.61911543, 0.61910924],
                                         [0.68802787, 0.0, 0.00263901]], atol=1e-8)
    assert T.aces_rrt_odt_fit(1e30) == pytest.approx(1 / 0.983729, rel=1e-12)
    assert T.aces([[1e30] * 3]).min() == 1.0


# Troy Sobotka's published AgX default-contrast LUT (github.com/sobotka/AgX,
# LUTs/AgX_Default_Contrast.spi1d, 4096 entries over [0, 1]): index -> value.
AGX_LUT_SAMPLES = {0: 0.0, 256: 0.0044384, 512: 0.0111792, 1024: 0.0390305, 1536: 0.1154386,
                   2048: 0.2928964, 2482: 0.5000888, 2560: 0.5381819, 3072: 0.7776929,
                   3584: 0.9361831, 4095: 1.0}
AGX_FIT_MAX_ERROR = 5.8e-3   # the polynomial's largest error over the whole LUT (measured)


def test_agx_sigmoid_fits_blenders_published_curve():
    x = np.array(list(AGX_LUT_SAMPLES)) / 4095.0
    lut = np.array(list(AGX_LUT_SAMPLES.values()))
    err = np.abs(T.agx_sigmoid(x) - lut)
    assert err.max() < AGX_FIT_MAX_ERROR
    assert T.agx_sigmoid(0.0) == 0.0 and T.agx_sigmoid(1.0) == pytest.approx(1.0, abs=2e-3)


def test_agx_end_to_end_on_greys_matches_the_lut():
    """Greys placed on LUT samples: 0.18 x 2^(-10 + 16.5 x) sits at x of the log encoding; the
    output is the LUT value through the outset (its rows sum to ~1), the 2.2 display power and
    sRGB. Published anchors: middle grey lands at log position 10/16.5 (index 2482), where the
    curve is 0.5 (2.2-encoded) - AgX puts scene grey at display half."""
    idx = np.array(list(AGX_LUT_SAMPLES))
    x = idx / 4095.0
    grey = 2.0 ** (T.AGX_MIN_EV + x * (T.AGX_MAX_EV - T.AGX_MIN_EV))
    assert T.agx_log_encoding([[0.18] * 3])[0] == pytest.approx([2482 / 4095] * 3, abs=2e-4)
    lut = np.array(list(AGX_LUT_SAMPLES.values()))
    expect = T.srgb_encode(np.clip(lut[:, None] * T.AGX_OUTSET.sum(axis=1), 0, 1) ** 2.2)
    got = T.tonemap(grey[:, None] * np.ones(3), 0.0, "agx")
    np.testing.assert_allclose(got, expect, atol=7e-3)
    np.testing.assert_allclose(T.AGX_OUTSET @ T.AGX_INSET, np.eye(3), atol=1e-12)


def test_pbr_neutral_reference_values():
    """Khronos's reference (KhronosGroup/ToneMapping, PBR_Neutral): below the compression start
    a colour with min >= 0.08 loses exactly 0.04; black stays black; 0.18 grey -> 0.14 linear."""
    np.testing.assert_allclose(T.pbr_neutral([[0.18] * 3]), [[0.14] * 3], atol=1e-12)
    np.testing.assert_allclose(T.pbr_neutral([[0.0] * 3]), [[0.0] * 3])
    x = 0.05   # toe: x - (x - 6.25 x^2) = 6.25 x^2
    np.testing.assert_allclose(T.pbr_neutral([[x] * 3]), [[6.25 * x * x] * 3], rtol=1e-12)


def test_false_colour_bands_and_glsl_twin(gl_tonemap):
    """A grey at 0.18 x 2^ev lands in the band containing ev (edges excluded); GLSL = numpy
    exactly except within 1e-4 EV of an edge (float32 log2)."""
    e = np.asarray(T.FALSE_COLOUR_EDGES)
    mids = np.concatenate([[e[0] - 1], (e[1:] + e[:-1]) / 2, [e[-1] + 1]])
    greys = 0.18 * 2.0 ** mids
    got = T.false_colour(greys[:, None] * np.ones(3))
    np.testing.assert_array_equal(got, np.asarray(T.FALSE_COLOUR_RGB, np.float32))
    np.testing.assert_array_equal(T.false_colour(greys[:, None] * np.ones(3) / 4, 2.0), got)
    assert T.false_colour([[0.0, 0.0, 0.0]])[0].tolist() == list(
        np.float32(T.FALSE_COLOUR_RGB[0]))
    c = _colours(5000, seed=3)
    for stops in (0.0, 3.0):
        g = gl_tonemap(c, stops, None)
        f = T.false_colour(c, stops)
        ev = T.false_colour_ev(c, stops)
        near = np.min(np.abs(ev[:, None] - e[None, :]), axis=1) < 1e-4
        assert np.all((np.abs(g - f).max(axis=1) < 1e-6) | near)
        assert (~near).sum() > 4900
    legend = T.false_colour_legend()
    assert len(legend) == len(T.FALSE_COLOUR_RGB)
    assert legend[0][0] == "< -6 EV" and legend[4][0] == "-1 .. +1 EV"
    assert legend[-1][0] == ">= +6 EV"


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


@pytest.mark.parametrize("name", T.NAMES)
def test_demo_pngs_take_the_tone_mapper(tmp_path, name):
    """The demo's PNG writer (app/demo/pipeline.py) encodes with the tone mapper it is given."""
    from app.demo.pipeline import _save_png
    from tests.support.images import read_png
    img = np.random.default_rng(2).uniform(0, 8, (8, 12, 3)).astype(np.float32)
    _save_png(tmp_path / "x.png", img, exposure=-1.0, tonemapper=name)
    np.testing.assert_array_equal(read_png(tmp_path / "x.png"), T.tonemap_to_srgb8(img, -1.0, name))
