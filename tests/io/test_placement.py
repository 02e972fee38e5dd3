"""app/io/placement.py: the scan's floor and centre, and a mesh standing on it (pure numpy).

References: the demo room's floor is y = 0 and its x/z centre (0, 0) (app/demo/room.py:
ROOM_MIN/ROOM_MAX); a placed box's bounds are computed independently from its eight corners."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from app.demo import room as demo_room
from app.errors import ScanlightError
from app.io.formats import object_matrix, placed_mesh, rotation_xyz
from app.io.mesh import build_mesh, load_mesh, transform_mesh, normalize_mesh
from app.io.placement import (FLOOR_BAND, Room, floor_height, floor_spec, load_floor_spec,
                              room_centre_xz, room_of)

BUNNY = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "bunny.glb"


@pytest.fixture(scope="module")
def demo():
    """The demo room's ground-truth cloud: floor at y = 0, boxes standing on it."""
    return demo_room.sample_room(30_000, seed=3, shadows=False)


def _noisy(cloud, sigma=0.01, strays=0.02, seed=0):
    """The cloud with scanner noise in y and a few percent of stray points under the floor."""
    rng = np.random.default_rng(seed)
    p = cloud.positions.copy()
    p[:, 1] += rng.normal(0.0, sigma, len(p))
    k = int(strays * len(p))
    idx = rng.choice(len(p), k, replace=False)
    p[idx, 1] -= rng.uniform(0.2, 1.0, k)
    return p, cloud.normals


def test_floor_of_the_demo_room(demo):
    floor, source = floor_height(demo.positions, demo.normals)
    assert source == "horizontal points"
    assert floor == pytest.approx(demo_room.ROOM_MIN[1], abs=1e-9)   # points exactly on y = 0


def test_floor_under_noise_strays_flipped_normals_and_holes(demo):
    p, n = _noisy(demo)
    assert floor_height(p, n)[0] == pytest.approx(0.0, abs=0.003)      # middle of the layer
    assert floor_height(p, -n)[0] == pytest.approx(0.0, abs=0.003)     # photogrammetry flips
    p[::37] = np.nan
    assert floor_height(p, n)[0] == pytest.approx(0.0, abs=0.003)
    # without normals: the heights of every point (walls too); the band median still finds it
    floor, source = floor_height(p)
    assert source.startswith("all points") and floor == pytest.approx(0.0, abs=FLOOR_BAND)


def test_the_5th_percentile_alone_would_sit_under_the_floor(demo):
    """Why the band median: the percentile lies in the noise's lower tail, about 1.6 sigma low
    here (stray points + noise); the floor is the layer's middle."""
    p, n = _noisy(demo, sigma=0.02)
    flat = np.abs(n[:, 1]) > 0.8
    assert np.percentile(p[flat, 1], 5) < -0.02
    assert abs(floor_height(p, n)[0]) < 0.006


def test_room_centre_ignores_stray_points(demo):
    assert room_centre_xz(demo.positions) == pytest.approx((0.0, 0.0), abs=0.02)
    far = np.vstack([demo.positions, np.tile([50.0, 0.0, -80.0], (100, 1))])   # 0.3 %
    assert room_centre_xz(far) == pytest.approx((0.0, 0.0), abs=0.05)
    shifted = demo.positions + (3.0, 0.0, -1.5)
    assert room_centre_xz(shifted) == pytest.approx((3.0, -1.5), abs=0.02)


def test_no_floor_falls_back_to_the_lowest_point(demo):
    small = demo.subset(np.arange(10))
    r = room_of(small)
    assert not r.floor_found and "10 usable points" in r.floor_from
    assert r.floor_y == small.positions[:, 1].min()
    assert room_of(demo).floor_found


def _box(size=(2.0, 1.0, 0.5), offset=(10.0, 20.0, -5.0)) -> tuple:
    """A box mesh (12 triangles) of ``size`` with its min corner at ``offset``; its corners."""
    c = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    corners = c * size + offset
    faces = [(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1),
             (2, 3, 7), (2, 7, 6), (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)]
    return build_mesh(corners, faces), corners


