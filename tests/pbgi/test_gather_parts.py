"""The gather kept apart per BRDF factor (app/pbgi/gather_parts.py, pbgi_gather.glsl's
GATHER_PARTS): the parts recombined with the material they were gathered with give the image,
recombined with another one give what a new gather with that material gives, and
``recombinable`` refuses the edits whose new gather would use other micro-buffers."""

from __future__ import annotations

import numpy as np
import pytest

from app.material import Material
from app.pbgi.gather_parts import material_ids, recombinable, recombine
from app.pbgi.renderer import RenderParams

GOLD = dict(base_color=(1.0, 0.71, 0.29), metallic=1.0, roughness=0.25)


def _render(r, mat, mode="classic", parts=True, size=32, **kw):
    from app.demo.room import default_views
    cam = default_views(size, size)["closeup"]
    r.forget_microbuffers()
    return r.render(cam, [mat], RenderParams(mode=mode, microbuffer=16, **kw), parts=parts)


def _rel(a, b, mask):
    """Relative difference over ``mask``: max per pixel against the mean."""
    return float(np.abs(a - b)[mask].max() / max(np.abs(b)[mask].mean(), 1e-9))


@pytest.mark.parametrize("mode", ["classic", "hybrid", "envmap"])
@pytest.mark.parametrize("mat", [
    Material(roughness=0.5, base_color=(0.7, 0.3, 0.2)),                    # no lobe buffer
    Material(**GOLD),                                                        # lobe-only metal
    Material(roughness=0.3, sheen=0.6, sheen_tint=0.3, specular=0.7, specular_tint=0.5,
             clearcoat=0.5, clearcoat_gloss=0.8, base_color=(0.2, 0.5, 0.8)),
], ids=["rough", "gold", "layered"])
def test_the_parts_recombine_to_the_image(demo_relighter, mode, mat):
    """The GATHER_PARTS variant's image is the plain gather's (1e-4 of the mean per pixel:
    summation order), and numpy's recombination of its parts is that image (1e-4)."""
    plain = _render(demo_relighter, mat, mode, parts=False)
    split = _render(demo_relighter, mat, mode)
    on = plain.image[..., 3] > 0
    assert on.sum() > 200 and plain.parts is None
    assert plain.stats.completed and split.stats.completed
    assert _rel(split.image[..., :3], plain.image[..., :3], on) < 1e-4
    assert _rel(recombine(split.parts, mat), split.image[..., :3], on) < 1e-4
    assert set(np.unique(material_ids(split.parts)[on])) == {0}


@pytest.mark.parametrize("mode", ["classic", "hybrid"])
@pytest.mark.parametrize("old,new", [
    (dict(roughness=0.5), dict(roughness=0.5, base_color=(0.1, 0.8, 0.3))),
    (dict(roughness=0.5), dict(roughness=0.5, metallic=1.0, base_color=(0.9, 0.9, 0.9))),
    (GOLD, dict(GOLD, base_color=(0.95, 0.93, 0.88))),                       # gold -> silver
    (dict(roughness=0.9, sheen=0.0), dict(roughness=0.9, sheen=0.8, sheen_tint=1.0)),
    (dict(roughness=0.4, clearcoat=0.3), dict(roughness=0.4, clearcoat=1.0, specular=0.9)),
    (dict(roughness=0.9, sheen=0.8), dict(roughness=0.9, sheen=0.8, metallic=0.5)),
], ids=["colour", "metal", "silver", "sheen", "coat", "sheen-metal"])
def test_a_recombined_edit_is_the_new_gather(demo_relighter, mode, old, new):
    """Parts of material A recombined with B against B's own gather on the same cut: equal up to
    float rounding (1e-3 of the mean per pixel; the lobe buffers' noise is the same noise, the
    pass and frame jitter being the same) for every edit ``recombinable`` accepts."""
    a, b = Material(**old), Material(**new)
    params = RenderParams(mode=mode, microbuffer=16)
    assert recombinable([a], [b], params, walks_asset=False) is None
    ra, rb = _render(demo_relighter, a, mode), _render(demo_relighter, b, mode, parts=False)
    on = rb.image[..., 3] > 0
    assert _rel(recombine(ra.parts, b), rb.image[..., :3], on) < 1e-3


def test_a_smaller_specular_share_recombines_at_least_as_accurately(demo_relighter):
    """Metallic 0.8 -> 0.2 at roughness 0.3: the new gather would size its lobe buffers down
    (lib/lobe_size.glsl), the recombination keeps the old, larger ones - so the two differ by
    the lobe's quantisation, and the recombination is the closer to a reference (M 32, 4
    passes): measured 15.2% against 19.7% relative RMSE."""
    a, b = Material(roughness=0.3, metallic=0.8), Material(roughness=0.3, metallic=0.2)
    assert recombinable([a], [b], RenderParams(), walks_asset=False) is None
    from app.demo.room import default_views
    cam = default_views(32, 32)["closeup"]
    ref = demo_relighter.render_passes(cam, [b], RenderParams(mode="classic", microbuffer=32),
                                       passes=4).image
    on = ref[..., 3] > 0.999
    rec = recombine(_render(demo_relighter, a).parts, b)
    own = _render(demo_relighter, b, parts=False).image[..., :3]
    err = [float(np.sqrt(((x - ref[..., :3]) ** 2)[on].mean()) / ref[..., :3][on].mean())
           for x in (rec, own)]
    assert err[0] <= err[1] * 1.05


@pytest.mark.parametrize("old,new,why", [
    (dict(roughness=0.5), dict(roughness=0.4), "roughness"),
    (dict(roughness=0.5), dict(roughness=0.5, anisotropic=0.5), "anisotropic"),
    (dict(roughness=0.3, metallic=0.0), dict(roughness=0.3, metallic=1.0), "specular share"),
    (dict(roughness=0.3, base_color=(0.9, 0.9, 0.9)), dict(roughness=0.3,
                                                          base_color=(0.1, 0.1, 0.1)),
     "specular share"),
    (dict(roughness=0.3, base_color=(0.0, 1.0, 0.0)), dict(roughness=0.3,
                                                          base_color=(1.0, 0.5, 0.0)),
     "specular share"),      # the same 0.3/0.6/0.1 tint luminance, a lower Rec. 709 one
    (GOLD, dict(GOLD, metallic=0.5), "coarse micro-buffer"),
    (dict(roughness=0.5), dict(roughness=0.5, clearcoat=0.5), "clearcoat turned on"),
    (dict(roughness=0.5), dict(roughness=0.5, emissive=(1.0, 0.0, 0.0)), "emissive"),
], ids=["roughness", "anisotropic", "dielectric-to-metal", "darker-glossy", "green-to-orange",
        "gold-half",
        "coat-on", "emissive"])
def test_edits_that_need_other_buffers_are_refused(old, new, why):
    params = RenderParams()
    assert why in (recombinable([Material(**old)], [Material(**new)], params, False) or "")


def test_textures_and_the_asset_bounce_are_refused():
    tex = np.ones((4, 4, 3), np.float32)
    a = Material(base_color_texture=tex)
    b = Material(base_color_texture=tex, base_color=(0.1, 0.2, 0.3))
    params = RenderParams()
    assert "textured" in recombinable([a], [b], params, False)
    plain = [Material()], [Material(base_color=(0.1, 0.2, 0.3))]
    assert recombinable(*plain, params, walks_asset=False) is None
    assert "bounce" in recombinable(*plain, params, walks_asset=True)
    assert recombinable(*plain, RenderParams(asset_bounces=0), walks_asset=True) is None
    assert recombinable([Material()], [Material()], params, walks_asset=True) is None
