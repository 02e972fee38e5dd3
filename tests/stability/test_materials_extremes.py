"""Disney material parameters at the ends of their ranges, in every mode: finite, non-negative,
completed renders of the box room's sphere, bounded by what the room can reflect, and the
micro-buffer modes agreeing with Classic."""

from __future__ import annotations

import pytest

from tests.stability.sane import MODES, assert_sane, params
from tests.support import scenes as S
from app.material import Material

WHITE, BLACK, GREY = (1.0, 1.0, 1.0), (0.0, 0.0, 0.0), (0.5, 0.5, 0.5)

CASES = {
    "roughness-0": Material(base_color=GREY, roughness=0.0),
    "roughness-1e-4": Material(base_color=GREY, roughness=1e-4),
    "roughness-0.01": Material(base_color=GREY, roughness=0.01),
    "roughness-1": Material(base_color=GREY, roughness=1.0),
    "metallic-0": Material(base_color=WHITE, roughness=0.3, metallic=0.0),
    "metallic-1": Material(base_color=WHITE, roughness=0.3, metallic=1.0),
    "metallic-1-roughness-0": Material(base_color=WHITE, roughness=0.0, metallic=1.0),
    "anisotropic-1": Material(base_color=WHITE, roughness=0.3, metallic=1.0, anisotropic=1.0),
    "anisotropic-1-roughness-0": Material(base_color=WHITE, roughness=0.0, anisotropic=1.0),
    "clearcoat-1-gloss-0": Material(base_color=GREY, clearcoat=1.0, clearcoat_gloss=0.0),
    "clearcoat-1-gloss-1": Material(base_color=GREY, clearcoat=1.0, clearcoat_gloss=1.0),
    "sheen-1": Material(base_color=GREY, roughness=1.0, sheen=1.0, sheen_tint=1.0),
    "base-black": Material(base_color=BLACK, roughness=0.5),
    "base-white": Material(base_color=WHITE, roughness=0.5),
    "specular-0": Material(base_color=GREY, roughness=0.2, specular=0.0),
    "specular-1": Material(base_color=GREY, roughness=0.2, specular=1.0, specular_tint=1.0),
    "everything-1": Material(base_color=WHITE, roughness=0.0, metallic=1.0, anisotropic=1.0,
                             clearcoat=1.0, clearcoat_gloss=1.0, sheen=1.0, subsurface=1.0,
                             specular=1.0, specular_tint=1.0),
}

LIGHT = S.LIGHT[3]      # the brightest radiance in the room (its ceiling light)
# A material reflects at most what arrives: the Disney lobes are not exactly energy conserving
# (sheen and the clearcoat add on top of the base, the retro-reflective diffuse exceeds 1 at
# grazing angles), so the bound is 1.5 times the light, not 1.
MAX_GAIN = 1.5
# The micro-buffer modes share the gather and differ only in how the cut is found: their mean
# over the sphere is within 5% of Classic's (Hybrid's far-field sharing measured 1% here).
MODE_AGREEMENT = 0.05


@pytest.fixture(scope="module")
def room():
    return S.sphere_in_box_room(0.1)


CAM = S.look((0.3, 1.0, 0.9), (0.0, 0.8, 0.0), 32, 40)
_classic_mean: dict[str, float] = {}


def _classic(room, case):
    if case not in _classic_mean:
        rgb = assert_sane(room.render(CAM, [CASES[case]], params("classic")), case)
        _classic_mean[case] = float(rgb.mean())
    return _classic_mean[case]


# Measured failures (M = 8), kept as strict xfails until fixed. (Anisotropic 1 was one - a
# firefly 2.8x the light from the isotropic warp of its lobe - until lib/lobe.glsl mapped the
# lobe through GGX's slope stretch; tests/pbgi/test_lobe_anisotropic.py.)
KNOWN: dict[tuple[str, str], str] = {}
# specular only (black base, F0 4%, roughness 0.5): Hybrid's far-field sharing gives a block's
# receivers the block's frame, which moves a specular-only mean most: measured 5.0% below
# Classic (0.02775 vs 0.02921) at M = 8, every other material within 1.6%
AGREEMENT = {"base-black": 0.08}


def _cases():
    for case in CASES:
        for mode in MODES:
            reason = KNOWN.get((case, mode))
            marks = [pytest.mark.xfail(strict=True, reason=reason)] if reason else []
            yield pytest.param(case, mode, id=f"{case}-{mode}", marks=marks)


@pytest.mark.parametrize("case,mode", list(_cases()))
def test_extreme_material_renders_finite_and_bounded(room, case, mode):
    res = room.render(CAM, [CASES[case]], params(mode))
    rgb = assert_sane(res, f"{case}/{mode}", min_receivers=200)
    assert rgb.max() <= MAX_GAIN * LIGHT, (case, mode, float(rgb.max()))
    if mode in ("mipmapped", "hybrid"):
        ref = _classic(room, case)
        tol = AGREEMENT.get(case, MODE_AGREEMENT)
        assert abs(rgb.mean() / ref - 1) < tol, (case, mode, rgb.mean(), ref)
    if case == "base-black":
        # no diffuse, and a 4% specular: far darker than the white sphere
        white = room.render(CAM, [CASES["base-white"]], params(mode)).image[..., :3]
        assert rgb.mean() < 0.2 * white[white.any(-1)].mean(), mode
