"""Display transform for PNG output and the viewer: exposure in stops, one of the tone mappers of
``TONEMAPPERS``, sRGB encoding; and the false-colour EV view. GLSL twin: shaders/lib/tonemap.glsl
(same formulas; tests/render/test_tonemap.py compares them for every tone mapper).

``TONEMAPPERS`` is the one closed registry: its order is declared once, here. ``view.tonemap``'s
choices (app/params.py), ``render --tonemap`` and the shader's integer index (``glsl_defines``,
injected as ``TONEMAP_<NAME>`` defines) are all generated from it.

- ``pbr-neutral`` (the default): Khronos PBR Neutral (2024). It leaves base colours below ~0.8
  untouched (a look-dev viewer must show the material's colour as authored) and only rolls
  highlights off to white.
- ``aces``: Stephen Hill's fit of the ACES RRT + sRGB ODT (BakingLab's ACES.hlsl): sRGB -> AP1
  (with the RRT's saturation folded in), a rational fit of RRT+ODT per channel, AP1 -> sRGB.
  Chosen over Narkowicz's 2015 one-curve fit because it keeps ACES's gamut handling (hue skews
  and desaturation of bright saturated colours as ACES shows them); Narkowicz applies one curve to
  sRGB channels and over-saturates highlights. No 1/0.6 pre-exposure (three.js adds one): an
  exposure is the user's EV.
- ``agx``: AgX base as Blender ships it (Troy Sobotka's AgX, config.ocio of github.com/sobotka/AgX):
  the inset matrix, a log2 encoding of -10 .. +6.5 stops around 0.18 (absolute log2 -12.47393 ..
  4.026069), the default-contrast sigmoid, then the outset (the inset's inverse) and a 2.2 power
  back to display-linear (Benjamin Wrensch's "minimal AgX", as in Godot and three.js). The sigmoid
  is Wrensch's 6th-order polynomial fit of AgX_Default_Contrast.spi1d, not the LUT itself: over the
  LUT's 4096 entries its error is at most 5.8e-3 (mean square 7.1e-6), about one 8-bit code.
- ``clamp``: linear values clipped to [0, 1] (shows what the radiance is, clipped at 1).

Every mapper takes the same sanitised input (NaN -> 0, negatives -> 0, capped at MAX_INPUT) and
returns display-linear [0, 1]; ``srgb_encode`` follows.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from app.errors import ScanlightError

MAX_INPUT = 1e30  # cap before mapping: Inf and 1e38 would overflow the highlight formulas
_START = 0.8 - 0.04
_DESAT = 0.15


def sanitize(rgb) -> np.ndarray:
    """Linear radiance made safe to map: NaN -> 0, negatives -> 0, capped at MAX_INPUT."""
    c = np.nan_to_num(np.asarray(rgb, dtype=np.float64), nan=0.0, posinf=MAX_INPUT, neginf=0.0)
    return np.clip(c, 0.0, MAX_INPUT)


def pbr_neutral(rgb) -> np.ndarray:
    """Khronos PBR Neutral tone mapper on (..., 3) non-negative linear RGB -> [0, 1)."""
    c = np.asarray(rgb, dtype=np.float64)
    x = c.min(axis=-1, keepdims=True)
    offset = np.where(x < 0.08, x - 6.25 * x * x, 0.04)
    c = c - offset
    peak = c.max(axis=-1, keepdims=True)
    d = 1.0 - _START
    new_peak = 1.0 - d * d / (peak + d - _START)
    compress = peak >= _START
    scaled = c * (new_peak / np.where(compress, peak, 1.0))
    g = 1.0 - 1.0 / (_DESAT * (peak - new_peak) + 1.0)
    return np.where(compress, scaled + (new_peak - scaled) * g, c)


# Hill's fit (BakingLab ACES.hlsl): mul(M, v) with M row-major, i.e. v @ M.T here.
ACES_INPUT = np.array([[0.59719, 0.35458, 0.04823],     # sRGB -> AP1, with the RRT saturation
                       [0.07600, 0.90834, 0.01566],
                       [0.02840, 0.13383, 0.83777]])
ACES_OUTPUT = np.array([[1.60475, -0.53108, -0.07367],  # ODT saturation, AP1 -> sRGB
                        [-0.10208, 1.10813, -0.00605],
                        [-0.00327, -0.07276, 1.07602]])
# The fit's input is capped here: v * v must stay inside float32 in the shader, and at 1e15 the
# rational fit equals its limit 1 / 0.983729 to 4e-16.
ACES_FIT_MAX = 1e15


def aces_rrt_odt_fit(v) -> np.ndarray:
    """Hill's RRTAndODTFit: the rational fit of the ACES RRT + ODT curve, per AP1 channel."""
    v = np.minimum(np.asarray(v, np.float64), ACES_FIT_MAX)
    a = v * (v + 0.0245786) - 0.000090537
    b = v * (0.983729 * v + 0.4329510) + 0.238081
    return a / b


