"""The object JSON: validation with clear errors, and placement (normalise, rotate, scale, move)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from app.errors import ScanlightError
from app.io.formats import ObjectSpec, load_object, placed_mesh, rotation_xyz
from app.io.mesh import face_normals

# A box 4 x 2 x 1 (x, y, z) whose corner sits at (10, 20, 30): normalising must undo both.
BOX_OBJ = """v 10 20 30
v 14 20 30
v 14 22 30
v 10 22 30
v 10 20 31
v 14 20 31
v 14 22 31
v 10 22 31
v 100 100 100
f 1 3 2
f 1 4 3
f 5 6 7
f 5 7 8
f 1 2 6
f 1 6 5
f 2 3 7
f 2 7 6
f 3 4 8
f 3 8 7
f 4 1 5
f 4 5 8
"""  # the last vertex is on no face: it must not count for the bounding box


def write_json(path, d):
    path.write_text(json.dumps(d))
    return path


def test_relative_mesh_path_and_defaults(tmp_path):
    (tmp_path / "assets").mkdir()
    (tmp_path / "assets" / "box.obj").write_text(BOX_OBJ)
    spec = load_object(write_json(tmp_path / "o.json", {"mesh": "assets/box.obj"}))
    assert spec.mesh == str((tmp_path / "assets" / "box.obj").resolve())
    assert spec.translate == (0, 0, 0) and spec.scale == 1.0 and spec.rotate_deg == (0, 0, 0)
    assert spec.source == str(tmp_path / "o.json")


def test_normalised_then_scaled_and_translated(tmp_path):
    (tmp_path / "box.obj").write_text(BOX_OBJ)
    spec = load_object(write_json(tmp_path / "o.json", {
        "mesh": "box.obj", "translate": [1.0, 2.0, -3.0], "scale": 0.5}))
    m = placed_mesh(spec)
    lo, hi = m.bounds()
    # largest extent 4 -> 1, then x 0.5: extents (4, 2, 1) / 4 * 0.5
    np.testing.assert_allclose(hi - lo, [0.5, 0.25, 0.125], atol=1e-6)
    np.testing.assert_allclose((hi + lo) / 2, [1.0, 2.0, -3.0], atol=1e-6)


def test_rotation_order_is_x_then_y_then_z(tmp_path):
    # Rx(90) takes +y to +z, then Ry(90) takes +z to +x.  (Other orders give other answers:
    # Ry first leaves +y alone, then Rx(90) gives +z.)
    np.testing.assert_allclose(rotation_xyz([90, 90, 0]) @ [0, 1, 0], [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(rotation_xyz([0, 0, 90]) @ [1, 0, 0], [0, 1, 0], atol=1e-12)
    (tmp_path / "box.obj").write_text(BOX_OBJ)
    m = placed_mesh(ObjectSpec(str(tmp_path / "box.obj"), (5, 0, 0), 2.0, (0, 0, 90)))
    lo, hi = m.bounds()
    # extents (1, 0.5, 0.25) * 2, turned about z: the long side now lies along y
    np.testing.assert_allclose(hi - lo, [1.0, 2.0, 0.5], atol=1e-6)
    np.testing.assert_allclose((hi + lo) / 2, [5, 0, 0], atol=1e-6)
    fn = face_normals(m.positions, m.indices)  # winding and normals stay consistent
    assert np.all(np.sum(fn * m.normals[m.indices[:, 0]], axis=1) > 0)


def test_sphere_placement_transforms_normals_and_tangents():
    spec = ObjectSpec("sphere", (0, 1, 0), 0.3, (30, 45, 60))
    m = placed_mesh(spec, sphere_subdivisions=3)
    d = m.positions - [0, 1, 0]
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 0.15, atol=1e-6)  # diameter 0.3
    np.testing.assert_allclose(m.normals, d / 0.15, atol=1e-5)
    np.testing.assert_allclose(np.sum(m.tangents[:, :3] * m.normals, axis=1), 0, atol=1e-5)
    # the north-pole direction (+y) of the unrotated sphere follows the rotation
    top = np.argmax(np.sum(d * (rotation_xyz((30, 45, 60)) @ [0, 1, 0]), axis=1))
    np.testing.assert_allclose(d[top] / 0.15, rotation_xyz((30, 45, 60)) @ [0, 1, 0], atol=1e-5)


@pytest.mark.parametrize("content, expect", [
    ("{not json", "not valid JSON"),
    ("[1, 2]", "must hold a JSON object"),
    ('{"translate": [0, 0, 0]}', "object has no 'mesh' key"),
    ('{"mesh": "sphere", "translation": [0, 0, 0]}', "unknown object key(s) 'translation'"),
    ('{"mesh": 3}', "object 'mesh' must be a file path or \"sphere\""),
    ('{"mesh": "sphere", "scale": "2"}', "'scale' must be a number in [1e-6, 1e6]"),
    ('{"mesh": "sphere", "scale": -1}', "'scale' must be a number in [1e-6, 1e6]"),
    ('{"mesh": "sphere", "scale": true}', "'scale' must be a number in [1e-6, 1e6]"),
    ('{"mesh": "sphere", "translate": [0, 0]}', "'translate' must be a list of 3 finite numbers"),
    ('{"mesh": "sphere", "rotate_deg": [0, "a", 0]}', "'rotate_deg' must be a list of 3"),
    ('{"mesh": "sphere", "translate": [0, NaN, 0]}', "'translate' must be a list of 3 finite"),
    ('{"mesh": "gone.glb"}', "object mesh file 'gone.glb' not found"),
    ('{"mesh": "box.stl"}', "unsupported extension"),
])
def test_bad_object_json(tmp_path, content, expect):
    p = tmp_path / "o.json"
    p.write_text(content)
    with pytest.raises(ScanlightError) as err:
        load_object(p)
    msg = str(err.value)
    assert msg.startswith(str(p)) and expect in msg and "\n" not in msg


def test_missing_and_empty_object_file(tmp_path):
    with pytest.raises(ScanlightError, match=r"o\.json: object file not found"):
        load_object(tmp_path / "o.json")
    (tmp_path / "e.json").write_text("")
    with pytest.raises(ScanlightError, match=r"e\.json: object file is empty"):
        load_object(tmp_path / "e.json")


def test_degenerate_mesh_is_an_error(tmp_path):
    (tmp_path / "flat.obj").write_text("v 1 1 1\nv 1 1 1\nv 1 1 1\nf 1 2 3\n")
    with pytest.raises(ScanlightError, match=r"flat\.obj: mesh has no triangle with an area"):
        placed_mesh(ObjectSpec(str(tmp_path / "flat.obj")))


def test_builtin_knot_object_is_placed_like_a_mesh_file():
    """"knot" (the demo's non-convex asset) is normalised to extent 1, then scaled and moved."""
    import numpy as np
    from app.io.formats import object_from_dict, placed_mesh
    mesh = placed_mesh(object_from_dict({"mesh": "knot", "scale": 0.8, "translate": [1, 2, 3]},
                                        ".", "k.json"))
    lo, hi = (np.asarray(b, float) for b in mesh.bounds())
    assert np.max(hi - lo) == pytest.approx(0.8, rel=1e-5)
    assert 0.5 * (lo + hi) == pytest.approx([1, 2, 3], abs=1e-5)
