"""Radiance at the extremes, in every mode: a room from 1e-6 to 1e6 times its radiance (beyond
half float's 65504) renders the same image times the factor; one point 1e6 times brighter than
a dim room adds exactly its own light; negative, NaN and Inf colours are repaired by the loader
and refused by the renderer, which never sees them."""

from __future__ import annotations

import numpy as np
import pytest

from tests.stability.sane import MODES, assert_sane, params
from tests.support import scenes as S
from app.cloud import PointCloud
from app.errors import ScanlightError
from app.io.clean import HALF_MAX
from app.io.limits import MAX_RADIANCE
from app.io.pointcloud import load_cloud
from app.material import Material
from app.pbgi.renderer import Relighter

MATERIALS = {"diffuse": Material(base_color=(0.5,) * 3, roughness=0.5),
             "glossy-metal": Material(base_color=(0.9,) * 3, roughness=0.05, metallic=1.0)}
CAM = S.look((0.3, 1.0, 0.9), (0.0, 0.8, 0.0), 24, 40)
SCALES = (1e-6, 1e-3, 1e3, 1e5, 1e6)
# float32 from the cloud to the output: scaling the radiance scales every pixel to rounding
# (measured <= 8e-7 relative); 1e-4 leaves room for a different summation order, not for a
# threshold or an epsilon that does not scale.
LINEAR_RTOL = 1e-4


@pytest.fixture(scope="module")
def room():
    cloud = S.box_room(0.1)
    r = Relighter()
    r.set_cloud(cloud)
    r.set_asset(S.sphere((0.0, 0.8, 0.0), 0.3, subdivisions=3))
    return r, cloud


def _with_colors(r, cloud, colors):
    """The same tree recoloured (Relighter.set_cloud reuses the geometry)."""
    r.set_cloud(PointCloud(cloud.positions, cloud.normals, colors, hdr=True))


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("scale", SCALES, ids=[f"x{s:g}" for s in SCALES])
def test_output_scales_linearly_with_the_cloud_radiance(room, scale, mode):
    r, cloud = room
    for name, mat in MATERIALS.items():
        _with_colors(r, cloud, cloud.colors)
        ref = assert_sane(r.render(CAM, [mat], params(mode)), f"x1/{mode}/{name}")
        _with_colors(r, cloud, cloud.colors * np.float32(scale))
        got = assert_sane(r.render(CAM, [mat], params(mode)), f"x{scale:g}/{mode}/{name}")
        lit = ref > 1e-3 * ref.max()
        ratio = got[lit] / (scale * ref[lit].astype(np.float64))
        assert np.abs(ratio - 1).max() < LINEAR_RTOL, (scale, mode, name, ratio.min(), ratio.max())
        assert (got[~lit] <= 2e-3 * scale * ref.max()).all()
        if scale >= 1e5:
            assert got.max() > HALF_MAX, (scale, mode, name)   # above half float, not clipped


@pytest.mark.parametrize("mode", MODES)
def test_one_point_a_million_times_brighter_than_a_dim_room(room, mode):
    """Dim room of radiance 1e-3, the ceiling point nearest the centre at 1e3: its light and the
    room's add up (the tree is the same, the gather linear), to 1e-5 of the brightest pixel.
    Hybrid's block levels (app/pbgi/block_levels.py) are a fit of the far field's irradiance
    ratios, not linear in the light: the renderer is checked without them, and with them the
    sum holds to 1e-3 (measured 4e-5)."""
    r, cloud = room
    dim = np.full_like(cloud.colors, 1e-3)
    spike = np.zeros_like(cloud.colors)
    spike[np.argmin(np.linalg.norm(cloud.positions - [0.0, 2.0, 0.0], axis=1))] = 1e3
    finder = r.mode_for(params(mode)).cut if mode == "hybrid" else None
    for name, mat in MATERIALS.items():
        for levels in ((False, True) if finder is not None else (False,)):
            if finder is not None:
                finder.level_fit = levels
            parts = []
            try:
                for colors in (dim, spike, dim + spike):
                    _with_colors(r, cloud, colors)
                    res = r.render(CAM, [mat], params(mode))
                    assert_sane(res, f"spike/{mode}/{name}")
                    parts.append(res.image[..., :3].astype(np.float64))
            finally:
                if finder is not None:
                    finder.level_fit = True
            a, b, both = parts
            assert b.max() > 100 * a.max(), (mode, name)     # the point is seen, not averaged away
            tol = 1e-3 if levels else 1e-5
            assert np.abs(both - a - b).max() < tol * both.max(), (mode, name, levels)