def aces(rgb) -> np.ndarray:
    """Stephen Hill's fitted ACES RRT + sRGB ODT on (..., 3) non-negative linear sRGB -> [0, 1]."""
    c = np.asarray(rgb, np.float64) @ ACES_INPUT.T
    return np.clip(aces_rrt_odt_fit(c) @ ACES_OUTPUT.T, 0.0, 1.0)


# AgX base: sobotka/AgX config.ocio, colour space "AgX Log (Kraken)": the inset MatrixTransform
# (rows) and the lg2 AllocationTransform's vars, log2(0.18) - 10 and log2(0.18) + 6.5.
AGX_INSET = np.array([[0.842479062253094, 0.0784335999999992, 0.0792237451477643],
                      [0.0423282422610123, 0.878468636469772, 0.0791661274605434],
                      [0.0423756549057051, 0.0784336, 0.879142973793104]])
AGX_OUTSET = np.linalg.inv(AGX_INSET)
AGX_MIN_EV = -12.47393
AGX_MAX_EV = 4.026069
AGX_DISPLAY_GAMMA = 2.2   # the AgX sigmoid's output is encoded for a 2.2 power display
# Wrensch's polynomial fit of AgX_Default_Contrast.spi1d, highest power first
AGX_SIGMOID_POLY = (15.5, -40.14, 31.96, -6.868, 0.4298, 0.1191, -0.00232)


def agx_sigmoid(x) -> np.ndarray:
    """The AgX default-contrast curve on the [0, 1] log encoding (polynomial fit), to [0, 1]."""
    x = np.asarray(x, np.float64)
    x2 = x * x
    x4 = x2 * x2
    p = AGX_SIGMOID_POLY
    y = p[0] * x4 * x2 + p[1] * x4 * x + p[2] * x4 + p[3] * x2 * x + p[4] * x2 + p[5] * x + p[6]
    return np.clip(y, 0.0, 1.0)


def agx_log_encoding(rgb) -> np.ndarray:
    """Inset, then log2 mapped from [AGX_MIN_EV, AGX_MAX_EV] onto [0, 1] (clamped)."""
    v = np.asarray(rgb, np.float64) @ AGX_INSET.T
    lg = np.clip(np.log2(np.maximum(v, 2.0 ** AGX_MIN_EV)), AGX_MIN_EV, AGX_MAX_EV)
    return (lg - AGX_MIN_EV) / (AGX_MAX_EV - AGX_MIN_EV)


def agx(rgb) -> np.ndarray:
    """AgX base on (..., 3) non-negative linear sRGB -> display-linear [0, 1]."""
    y = agx_sigmoid(agx_log_encoding(rgb)) @ AGX_OUTSET.T
    return np.clip(y, 0.0, 1.0) ** AGX_DISPLAY_GAMMA


