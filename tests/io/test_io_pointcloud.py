"""Point cloud files: colour meaning by stored type, repairs counted, round trips, bad files."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from app.cloud import PointCloud
from app.color import srgb_to_linear
from app.errors import ScanlightError
from app.io.clean import HALF_MAX
from app.io.pointcloud import FLOAT32_COORD_LIMIT, load_cloud, save_cloud

RNG = np.random.default_rng(7)


def write_ply(path, columns: dict, fmt="binary_little_endian", n=None):
    """A PLY written by hand (not by save_cloud): columns = {name: (ply type, values)}."""
    n = len(next(iter(columns.values()))[1]) if n is None else n
    header = ["ply", f"format {fmt} 1.0", f"element vertex {n}"]
    header += [f"property {t} {k}" for k, (t, _) in columns.items()]
    header.append("end_header")
    body = ""
    if fmt == "ascii":
        rows = np.stack([np.asarray(v, dtype=np.float64) for _, v in columns.values()], axis=1)
        body = "".join(" ".join(repr(float(x)) if t in ("float", "double") else str(int(x))
                                for x, (t, _) in zip(r, columns.values())) + "\n" for r in rows)
        data = body.encode()
    else:
        e = ">" if fmt == "binary_big_endian" else "<"
        npt = {"float": "f4", "double": "f8", "uchar": "u1", "ushort": "u2", "int": "i4"}
        dt = np.dtype([(k, e + npt[t]) for k, (t, _) in columns.items()])
        rec = np.empty(len(next(iter(columns.values()))[1]), dtype=dt)
        for k, (_, v) in columns.items():
            rec[k] = v
        data = rec.tobytes()
    with open(path, "wb") as f:
        f.write(("\n".join(header) + "\n").encode() + data)


def sphere_points(n, radius=1.0, centre=(0.0, 0.0, 0.0)):
    d = RNG.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return np.asarray(centre) + radius * d, d


def xyz_normals(pos, nrm):
    return {"x": ("float", pos[:, 0]), "y": ("float", pos[:, 1]), "z": ("float", pos[:, 2]),
            "nx": ("float", nrm[:, 0]), "ny": ("float", nrm[:, 1]), "nz": ("float", nrm[:, 2])}


# --------------------------------------------------------------------------- colour meaning

@pytest.mark.parametrize("fmt", ["binary_little_endian", "binary_big_endian", "ascii"])
def test_ply_uchar_colours_are_srgb_and_linearised(tmp_path, fmt):
    pos, nrm = sphere_points(300)
    rgb8 = RNG.integers(0, 256, (300, 3))
    cols = xyz_normals(pos, nrm)
    cols.update({k: ("uchar", rgb8[:, i]) for i, k in enumerate(("red", "green", "blue"))})
    write_ply(tmp_path / "a.ply", cols, fmt)
    c = load_cloud(tmp_path / "a.ply")
    assert not c.hdr and c.report["color_type"] == "uchar"
    np.testing.assert_allclose(c.colors, srgb_to_linear(rgb8 / 255.0), rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(c.normals, nrm, atol=1e-6)  # normals from the file are kept
    assert c.report["normals"] == "file"
    np.testing.assert_allclose(c.positions, pos.astype(np.float32), rtol=0, atol=1e-6)


def test_ply_float_colours_are_linear_hdr_kept_above_one(tmp_path):
    pos, nrm = sphere_points(50)
    rgb = RNG.uniform(0, 3000, (50, 3)).astype(np.float32)
    cols = xyz_normals(pos, nrm)
    cols.update({k: ("float", rgb[:, i]) for i, k in enumerate(("red", "green", "blue"))})
    write_ply(tmp_path / "h.ply", cols)
    c = load_cloud(tmp_path / "h.ply")
    assert c.hdr
    np.testing.assert_array_equal(c.colors, rgb)  # not divided by 255 (open3d does that)


def test_ushort_colours_normalised_by_65535(tmp_path):
    pos, nrm = sphere_points(20)
    v = RNG.integers(0, 65536, (20, 3))
    cols = xyz_normals(pos, nrm)
    cols.update({k: ("ushort", v[:, i]) for i, k in enumerate(("red", "green", "blue"))})
    write_ply(tmp_path / "u.ply", cols)
    np.testing.assert_allclose(load_cloud(tmp_path / "u.ply").colors,
                               srgb_to_linear(v / 65535.0), rtol=1e-6, atol=1e-7)


# ------------------------------------------------------------------------------ round trips

def test_save_load_roundtrip_hdr(tmp_path):
    pos, nrm = sphere_points(500, 2.0, (1.0, 1.4, -2.0))
    rgb = RNG.uniform(0, 50, (500, 3)).astype(np.float32)
    cloud = PointCloud(pos, nrm, rgb, hdr=True)
    save_cloud(cloud, tmp_path / "o.ply")
    header = (tmp_path / "o.ply").read_bytes()[:400]
    assert b"property float red" in header and b"property float nx" in header
    assert b"property float x" in header  # small coordinates stay float32
    back = load_cloud(tmp_path / "o.ply")
    assert back.hdr and len(back) == 500
    np.testing.assert_array_equal(back.colors, rgb)
    np.testing.assert_allclose(back.normals, nrm, atol=1e-7)
    np.testing.assert_allclose(back.positions, pos, atol=4e-7)


def test_save_load_roundtrip_ldr_is_exact_uchar(tmp_path):
    pos, nrm = sphere_points(256)
    k = np.arange(256)
    lin = srgb_to_linear(np.stack([k, k[::-1], k], axis=1) / 255.0)
    save_cloud(PointCloud(pos, nrm, lin, hdr=False), tmp_path / "l.ply")
    assert b"property uchar red" in (tmp_path / "l.ply").read_bytes()[:400]
    back = load_cloud(tmp_path / "l.ply")
    assert not back.hdr
    np.testing.assert_array_equal(back.colors, lin)  # every 8-bit level survives exactly
    save_cloud(back, tmp_path / "f.ply", color_type="float32")
    assert load_cloud(tmp_path / "f.ply").hdr


def test_huge_offset_survives_load_and_save(tmp_path):
    offset = np.array([1e6, -2e6, 3e6])
    pos, nrm = sphere_points(400, 1.5, offset)
    save_cloud(PointCloud(pos, nrm, np.ones((400, 3)), hdr=True), tmp_path / "big.ply")
    assert np.abs(pos).max() > FLOAT32_COORD_LIMIT
    assert b"property double x" in (tmp_path / "big.ply").read_bytes()[:400]
    back = load_cloud(tmp_path / "big.ply")
    np.testing.assert_array_equal(back.positions, pos)
    local = back.positions - offset  # millimetre geometry is intact, not float32-quantised
    np.testing.assert_allclose(np.linalg.norm(local, axis=1), 1.5, rtol=1e-9)


def test_normals_estimated_on_offset_plane(tmp_path):
    """A 1e6 m offset must not spoil the plane fit (positions are centred for open3d)."""
    g = np.stack(np.meshgrid(np.linspace(0, 1, 30), np.linspace(0, 1, 30)), -1).reshape(-1, 2)
    pos = np.column_stack([g, np.zeros(len(g))]) + [1e6, 1e6, 5.0]
    pos = np.vstack([pos, [1e6 + 0.5, 1e6 + 0.5, 6.0]])  # one point above: centre is above
    cols = {k: ("double", pos[:, i]) for i, k in enumerate("xyz")}
    write_ply(tmp_path / "p.ply", cols)
    c = load_cloud(tmp_path / "p.ply")
    assert c.report["normals"] == "estimated"
    assert np.all(c.normals[:-1, 2] > 0.99)  # facing up, towards the bounding-box centre


# ------------------------------------------------------- per-point attributes: provenance

def _provenance(n):
    """Every label, in order, and scores with NaN where a label has none."""
    from app.hdr.result import PROVENANCE
    labels = np.resize(np.array(sorted(PROVENANCE), np.uint8), n)
    scores = np.where(labels % 2 == 0, np.nan, RNG.uniform(0, 1, n)).astype(np.float32)
    return labels, scores


def test_provenance_round_trips_as_ply_properties(tmp_path):
    from app.hdr.result import PROVENANCE_ATTR, SCORE_ATTR
    pos, nrm = sphere_points(200)
    labels, scores = _provenance(200)
    extra = np.arange(200, dtype=np.int32)          # written (int), not read back: unknown name
    cloud = PointCloud(pos, nrm, RNG.uniform(0, 5, (200, 3)), True,
                       attributes={PROVENANCE_ATTR: labels, SCORE_ATTR: scores, "index": extra})
    save_cloud(cloud, tmp_path / "p.ply")
    header = (tmp_path / "p.ply").read_bytes()[:800]
    assert b"property uchar provenance\n" in header
    assert b"property float provenance_score\n" in header and b"property int index\n" in header
    back = load_cloud(tmp_path / "p.ply")
    assert set(back.attributes) == {PROVENANCE_ATTR, SCORE_ATTR}
    assert back.attributes[PROVENANCE_ATTR].dtype == np.uint8
    assert back.attributes[SCORE_ATTR].dtype == np.float32
    np.testing.assert_array_equal(back.attributes[PROVENANCE_ATTR], labels)
    np.testing.assert_array_equal(back.attributes[SCORE_ATTR], scores)     # NaN stays NaN
    assert not back.report.get("warnings")
    plain = PointCloud(pos, nrm, np.ones((200, 3)), True)                   # none: none back
    save_cloud(plain, tmp_path / "plain.ply")
    assert load_cloud(tmp_path / "plain.ply").attributes == {}


@pytest.mark.parametrize("fmt", ["ascii", "binary_big_endian"])
def test_provenance_read_from_hand_written_ply(tmp_path, fmt):
    from app.hdr.result import PROVENANCE_ATTR, SCORE_ATTR
    pos, nrm = sphere_points(30)
    labels, scores = _provenance(30)
    cols = xyz_normals(pos, nrm)
    cols.update({PROVENANCE_ATTR: ("uchar", labels), SCORE_ATTR: ("float", scores)})
    write_ply(tmp_path / "h.ply", cols, fmt)
    back = load_cloud(tmp_path / "h.ply")
    np.testing.assert_array_equal(back.attributes[PROVENANCE_ATTR], labels)
    np.testing.assert_allclose(back.attributes[SCORE_ATTR], scores, rtol=1e-6)


def test_provenance_follows_the_points_kept(tmp_path):
    """Points dropped for NaN positions take their provenance with them."""
    from app.hdr.result import PROVENANCE_ATTR, SCORE_ATTR
    pos, nrm = sphere_points(40)
    pos[[2, 17]] = np.nan
    labels, scores = _provenance(40)
    cols = xyz_normals(pos, nrm)
    cols.update({PROVENANCE_ATTR: ("uchar", labels), SCORE_ATTR: ("float", scores)})
    write_ply(tmp_path / "d.ply", cols)
    back = load_cloud(tmp_path / "d.ply")
    keep = np.ones(40, bool)
    keep[[2, 17]] = False
    assert len(back) == 38
    np.testing.assert_array_equal(back.attributes[PROVENANCE_ATTR], labels[keep])
    np.testing.assert_array_equal(back.attributes[SCORE_ATTR], scores[keep])


@pytest.mark.parametrize("case, kept, expect", [
    ("unknown_code", set(), "2 points have provenance codes outside 0-4 (7, 9): provenance ignored"),
    ("float_labels", set(), "property 'provenance' is float, not an integer label"),
    ("int_scores", {"provenance"}, "property 'provenance_score' is int, not float"),
    ("scores_alone", set(), "property 'provenance_score' without 'provenance': ignored"),
])
def test_bad_provenance_is_dropped_with_a_warning(tmp_path, caplog, case, kept, expect):
    """Provenance describes the cloud; a bad one is ignored (one warning line), the cloud loads."""
    pos, nrm = sphere_points(12)
    labels, scores = _provenance(12)
    cols = xyz_normals(pos, nrm)
    if case == "unknown_code":
        labels[[3, 5]] = (7, 9)
    if case != "scores_alone":
        cols["provenance"] = ("float" if case == "float_labels" else "uchar", labels)
    cols["provenance_score"] = ("int", np.arange(12)) if case == "int_scores" else ("float", scores)
    write_ply(tmp_path / f"{case}.ply", cols)
    with caplog.at_level(logging.WARNING, logger="app.io.pointcloud"):
        back = load_cloud(tmp_path / f"{case}.ply")
    assert len(back) == 12 and set(back.attributes) == kept
    assert [w for w in back.report["warnings"] if expect in w], back.report["warnings"]
    assert expect in caplog.text


def test_cloud_attributes_are_checked_sliced_and_saved_strictly(tmp_path):
    pos, nrm = sphere_points(5)
    with pytest.raises(ValueError, match="point attribute 'q' has 4 values but the cloud has 5"):
        PointCloud(pos, nrm, np.ones((5, 3)), attributes={"q": np.zeros(4)})
    c = PointCloud(pos, nrm, np.ones((5, 3)), True, None, {}, {"q": np.arange(5.0)})  # positional
    np.testing.assert_array_equal(c.subset([4, 1]).attributes["q"], [4.0, 1.0])
    for attrs, msg in [({"q": np.arange(5)}, "is int64"), ({"red": np.zeros(5, np.uint8)}, "name"),
                       ({"a b": np.zeros(5, np.uint8)}, "name"),
                       ({"q": np.zeros((5, 2), np.float32)}, "shape")]:
        with pytest.raises(ValueError, match=msg):
            save_cloud(PointCloud(pos, nrm, np.ones((5, 3)), True, attributes=attrs),
                       tmp_path / "x.ply")
        assert not (tmp_path / "x.ply").exists()


# ------------------------------------------------------------------------ repairs, counted

def test_nonfinite_positions_dropped_and_counted(tmp_path, caplog):
    pos, nrm = sphere_points(100)
    pos[[3, 10, 50], [0, 1, 2]] = [np.nan, np.inf, -np.inf]
    write_ply(tmp_path / "n.ply", xyz_normals(pos, nrm))
    with caplog.at_level(logging.WARNING, logger="app.io.pointcloud"):
        c = load_cloud(tmp_path / "n.ply")
    assert len(c) == 97 and c.report["dropped_nonfinite_positions"] == 3
    assert np.all(np.isfinite(c.positions))
    keep = np.ones(100, bool)
    keep[[3, 10, 50]] = False
    np.testing.assert_allclose(c.positions, pos[keep].astype(np.float32), atol=1e-7)
    assert "dropped 3 points with NaN/Inf positions" in caplog.text


def test_bad_colours_clamped_and_counted(tmp_path):
    pos, nrm = sphere_points(6)
    rgb = np.full((6, 3), 2.0, np.float32)
    rgb[0, 0], rgb[1, 1], rgb[2, 2], rgb[3] = np.nan, np.inf, -0.5, -np.inf
    cols = xyz_normals(pos, nrm)
    cols.update({k: ("float", rgb[:, i]) for i, k in enumerate(("red", "green", "blue"))})
    write_ply(tmp_path / "c.ply", cols)
    c = load_cloud(tmp_path / "c.ply")
    r = c.report
    assert (r["clamped_nan_colors"], r["clamped_inf_colors"], r["clamped_negative_colors"]) == (1, 1, 2)
    assert c.colors[0, 0] == 0 and c.colors[1, 1] == HALF_MAX and c.colors[2, 2] == 0
    assert np.all(c.colors[3] == 0) and np.all(c.colors[4:] == 2.0)
    assert any("negative" in w for w in r["warnings"])


def test_zero_length_normals_reestimated(tmp_path):
    g = np.stack(np.meshgrid(np.linspace(-1, 1, 20), np.linspace(-1, 1, 20)), -1).reshape(-1, 2)
    pos = np.column_stack([g, np.zeros(len(g))])
    nrm = np.tile([0.0, 0.0, 2.0], (len(pos), 1))  # non-unit: normalised, not counted
    nrm[[0, 7, 100]] = 0.0
    nrm[200] = np.nan
    write_ply(tmp_path / "z.ply", xyz_normals(pos, nrm))
    c = load_cloud(tmp_path / "z.ply")
    assert c.report["replaced_bad_normals"] == 4
    np.testing.assert_allclose(np.abs(c.normals[:, 2]), 1.0, atol=1e-5)  # the plane's normal
    np.testing.assert_allclose(np.linalg.norm(c.normals, axis=1), 1.0, atol=1e-6)


def test_missing_normals_estimated_facing_inwards(tmp_path, caplog):
    pos, outward = sphere_points(2000, 2.0)
    write_ply(tmp_path / "s.ply", {k: ("float", pos[:, i]) for i, k in enumerate("xyz")})
    with caplog.at_level(logging.WARNING, logger="app.io.pointcloud"):
        c = load_cloud(tmp_path / "s.ply")
    assert c.report["normals"] == "estimated" and "no normals" in caplog.text
    cos = np.sum(c.normals * -outward, axis=1)  # a room is seen from inside: inwards
    assert np.median(cos) > 0.99 and cos.min() > 0.9
    assert not c.hdr and np.all(c.colors == 0.5)  # no colours: grey, with a warning
    assert any("no colours" in w for w in c.report["warnings"])


# --------------------------------------------------------------------------- other formats

@pytest.mark.parametrize("ascii_", [True, False])
def test_pcd_via_open3d(tmp_path, ascii_):
    import open3d as o3d

    pos, nrm = sphere_points(64)
    rgb8 = RNG.integers(0, 256, (64, 3))
    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pos))
    pc.normals = o3d.utility.Vector3dVector(nrm)
    pc.colors = o3d.utility.Vector3dVector(rgb8 / 255.0)
    o3d.io.write_point_cloud(str(tmp_path / "a.pcd"), pc, write_ascii=ascii_)
    c = load_cloud(tmp_path / "a.pcd")
    assert not c.hdr and len(c) == 64
    np.testing.assert_allclose(c.colors, srgb_to_linear(rgb8 / 255.0), atol=1e-6)
    np.testing.assert_allclose(c.positions, pos, atol=1e-5)
    np.testing.assert_allclose(c.normals, nrm, atol=1e-5)
    data = (tmp_path / "a.pcd").read_bytes()
    (tmp_path / "t.pcd").write_bytes(data[: len(data) - 200])
    with pytest.raises(ScanlightError, match=r"t\.pcd: truncated PCD: header declares 64 points"):
        load_cloud(tmp_path / "t.pcd")


def test_xyz_xyzrgb_pts(tmp_path):
    pos, _ = sphere_points(40)
    np.savetxt(tmp_path / "a.xyz", pos)
    c = load_cloud(tmp_path / "a.xyz")
    np.testing.assert_allclose(c.positions, pos, rtol=1e-15)
    assert c.report["normals"] == "estimated"
    rgb8 = RNG.integers(0, 256, (40, 3))
    np.savetxt(tmp_path / "b.xyzrgb", np.column_stack([pos, rgb8]))
    np.testing.assert_allclose(load_cloud(tmp_path / "b.xyzrgb").colors,
                               srgb_to_linear(rgb8 / 255.0), atol=1e-7)
    np.savetxt(tmp_path / "c.xyzrgb", np.column_stack([pos, rgb8 / 255.0]))  # open3d style 0..1
    np.testing.assert_allclose(load_cloud(tmp_path / "c.xyzrgb").colors,
                               srgb_to_linear(rgb8 / 255.0), atol=1e-6)
    rows = np.column_stack([pos, RNG.integers(-2000, 2000, 40), rgb8])  # x y z intensity r g b
    np.savetxt(tmp_path / "d.pts", rows, header="40", comments="")
    d = load_cloud(tmp_path / "d.pts")
    assert not d.hdr
    np.testing.assert_allclose(d.colors, srgb_to_linear(rgb8 / 255.0), atol=1e-7)
    np.savetxt(tmp_path / "e.pts", rows[:30], header="40", comments="")
    with pytest.raises(ScanlightError, match=r"e\.pts: truncated PTS: first line declares 40"):
        load_cloud(tmp_path / "e.pts")


# ------------------------------------------------------------------------------- bad input

def _cols(n):
    pos, nrm = sphere_points(n)
    return xyz_normals(pos, nrm)


@pytest.mark.parametrize("case, expect", [
    ("missing", "point cloud file not found"),
    ("empty", "point cloud file is empty"),
    ("truncated", "truncated PLY: header declares 100 vertices but the data holds only 37"),
    ("truncated_ascii", "truncated PLY: header declares 100 vertices but the file holds 60"),
    ("torn_line", "corrupt or truncated PLY vertex data"),
    ("not_ply", "not a PLY file"),
    ("no_end_header", "no 'end_header'"),
    ("zero_points", "point cloud has no points"),
    ("all_nan", "all 5 points have NaN or Inf positions"),
])
def test_bad_ply(tmp_path, case, expect):
    p = tmp_path / f"{case}.ply"
    if case == "empty":
        p.write_bytes(b"")
    elif case == "truncated":
        write_ply(p, _cols(37), n=100)
    elif case == "truncated_ascii":
        write_ply(p, _cols(60), "ascii", n=100)
    elif case == "torn_line":
        write_ply(p, _cols(10), "ascii")
        p.write_bytes(p.read_bytes()[:-60])  # the last line loses numbers
    elif case == "not_ply":
        p.write_bytes(b"hello\nworld\n")
    elif case == "no_end_header":
        p.write_bytes(b"ply\nformat ascii 1.0\nelement vertex 3\n")
    elif case == "zero_points":
        write_ply(p, _cols(0))
    elif case == "all_nan":
        write_ply(p, {k: ("float", np.full(5, np.nan)) for k in "xyz"})
    with pytest.raises(ScanlightError) as err:
        load_cloud(p)
    msg = str(err.value)
    assert msg.startswith(str(p)) and expect in msg and "\n" not in msg


def test_unknown_extension_and_empty_text(tmp_path):
    (tmp_path / "a.las").write_bytes(b"LASF")
    with pytest.raises(ScanlightError, match=r"a\.las: unsupported point cloud file extension"):
        load_cloud(tmp_path / "a.las")
    (tmp_path / "b.xyz").write_text("# only a comment\n")
    with pytest.raises(ScanlightError, match=r"b\.xyz: point cloud has no points"):
        load_cloud(tmp_path / "b.xyz")
    (tmp_path / "c.xyz").write_text("1 2 3\n4 5\n")
    with pytest.raises(ScanlightError, match=r"c\.xyz: corrupt \.xyz file"):
        load_cloud(tmp_path / "c.xyz")


def test_save_rejects_other_formats(tmp_path):
    with pytest.raises(ScanlightError, match=r"saved as \.ply only"):
        save_cloud(PointCloud(np.zeros((1, 3)), np.zeros((1, 3)), np.zeros((1, 3))),
                   tmp_path / "a.pcd")


@pytest.mark.parametrize("fmt", ["binary_little_endian", "binary_big_endian", "ascii"])
def test_elements_before_the_vertices_are_skipped_whole(tmp_path, fmt):
    """A scanner's PLY may put other elements first (three camera records here, 12 bytes each
    in binary): the reader skips all of their bytes, so the vertices come back as written."""
    e = ">" if fmt == "binary_big_endian" else "<"
    pos = np.array([[1.5, -2.0, 3.25], [0.5, 4.0, -1.0]])
    nrm = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    cams = np.array([[9.0, 9.0, 1.0], [8.0, 7.0, 6.0], [5.0, 4.0, 3.0]])
    header = ["ply", f"format {fmt} 1.0", "element camera 3", "property float k0",
              "property float k1", "property float k2", "element vertex 2"]
    header += [f"property float {k}" for k in ("x", "y", "z", "nx", "ny", "nz")]
    header.append("end_header")
    verts = np.c_[pos, nrm]
    if fmt == "ascii":
        data = "".join(" ".join(repr(float(x)) for x in r) + "\n" for r in [*cams, *verts])
        data = data.encode()
    else:
        data = cams.astype(e + "f4").tobytes() + verts.astype(e + "f4").tobytes()
    (tmp_path / "scan.ply").write_bytes(("\n".join(header) + "\n").encode() + data)
    back = load_cloud(tmp_path / "scan.ply")
    np.testing.assert_array_equal(back.positions, pos)
    np.testing.assert_array_equal(back.normals, nrm)
