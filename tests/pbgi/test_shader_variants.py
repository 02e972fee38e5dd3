"""Shader variants per material feature set (pbgi.shader_variants): the final gather compiled
without the subsurface, anisotropy, sheen or clearcoat code no material uses gives the image of
the program with all of them, in every mode that gathers, glossy lobes included."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from app.material import Material
from app.pbgi.gather import FEATURES, absent_features
from app.pbgi.renderer import Relighter, RenderParams
from tests.support import scenes as S

ALL = tuple(sorted(FEATURES.values()))


def test_absent_features_are_the_parameters_every_material_has_at_zero():
    assert absent_features([Material()]) == ALL
    assert absent_features([Material(clearcoat=1.0)]) == ("ANISOTROPY", "SHEEN", "SUBSURFACE")
    assert absent_features([Material(sheen=0.2), Material(anisotropic=0.5)]) == \
        ("CLEARCOAT", "SUBSURFACE")
    assert absent_features([Material(subsurface=1, sheen=1, anisotropic=1, clearcoat=1)]) == ()


@pytest.fixture(scope="module")
def room(ctx):
    rl = Relighter(ctx)
    rl.set_cloud(S.box_room(spacing=0.08))
    rl.set_asset(S.sphere((0.0, 0.0, 0.0), 0.5, subdivisions=4))
    return rl, S.look((0.0, 0.3, 1.7), (0.0, 0.0, 0.0), size=32, fov=45.0)


MATERIALS = {
    "diffuse": Material(base_color=(0.7, 0.5, 0.3), roughness=0.6),
    "gold 0.25": Material(base_color=(1.0, 0.77, 0.34), metallic=1.0, roughness=0.25),
    "silver 0.05": Material(base_color=(0.97, 0.96, 0.91), metallic=1.0, roughness=0.05),
    "car paint": Material(base_color=(0.5, 0.05, 0.05), roughness=0.4, clearcoat=1.0,
                          clearcoat_gloss=0.9),
    "fabric": Material(base_color=(0.5, 0.2, 0.3), roughness=0.95, sheen=1.0),
    "skin": Material(base_color=(0.8, 0.5, 0.4), roughness=0.5, subsurface=0.7),
    "brushed": Material(base_color=(0.9, 0.9, 0.9), metallic=1.0, roughness=0.3,
                        anisotropic=0.8),
}


@pytest.mark.parametrize("mode", ["classic", "hybrid", "envmap"])
@pytest.mark.parametrize("name", list(MATERIALS))
def test_a_variant_renders_what_the_full_program_renders(room, mode, name):
    rl, cam = room
    mat = MATERIALS[name]
    p = RenderParams(mode=mode, microbuffer=12, envmap_face=32)
    on = rl.render(cam, [mat], p)
    off = rl.render(cam, [mat], replace(p, shader_variants=False))
    assert on.stats.absent_features == absent_features([mat]) and on.stats.completed
    assert off.stats.absent_features == ()
    a, b = on.image[..., :3].astype(np.float64), off.image[..., :3].astype(np.float64)
    assert np.isfinite(a).all() and b.max() > 0
    # the isotropic GGX of a variant is the anisotropic one with ax = ay, up to rounding
    assert np.abs(a - b).max() <= 1e-4 * b.max(), np.abs(a - b).max() / b.max()