def clamp(rgb) -> np.ndarray:
    """Linear clamp to [0, 1]: the radiance as it is, clipped at 1."""
    return np.clip(np.asarray(rgb, np.float64), 0.0, 1.0)


@dataclass(frozen=True)
class ToneMapper:
    name: str         # the value of ``view.tonemap`` / ``render --tonemap``
    title: str        # what the stats JSON and the docs call it
    curve: Callable   # (..., 3) sanitised linear radiance -> display-linear [0, 1]


# The closed registry, in its one declared order (the shader's TONEMAP_* indices follow it).
TONEMAPPERS: dict[str, ToneMapper] = {m.name: m for m in (
    ToneMapper("pbr-neutral", "Khronos PBR Neutral", pbr_neutral),
    ToneMapper("aces", "ACES (Hill's fitted RRT+ODT, BakingLab)", aces),
    ToneMapper("agx", "AgX base (Blender/Sobotka, Wrensch's polynomial sigmoid)", agx),
    ToneMapper("clamp", "linear clamp", clamp),
)}
NAMES: tuple[str, ...] = tuple(TONEMAPPERS)
DEFAULT = "pbr-neutral"


def get(name: str) -> ToneMapper:
    if name not in TONEMAPPERS:
        raise ScanlightError(None, f"unknown tone mapper {name!r}; one of {', '.join(NAMES)}")
    return TONEMAPPERS[name]


def index(name: str) -> int:
    """The shader's integer for ``name`` (u_tonemap), from the registry's order."""
    get(name)
    return NAMES.index(name)


def srgb_encode(linear) -> np.ndarray:
    """sRGB OETF (IEC 61966-2-1) of linear values, clamped to [0, 1]."""
    c = np.clip(np.asarray(linear, dtype=np.float64), 0.0, 1.0)
    return np.where(c <= 0.0031308, c * 12.92,
                    1.055 * np.maximum(c, 0.0031308) ** (1.0 / 2.4) - 0.055)


def tonemap(linear_rgb, exposure_stops: float = 0.0, tonemapper: str = DEFAULT) -> np.ndarray:
    """(..., 3) linear radiance -> display-encoded sRGB float32 in [0, 1]."""
    curve = get(tonemapper).curve
    c = sanitize(sanitize(linear_rgb) * 2.0 ** float(exposure_stops))
    return srgb_encode(curve(c)).astype(np.float32)


def tonemap_to_srgb8(linear_rgb, exposure_stops: float = 0.0,
                     tonemapper: str = DEFAULT) -> np.ndarray:
    """(..., 3) or (..., 4) linear radiance -> uint8 sRGB for a PNG. Alpha (4th channel) is
    coverage, not light: it is clipped to [0, 1] and stored linearly, not tone mapped."""
    a = np.asarray(linear_rgb)
    if a.ndim < 1 or a.shape[-1] not in (3, 4):
        raise ScanlightError(None, f"tone mapping needs (..., 3) or (..., 4) colours, got shape "
                                   f"{a.shape}")
    if not np.isfinite(exposure_stops):
        raise ScanlightError(None, f"exposure must be a finite number of stops, "
                                   f"got {exposure_stops}")
    out = tonemap(a[..., :3], exposure_stops, tonemapper)
    if a.shape[-1] == 4:
        alpha = np.clip(np.nan_to_num(np.asarray(a[..., 3:], dtype=np.float64)), 0.0, 1.0)
        out = np.concatenate([out, alpha.astype(np.float32)], axis=-1)
    return np.round(out * 255.0).astype(np.uint8)


