"""The white furnace (conftest ``furnace``: a sphere inside a closed shell of radiance 1) with a
white dielectric and a white metal from the mirror to roughness 1, in every mode: every pixel is
the BRDF's directional albedo (numpy Monte Carlo, tests/support/scenes.albedo_of_cos), with the
tolerances of tests/pbgi/test_pbgi_render.py::test_white_furnace_at_every_roughness."""

from __future__ import annotations

import numpy as np
import pytest

from tests.stability.sane import MODES, assert_sane
from tests.support import scenes as S
from tests.support.scenes import albedo_of_cos, view_cos
from app.material import Material
from app.pbgi import brdf
from app.pbgi.renderer import RenderParams

CAM = S.look((0.0, 0.2, 1.6), (0.0, 0.0, 0.0), 24, 45)
ROUGHNESS = (0.0, 0.01, 0.1, 0.3, 0.6, 1.0)
VIEW_BINS = ((0.0, 0.2), (0.2, 0.4), (0.4, 0.7), (0.7, 1.01))
TOTAL, BAND, PIXEL = 0.02, 0.03, 0.10   # sum over the sphere, per band of view angles, per pixel


def _material(kind, rough):
    return Material(base_color=(1.0, 1.0, 1.0), roughness=rough,
                    metallic=1.0 if kind == "metal" else 0.0)


_EXPECT_OF: dict = {}


def _expect(furnace, kind, rough):
    key = (kind, rough)
    if key not in _EXPECT_OF:
        mat = _material(kind, rough)
        pix, cos_v = view_cos(furnace, CAM, mat)
        _EXPECT_OF[key] = (pix, cos_v, albedo_of_cos(brdf.pack_params(mat), cos_v))
    return _EXPECT_OF[key]


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("rough", ROUGHNESS, ids=[f"r{r:g}" for r in ROUGHNESS])
@pytest.mark.parametrize("kind", ["dielectric-white", "metal-white"])
def test_white_furnace_at_the_roughness_extremes(furnace, kind, rough, mode):
    res = furnace.render(CAM, [_material(kind, rough)], RenderParams(mode=mode, microbuffer=24))
    assert_sane(res, f"{kind}/{rough}/{mode}", min_receivers=200)
    pix, cos_v, expect = _expect(furnace, kind, rough)
    got = res.image.reshape(-1, 4)[pix, :3].mean(-1)
    assert abs(got.sum() / expect.sum() - 1) < TOTAL, (kind, rough, mode, got.sum() / expect.sum())
    q = got / expect - 1
    for lo, hi in VIEW_BINS:
        band = (cos_v >= lo) & (cos_v < hi)
        assert abs(q[band].mean()) < BAND, (kind, rough, mode, lo, hi, q[band].mean())
    assert np.abs(q).max() < PIXEL, (kind, rough, mode, np.abs(q).max())
