"""``scanlight render --object model.glb|.obj``: a mesh opened directly stands on the scan's floor.

The test room (tests/support/scenes.py: box_room) has its floor at y = 0 and its centre at
x = z = 0; the camera stands inside it looking down at the floor's middle."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from app.cli import main
from app.io.exr import read_exr_layers
from app.io.mesh import load_mesh
from app.io.pointcloud import save_cloud
from tests.support import scenes as S

BUNNY = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "bunny.glb"
CUBE_OBJ = """# a 0.4 x 0.3 x 0.2 box, its min corner at (5, 7, -3): the file's own units
v 5.0 7.0 -3.0
v 5.4 7.0 -3.0
v 5.4 7.3 -3.0
v 5.0 7.3 -3.0
v 5.0 7.0 -2.8
v 5.4 7.0 -2.8
v 5.4 7.3 -2.8
v 5.0 7.3 -2.8
f 1 4 3
f 1 3 2
f 5 6 7
f 5 7 8
f 1 2 6
f 1 6 5
f 4 8 7
f 4 7 3
f 1 5 8
f 1 8 4
f 2 3 7
f 2 7 6
"""


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    d = tmp_path_factory.mktemp("render_mesh")
    save_cloud(S.box_room(0.1), d / "room.ply")
    (d / "cam.json").write_text(json.dumps({"position": [0.0, 0.9, 0.95], "look_at": [0, 0.15, 0],
                                            "fov_y_deg": 55, "width": 32, "height": 32}))
    (d / "cube.obj").write_text(CUBE_OBJ)
    (d / "obj.json").write_text(json.dumps({"mesh": "sphere", "translate": [0, 0.8, 0],
                                            "scale": 0.6}))
    return d


def _render(d, obj, *extra, name="out"):
    code = main(["render", "--cloud", str(d / "room.ply"), "--object", str(obj),
                 "--camera", str(d / "cam.json"), "--microbuffer", "8",
                 "--out", str(d / f"{name}.exr"), "--stats", str(d / f"{name}.json"), *extra])
    if code != 0:
        return code, None, None
    return code, json.loads((d / f"{name}.json").read_text())["asset"], \
        read_exr_layers(d / f"{name}.exr")[""][..., 3]


def _centroid_x(alpha):
    return np.nonzero(alpha > 0.5)[1].mean()


def test_bunny_glb_stands_on_the_floor_in_its_own_units(inputs):
    if not BUNNY.is_file():
        pytest.skip("no ../shared/data/bunny.glb")
    d = inputs
    code, asset, _ = _render(d, BUNNY)
    assert code == 0
    lo, hi = (np.array(v) for v in asset["bounds"])
    raw_lo, raw_hi = load_mesh(BUNNY).bounds()
    assert asset["floor_y"] == pytest.approx(0.0, abs=1e-6) and asset["floor_found"]
    assert lo[1] == pytest.approx(asset["floor_y"], abs=1e-9)        # standing on it
    np.testing.assert_allclose(hi - lo, raw_hi - raw_lo, atol=1e-6)   # glTF metres, unscaled
    np.testing.assert_allclose(((lo + hi) / 2)[[0, 2]], asset["room_centre_xz"], atol=1e-9)
    assert asset["scale"] == 1.0 and asset["fit"] is None
    # --fit 0.5: the largest extent is exactly 0.5 m, still on the floor, and in the picture
    code, asset, alpha = _render(d, BUNNY, "--fit", "0.5", name="fit")
    lo, hi = (np.array(v) for v in asset["bounds"])
    assert code == 0 and np.max(hi - lo) == pytest.approx(0.5, abs=1e-9)
    assert lo[1] == pytest.approx(0.0, abs=1e-6)
    assert asset["scale"] == pytest.approx(0.5 / float(np.max(raw_hi - raw_lo)), rel=1e-9)
    assert alpha[8:28, 8:24].mean() > 0.1 and alpha[:3].sum() == 0   # bunny below the centre


def test_obj_fit_translate_and_rotate(inputs):
    """An OBJ in its own units (read as metres), moved by --translate: the placed bounds move by
    exactly that, and the asset moves to the right in the picture."""
    d = inputs
    code, asset, alpha = _render(d, d / "cube.obj")
    assert code == 0
    lo, hi = (np.array(v) for v in asset["bounds"])
    np.testing.assert_allclose(hi - lo, (0.4, 0.3, 0.2), atol=1e-9)
    np.testing.assert_allclose(lo[1], 0.0, atol=1e-6)
    assert alpha.sum() > 5
    code, moved, alpha2 = _render(d, d / "cube.obj", "--translate", "0.25,0.1,0", name="moved")
    assert code == 0
    np.testing.assert_allclose(np.array(moved["bounds"]) - np.array(asset["bounds"]),
                               [[0.25, 0.1, 0.0]] * 2, atol=1e-9)
    assert _centroid_x(alpha2) > _centroid_x(alpha) + 3                # pixels to the right
    code, turned, _ = _render(d, d / "cube.obj", "--rotate", "0,90,0", "--fit", "0.8",
                              name="turned")
    lo, hi = (np.array(v) for v in turned["bounds"])
    np.testing.assert_allclose(hi - lo, (0.4, 0.6, 0.8), atol=1e-9)   # x and z swapped, x2
    assert lo[1] == pytest.approx(0.0, abs=1e-6)


def test_the_object_json_is_placed_as_before(inputs):
    d = inputs
    code, asset, _ = _render(d, d / "obj.json", name="json")
    assert code == 0 and asset["placement"] == "object JSON"
    lo, hi = (np.array(v) for v in asset["bounds"])
    np.testing.assert_allclose((lo + hi) / 2, (0, 0.8, 0), atol=1e-3)


@pytest.mark.parametrize("obj, extra, code, text", [
    ("missing.glb", (), 3, "object file not found"),
    ("bad.glb", (), 3, "bad.glb"),
    ("cube.obj", ("--fit", "0"), 2, "--fit must be a size in metres"),
    ("cube.obj", ("--fit", "nan"), 2, "--fit must be a size in metres"),
    ("cube.obj", ("--translate", "1,2"), 2, "--translate expects three finite numbers"),
    ("cube.obj", ("--rotate", "a,b,c"), 2, "--rotate expects three finite numbers"),
    ("obj.json", ("--fit", "1"), 2, "--fit only applies to a mesh given directly"),
    ("room.ply", (), 3, "unsupported object file extension"),
])
def test_bad_objects_are_one_line(inputs, capsys, obj, extra, code, text):
    d = inputs
    (d / "bad.glb").write_bytes(b"glTF\x02\x00\x00\x00garbage")
    capsys.readouterr()
    assert _render(d, d / obj, *extra, name="bad")[0] == code
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and text in err[0], err
    assert not (d / "bad.exr").exists()