# -- false-colour EV view -------------------------------------------------------------------------
# Luminance after exposure, in stops relative to middle grey (0.18), in bands: the band edges
# (EV) and one display colour (sRGB-encoded, shown as is) per band, darkest first. Green is
# middle grey +-1 stop (as on cinema cameras' false colour); blues are shadows, yellow to red
# highlights, white is more than 6 stops over grey (past every tone mapper's shoulder).
FALSE_COLOUR_GREY = 0.18
LUMA = (0.2126, 0.7152, 0.0722)   # Rec. 709 / sRGB luminance
FALSE_COLOUR_EDGES = (-6.0, -4.0, -2.0, -1.0, 1.0, 2.0, 4.0, 6.0)
FALSE_COLOUR_RGB = ((0.30, 0.00, 0.45),   # below -6 EV: crushed
                    (0.05, 0.10, 0.60),   # -6 .. -4
                    (0.00, 0.45, 1.00),   # -4 .. -2
                    (0.00, 0.75, 0.75),   # -2 .. -1
                    (0.25, 0.75, 0.25),   # -1 .. +1: middle grey
                    (0.85, 0.90, 0.25),   # +1 .. +2
                    (1.00, 0.60, 0.00),   # +2 .. +4
                    (1.00, 0.10, 0.10),   # +4 .. +6
                    (1.00, 1.00, 1.00))   # above +6


def false_colour_ev(linear_rgb, exposure_stops: float = 0.0) -> np.ndarray:
    """(...) EV of each pixel's luminance x 2^exposure relative to 0.18; -inf where Y = 0."""
    y = sanitize(linear_rgb) @ np.asarray(LUMA) * 2.0 ** float(exposure_stops)
    with np.errstate(divide="ignore"):
        return np.log2(np.minimum(y, MAX_INPUT) / FALSE_COLOUR_GREY)


def false_colour(linear_rgb, exposure_stops: float = 0.0) -> np.ndarray:
    """(..., 3) linear radiance -> (..., 3) float32 display colour of its EV band."""
    band = np.searchsorted(np.asarray(FALSE_COLOUR_EDGES), false_colour_ev(linear_rgb,
                                                                           exposure_stops),
                           side="right")
    return np.asarray(FALSE_COLOUR_RGB, np.float32)[band]


def false_colour_legend() -> list[tuple[str, tuple[float, float, float]]]:
    """(EV range text, display colour) per band, darkest first, for the viewer's legend."""
    e = FALSE_COLOUR_EDGES
    names = [f"< {e[0]:+g}"] + [f"{a:+g} .. {b:+g}" for a, b in zip(e, e[1:])] + [f">= {e[-1]:+g}"]
    return [(n + " EV", c) for n, c in zip(names, FALSE_COLOUR_RGB)]


def glsl_header() -> str:
    """``gen/tonemap.glsl`` (app/render/programs.py), included by shaders/lib/tonemap.glsl: the
    defines of ``glsl_defines``, so every shader that includes the tone mappers gets them."""
    return "".join(f"#define {k} {v}\n" for k, v in glsl_defines().items())


def glsl_defines() -> dict[str, str]:
    """Defines for shaders/lib/tonemap.glsl: each tone mapper's index (TONEMAP_PBR_NEUTRAL ...)
    and the false-colour bands, so the shader keeps no list of its own."""
    out = {"TONEMAP_" + n.upper().replace("-", "_"): str(i) for i, n in enumerate(NAMES)}
    e, c = FALSE_COLOUR_EDGES, FALSE_COLOUR_RGB
    out["FALSE_COLOUR_BANDS"] = str(len(c))
    out["FALSE_COLOUR_EDGES"] = f"float[{len(e)}](" + ", ".join(f"{x:.6f}" for x in e) + ")"
    out["FALSE_COLOUR_RGB"] = f"vec3[{len(c)}](" + ", ".join(
        "vec3({:.6f}, {:.6f}, {:.6f})".format(*rgb) for rgb in c) + ")"
    out["FALSE_COLOUR_GREY"] = f"{FALSE_COLOUR_GREY:.6f}"
    out["TONEMAP_LUMA"] = "vec3({:.6f}, {:.6f}, {:.6f})".format(*LUMA)
    return out