ROOM = Room(floor_y=-1.25, centre_xz=(0.5, 2.0))


def _placed(mesh, spec):
    return transform_mesh(normalize_mesh(mesh), object_matrix(spec))


@pytest.mark.parametrize("fit, rotate, translate", [
    (None, None, None), (0.5, None, None), (None, (0, 90, 0), None), (None, (90, 0, 0), None),
    (3.0, (10, 20, 30), (0.1, 0.4, -0.3))])
def test_the_box_stands_on_the_floor_below_the_centre(fit, rotate, translate):
    """Independent twin: the corners rotated about their centre and sized, then moved so the
    lowest corner is on the floor and the x/z middle over the centre, then translated."""
    mesh, corners = _box()
    spec = floor_spec("box", mesh, ROOM, fit, translate, rotate)
    s = (fit / 2.0) if fit else 1.0                   # the box's largest extent is 2 units
    q = (corners - corners.mean(axis=0)) @ rotation_xyz(rotate or (0, 0, 0)).T * s
    lo, hi = q.min(axis=0), q.max(axis=0)
    want = q + (ROOM.centre_xz[0] - (lo[0] + hi[0]) / 2, ROOM.floor_y - lo[1],
                ROOM.centre_xz[1] - (lo[2] + hi[2]) / 2) + np.asarray(translate or (0, 0, 0))
    got = _placed(mesh, spec).positions
    np.testing.assert_allclose(got, want, atol=1e-9)
    if translate is None:
        assert got[:, 1].min() == pytest.approx(ROOM.floor_y, abs=1e-12)
    if rotate is None:                                # own units: the file's size, or --fit
        np.testing.assert_allclose(np.ptp(got, axis=0), np.array([2.0, 1.0, 0.5]) * s, atol=1e-12)


def test_a_quarter_turn_about_x_still_stands_on_the_floor():
    """A Z-up model turned upright: the rotated box is 0.5 high and sits on the floor."""
    mesh, _ = _box()
    got = _placed(mesh, floor_spec("box", mesh, ROOM, rotate=(90, 0, 0))).positions
    assert np.ptp(got[:, 1]) == pytest.approx(0.5, abs=1e-12)
    assert got[:, 1].min() == pytest.approx(ROOM.floor_y, abs=1e-12)


def test_the_viewer_and_render_agree_on_the_bunny():
    """The spec placed by the object JSON's path (placed_mesh, what the viewer's transform does)
    gives the mesh load_floor_spec returns; glTF units are kept: its extent is the file's."""
    if not BUNNY.is_file():
        pytest.skip("no ../shared/data/bunny.glb")
    spec, mesh, extent = load_floor_spec(str(BUNNY), ROOM, rotate=(0, 30, 0))
    lo, hi = load_mesh(BUNNY).bounds()
    assert extent == pytest.approx(float(np.max(hi - lo)), abs=1e-12) and spec.scale == extent
    np.testing.assert_allclose(placed_mesh(spec).positions, mesh.positions, atol=1e-9)
    assert mesh.bounds()[0][1] == pytest.approx(ROOM.floor_y, abs=1e-9)


def test_bad_sizes_are_one_line_errors():
    mesh, _ = _box(size=(2e7, 1.0, 1.0))
    with pytest.raises(ScanlightError, match="across in its own units; give --fit"):
        floor_spec("big.obj", mesh, ROOM)
    assert floor_spec("big.obj", mesh, ROOM, fit=2.0).scale == 2.0
    flat = build_mesh(np.zeros((3, 3)), [(0, 1, 2)])
    with pytest.raises(ScanlightError, match="zero size"):
        floor_spec("dot.obj", flat, ROOM)
    with pytest.raises(ScanlightError, match="translate must be three finite numbers"):
        floor_spec("box", _box()[0], ROOM, translate=(0, np.nan, 0))
