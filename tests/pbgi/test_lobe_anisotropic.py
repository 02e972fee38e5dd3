"""An anisotropic lobe in the lobe micro-buffer (lib/lobe.glsl: the slope stretch of GGX along
the material's tangent): the white furnace gives each pixel the BRDF's directional albedo for
its own view in its own tangent frame (numpy, Monte Carlo), with no pixel far above it - the
isotropic warp of an anisotropic lobe made single pixels 2.8x the light."""

from __future__ import annotations

import numpy as np
import pytest

from app.material import Material
from app.pbgi import brdf
from app.pbgi.renderer import RenderParams
from tests.support import scenes as S

CAM = S.look((0.0, 0.2, 1.6), (0.0, 0.0, 0.0), 24, 45)


def _expected(furnace, mat, n: int = 160):
    """(pixel indices, directional albedo) for up to n receivers spread over the sphere."""
    g = S.reference_gbuffer(furnace, CAM, mat)
    N, T, V = g["normal"], g["tangent"], g["view"]
    B = np.cross(N, T)
    pick = np.linspace(0, len(N) - 1, min(n, len(N))).astype(int)
    v_local = np.stack([np.einsum("ij,ij->i", V, T), np.einsum("ij,ij->i", V, B),
                        np.einsum("ij,ij->i", V, N)], axis=1)[pick]
    ok = v_local[:, 2] > 0.05
    pick, v_local = pick[ok], v_local[ok]
    a = brdf.directional_albedo(g["params"][pick], v_local, n_samples=1 << 13)
    return g["pixel"][pick], a.mean(-1)


@pytest.mark.parametrize("mode", ["classic", "hybrid"])
@pytest.mark.parametrize("aniso, rough", [(1.0, 0.3), (0.6, 0.15), (1.0, 0.08)])
def test_white_furnace_anisotropic(furnace, mode, aniso, rough):
    mat = Material(base_color=(0.9, 0.9, 0.9), metallic=1.0, roughness=rough,
                   anisotropic=aniso)
    res = furnace.render(CAM, [mat], RenderParams(mode=mode, microbuffer=24))
    assert res.stats.completed and res.stats.lobe_receivers
    pix, expect = _expected(furnace, mat)
    got = res.image.reshape(-1, 4)[pix, :3].mean(-1)
    q = got / expect - 1
    assert abs(got.sum() / expect.sum() - 1) < 0.03, (got.sum() / expect.sum())
    assert np.abs(q).max() < 0.15, np.abs(q).max()
    every = res.image[..., :3][res.image[..., 3] > 0]
    assert every.max() <= 1.0, every.max()          # albedo <= 1 under radiance 1