def _write_float_ply(path, pos, nrm, rgb):
    props = ("x", "y", "z", "nx", "ny", "nz", "red", "green", "blue")
    head = ("ply\nformat binary_little_endian 1.0\n"
            f"element vertex {len(pos)}\n" + "".join(f"property float {p}\n" for p in props)
            + "end_header\n")
    data = np.ascontiguousarray(np.c_[pos, nrm, rgb], dtype="<f4")
    path.write_bytes(head.encode() + data.tobytes())


BAD = {"negative": -1.0, "nan": np.nan, "+inf": np.inf, "-inf": -np.inf, "3e38": 3e38}


@pytest.mark.parametrize("mode", MODES)
def test_bad_colours_in_a_file_are_repaired_before_the_renderer(tmp_path, mode):
    """load_cloud (app.io.clean) sets negative and NaN colours to 0, +Inf to 65504 and finite
    values above MAX_RADIANCE (a float32 3e38) to it, and counts them: what reaches the renderer
    is finite and non-negative, and so is the image (before: 3e38 overflowed to Inf and NaN in
    the render with the scan's shadow, and in the evaluation's scale)."""
    room = S.box_room(0.1)
    rgb = room.colors.copy()
    for k, v in enumerate(BAD.values()):
        rgb[k::7, k % 3] = v
    _write_float_ply(tmp_path / "bad.ply", room.positions, room.normals, rgb)
    cloud = load_cloud(tmp_path / "bad.ply")
    rep = cloud.report
    assert rep["clamped_nan_colors"] > 0 and rep["clamped_negative_colors"] > 0
    assert rep["clamped_inf_colors"] > 0 and rep["clamped_huge_colors"] > 0
    assert np.isfinite(cloud.colors).all() and (cloud.colors >= 0).all()
    assert cloud.colors.max() == np.float32(MAX_RADIANCE)
    r = Relighter()
    r.set_cloud(cloud)
    r.set_asset(S.sphere((0.0, 0.8, 0.0), 0.3, subdivisions=3))
    for name, mat in MATERIALS.items():
        assert_sane(r.render(CAM, [mat], params(mode)), f"repaired/{mode}/{name}")


@pytest.mark.parametrize("path", ["new-tree", "recoloured-tree"])
@pytest.mark.parametrize("bad", list(BAD))
def test_bad_colours_built_in_code_are_refused_by_the_renderer(path, bad):
    """A PointCloud made in code skips the loader's repair: Relighter.set_cloud refuses it with
    one line, whether it builds a new tree or recolours the cached one (before: the recolouring
    took NaN, every pixel came out non-finite, and negative radiance gave negative pixels)."""
    room = S.box_room(0.1)
    pos = room.positions + (0.5 if path == "new-tree" else 0.0)
    r = Relighter()
    r.set_cloud(PointCloud(pos, room.normals, room.colors, hdr=True))   # cache this geometry
    if path == "new-tree":
        pos = pos + 0.25                                                # a geometry not cached
    rgb = room.colors.copy()
    rgb[::7, 1] = BAD[bad]
    with pytest.raises(ScanlightError) as err:
        r.set_cloud(PointCloud(pos, room.normals, rgb, hdr=True, source="made-in-code"))
    msg = str(err.value)
    assert "\n" not in msg and "made-in-code" in msg
    n_bad = len(rgb[::7])
    non_finite = n_bad if bad in ("nan", "+inf", "-inf") else 0
    negative = n_bad if bad in ("negative", "-inf") else 0
    want = f"{non_finite} points have NaN or Inf colours and {negative} negative ones"
    if bad == "3e38":
        want += f" and {n_bad} above {MAX_RADIANCE:g}"

    assert want in msg, msg
    assert "finite and non-negative" in msg
