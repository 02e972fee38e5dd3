"""Meshes: glTF (plain and Draco, node transforms, materials), OBJ+MTL, tangent frames, bad files."""

from __future__ import annotations

import base64
import io
import json
import logging
import struct
from pathlib import Path

import DracoPy
import numpy as np
import pytest
from PIL import Image

from app.color import srgb_to_linear
from app.errors import ScanlightError
from app.material import Material
from app.io.mesh import (compute_tangents, face_normals, load_mesh, make_default_asset,
                         make_sphere_mesh, transform_mesh)

DATA = Path(__file__).resolve().parents[3] / "shared" / "data"
needs_data = pytest.mark.skipif(not DATA.is_dir(), reason="../shared/data not present")


# ------------------------------------------------------------------------ a tiny glTF writer

class Gltf:
    """Builds glTF documents by hand, so tests control every byte the loader sees."""

    def __init__(self):
        self.doc = {"asset": {"version": "2.0"}, "buffers": [], "bufferViews": [],
                    "accessors": [], "meshes": [], "nodes": [], "materials": [],
                    "scenes": [{"nodes": []}], "scene": 0}
        self.bin = bytearray()

    def view(self, data: bytes) -> int:
        self.bin += b"\0" * (-len(self.bin) % 4)
        self.doc["bufferViews"].append({"buffer": 0, "byteOffset": len(self.bin),
                                        "byteLength": len(data)})
        self.bin += data
        return len(self.doc["bufferViews"]) - 1

    def accessor(self, a: np.ndarray) -> int:
        a = np.ascontiguousarray(a)
        ctype = {np.dtype("float32"): 5126, np.dtype("uint32"): 5125,
                 np.dtype("uint16"): 5123}[a.dtype]
        kind = "SCALAR" if a.ndim == 1 else f"VEC{a.shape[1]}"
        self.doc["accessors"].append({"bufferView": self.view(a.tobytes()), "componentType": ctype,
                                      "count": len(a), "type": kind})
        return len(self.doc["accessors"]) - 1

    def image(self, rgb8: np.ndarray) -> int:
        buf = io.BytesIO()
        Image.fromarray(rgb8).save(buf, format="PNG")
        self.doc.setdefault("images", []).append({"bufferView": self.view(buf.getvalue()),
                                                  "mimeType": "image/png"})
        self.doc.setdefault("textures", []).append({"source": len(self.doc["images"]) - 1})
        return len(self.doc["textures"]) - 1

    def primitive(self, pos, faces, normals=None, uvs=None, material=None) -> dict:
        attrs = {"POSITION": self.accessor(np.asarray(pos, np.float32))}
        if normals is not None:
            attrs["NORMAL"] = self.accessor(np.asarray(normals, np.float32))
        if uvs is not None:
            attrs["TEXCOORD_0"] = self.accessor(np.asarray(uvs, np.float32))
        prim = {"attributes": attrs,
                "indices": self.accessor(np.asarray(faces, np.uint32).reshape(-1))}
        if material is not None:
            prim["material"] = material
        return prim

    def mesh(self, *prims) -> int:
        self.doc["meshes"].append({"primitives": list(prims)})
        return len(self.doc["meshes"]) - 1

    def node(self, root=True, **kw) -> int:
        self.doc["nodes"].append(kw)
        if root:
            self.doc["scenes"][0]["nodes"].append(len(self.doc["nodes"]) - 1)
        return len(self.doc["nodes"]) - 1

    def write_glb(self, path):
        self.bin += b"\0" * (-len(self.bin) % 4)
        self.doc["buffers"] = [{"byteLength": len(self.bin)}]
        js = json.dumps(self.doc).encode()
        js += b" " * (-len(js) % 4)
        body = struct.pack("<I4s", len(js), b"JSON") + js + struct.pack("<I4s", len(self.bin),
                                                                         b"BIN\0") + self.bin
        Path(path).write_bytes(struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body)

    def write_gltf(self, path, bin_name=None):
        """.gltf with the buffer as an external file (bin_name) or a base64 data URI."""
        if bin_name:
            (Path(path).parent / bin_name).write_bytes(bytes(self.bin))
            uri = bin_name
        else:
            uri = "data:application/octet-stream;base64," + base64.b64encode(self.bin).decode()
        self.doc["buffers"] = [{"byteLength": len(self.bin), "uri": uri}]
        Path(path).write_text(json.dumps(self.doc))


QUAD_POS = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
QUAD_FACES = np.array([[0, 1, 2], [0, 2, 3]])
QUAD_UV_GLTF = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32)  # glTF: v down
UP = np.tile([0, 0, 1.0], (4, 1))


def quat(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    return [*(np.sin(angle / 2) * axis), np.cos(angle / 2)]


# ------------------------------------------------------------------------------- real files

@needs_data
@pytest.mark.parametrize("name, verts, faces", [("bunny.glb", 2826, 5648),
                                                ("suzi.glb", 7503, 14842)])
def test_real_draco_models(name, verts, faces):
    m = load_mesh(DATA / name)
    assert (len(m.positions), m.n_faces) == (verts, faces)  # the accessor counts in the JSON
    assert np.all(np.isfinite(m.normals)) and np.all(np.isfinite(m.positions))
    np.testing.assert_allclose(np.linalg.norm(m.normals, axis=1), 1.0, atol=1e-5)
    # the stored normals agree with the triangle winding (counter-clockwise outside)
    fn = face_normals(m.positions, m.indices)
    agree = np.sum(fn * m.normals[m.indices].sum(axis=1), axis=1) > 0
    assert agree.mean() > 0.99
    # positions are those of an independent Draco decode of the one bufferView
    data = (DATA / name).read_bytes()
    jlen = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20:20 + jlen])
    view = doc["bufferViews"][0]
    start = 20 + jlen + 8 + view.get("byteOffset", 0)
    ref = DracoPy.decode(data[start:start + view["byteLength"]])
    np.testing.assert_array_equal(m.positions, ref.points)
    np.testing.assert_array_equal(m.indices, ref.faces)
    # the JSON bounds predate Draco quantisation (differences seen: 5e-5 bunny, 2.5e-5 suzi)
    lo, hi = m.bounds()
    np.testing.assert_allclose(lo, doc["accessors"][1]["min"], atol=1.2e-4)
    np.testing.assert_allclose(hi, doc["accessors"][1]["max"], atol=1.2e-4)
    assert m.uvs is None and any("no texture coordinates" in w for w in m.report["warnings"])


@needs_data
def test_real_bunny_material():
    m = load_mesh(DATA / "bunny.glb")
    (mat,) = m.materials
    assert mat.base_color == pytest.approx((0.8, 0.8, 0.8)) and mat.metallic == 0.0
    assert mat.roughness == 0.5 and mat.specular == 0.5


def test_draco_primitive_with_node_transform(tmp_path):
    import trimesh

    box = trimesh.creation.box(extents=(1, 2, 3))
    blob = DracoPy.encode(box.vertices.astype(np.float32), box.faces.astype(np.uint32),
                          quantization_bits=16)
    g = Gltf()
    bv = g.view(blob)
    g.doc["accessors"] += [{"componentType": 5125, "count": 36, "type": "SCALAR"},
                           {"componentType": 5126, "count": 8, "type": "VEC3"}]
    prim = {"attributes": {"POSITION": 1}, "indices": 0,
            "extensions": {"KHR_draco_mesh_compression": {"bufferView": bv,
                                                          "attributes": {"POSITION": 0}}}}
    g.node(mesh=g.mesh(prim), translation=[10, 0, 0], rotation=quat([0, 0, 1], np.pi / 2))
    g.doc["extensionsRequired"] = ["KHR_draco_mesh_compression"]
    g.write_glb(tmp_path / "d.glb")
    m = load_mesh(tmp_path / "d.glb")
    lo, hi = m.bounds()
    # extents (1, 2, 3) turned 90 degrees about z -> (2, 1, 3), centred on x = 10
    np.testing.assert_allclose(hi - lo, [2, 1, 3], atol=1e-3)
    np.testing.assert_allclose((hi + lo) / 2, [10, 0, 0], atol=1e-3)
    assert m.n_faces == 12
    assert any("flat normals" in w for w in m.report["warnings"])  # no NORMAL attribute
    fn = face_normals(m.positions, m.indices)
    np.testing.assert_allclose(m.normals[m.indices[:, 0]], fn / np.linalg.norm(fn, axis=1)[:, None],
                               atol=1e-5)
    assert np.sum(fn * (m.positions[m.indices].mean(1) - [10, 0, 0])) > 0  # outward winding


# ------------------------------------------------------------------- glTF hierarchy, material

def test_gltf_node_hierarchy_and_mirroring(tmp_path):
    g = Gltf()
    quad = g.mesh(g.primitive(QUAD_POS, QUAD_FACES, UP, QUAD_UV_GLTF))
    child = g.node(root=False, mesh=quad, rotation=quat([1, 0, 0], np.pi / 2), scale=[2, 2, 2])
    g.node(children=[child], translation=[0, 5, 0])
    g.node(mesh=quad, matrix=[-1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 3, 0, 0, 1])  # mirror x, move
    g.write_glb(tmp_path / "h.glb")
    m = load_mesh(tmp_path / "h.glb")
    assert m.n_faces == 4 and len(m.materials) == 1
    # world = T(0,5,0) @ Rx(90) @ S(2): (x, y, 0) -> (2x, 5, 2y)
    first, second = m.positions[:4], m.positions[4:]
    expect_first = np.column_stack([2 * QUAD_POS[:, 0], np.full(4, 5.0), 2 * QUAD_POS[:, 1]])
    expect_second = np.column_stack([3 - QUAD_POS[:, 0], QUAD_POS[:, 1], QUAD_POS[:, 2]])
    if not np.allclose(first, expect_first, atol=1e-6):
        first, second = second, first
    np.testing.assert_allclose(first, expect_first, atol=1e-6)
    np.testing.assert_allclose(second, expect_second, atol=1e-6)
    # normals rotate with the node (+z -> -y) and winding stays consistent after the mirror
    fn = face_normals(m.positions, m.indices)
    np.testing.assert_allclose(np.sum(fn * m.normals[m.indices[:, 0]], axis=1) > 0, True)
    assert {tuple(np.round(n, 6)) for n in m.normals} == {(0.0, -1.0, 0.0), (0.0, 0.0, 1.0)}


def test_gltf_trs_is_translate_rotate_scale_and_normals_take_the_inverse_transpose(tmp_path):
    """The glTF spec's node matrix is T R S (scale first), and a normal goes through the inverse
    transpose of the linear part: with a non-uniform scale and a tilted normal, both differ from
    the other orders (S R, the plain matrix). The expectation is built here from the spec."""
    g = Gltf()
    tilt = np.tile([1.0, 0.0, 1.0], (4, 1)) / np.sqrt(2.0)
    quad = g.mesh(g.primitive(QUAD_POS, QUAD_FACES, tilt))
    angle = np.pi / 2
    g.node(mesh=quad, rotation=quat([0, 0, 1], angle), scale=[2, 1, 1], translation=[1, 2, 3])
    g.write_glb(tmp_path / "trs.glb")
    m = load_mesh(tmp_path / "trs.glb")
    c, s = np.cos(angle), np.sin(angle)
    lin = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) @ np.diag([2.0, 1.0, 1.0])
    np.testing.assert_allclose(m.positions, QUAD_POS @ lin.T + [1, 2, 3], atol=1e-6)
    n = tilt @ np.linalg.inv(lin)                # rows: (inv(L)^T n)^T
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    np.testing.assert_allclose(m.normals, n, atol=1e-6)


def test_gltf_materials_map_to_disney(tmp_path):
    g = Gltf()
    tex8 = np.zeros((2, 3, 3), np.uint8)
    tex8[0] = [200, 100, 10]  # top row of the picture
    tex8[1] = [5, 50, 250]
    mr8 = np.zeros((2, 2, 3), np.uint8)
    mr8[..., 1], mr8[..., 2] = 128, 64  # G = roughness, B = metallic
    g.doc["materials"] = [
        {"name": "paint", "pbrMetallicRoughness": {
            "baseColorFactor": [0.01, 0.5, 0.9, 1.0], "metallicFactor": 0.25,
            "roughnessFactor": 0.75, "baseColorTexture": {"index": g.image(tex8)},
            "metallicRoughnessTexture": {"index": g.image(mr8)}},
         "normalTexture": {"index": g.image(np.full((1, 1, 3), 128, np.uint8))},
         "emissiveFactor": [1.0, 0.5, 0.0],
         "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 4.0}}},
        {"name": "bare"},
    ]
    g.node(mesh=g.mesh(g.primitive(QUAD_POS, QUAD_FACES, UP, QUAD_UV_GLTF, material=0),
                       g.primitive(QUAD_POS + [0, 0, 1], QUAD_FACES, UP, QUAD_UV_GLTF, material=1)))
    g.write_glb(tmp_path / "m.glb")
    m = load_mesh(tmp_path / "m.glb")
    paint, bare = m.materials
    assert paint.name == "paint" and paint.base_color == pytest.approx((0.01, 0.5, 0.9))  # exact
    assert (paint.metallic, paint.roughness, paint.specular) == (0.25, 0.75, 0.5)
    assert paint.emissive == pytest.approx((4.0, 2.0, 0.0))
    # base colour texture: sRGB decoded to linear, stored bottom row first (OpenGL order)
    np.testing.assert_allclose(paint.base_color_texture[..., :3],
                               srgb_to_linear(tex8[::-1] / 255.0), atol=1e-6)
    np.testing.assert_allclose(paint.metallic_roughness_texture[..., 1], 128 / 255, atol=1e-6)
    np.testing.assert_allclose(paint.metallic_roughness_texture[..., 2], 64 / 255, atol=1e-6)
    assert paint.normal_texture.shape == (1, 1, 3)
    # glTF defaults for an empty material: white, fully metallic, fully rough
    assert bare.base_color == (1.0, 1.0, 1.0) and bare.metallic == 1.0 and bare.roughness == 1.0
    np.testing.assert_array_equal(m.material_ids, [0, 0, 1, 1])
    # UVs flipped to OpenGL convention: glTF (0, 1) is the bottom-left corner -> (0, 0)
    np.testing.assert_allclose(m.uvs[:4], [[0, 0], [1, 0], [1, 1], [0, 1]])
    # tangent = +x (u grows along x), bitangent = w * n x t = +y (v grows along y)
    np.testing.assert_allclose(m.tangents[:4], np.tile([1, 0, 0, 1], (4, 1)), atol=1e-6)


def test_gltf_missing_texture_is_a_warning(tmp_path, caplog):
    g = Gltf()
    g.doc["images"] = [{"uri": "gone.png"}]
    g.doc["textures"] = [{"source": 0}]
    g.doc["materials"] = [{"name": "m", "pbrMetallicRoughness": {
        "baseColorFactor": [0.3, 0.2, 0.1, 1], "baseColorTexture": {"index": 0}}}]
    g.node(mesh=g.mesh(g.primitive(QUAD_POS, QUAD_FACES, UP, QUAD_UV_GLTF, material=0)))
    g.write_gltf(tmp_path / "t.gltf", bin_name="t.bin")
    with caplog.at_level(logging.WARNING, logger="app.io.mesh"):
        m = load_mesh(tmp_path / "t.gltf")
    (mat,) = m.materials
    assert mat.base_color_texture is None and mat.base_color == pytest.approx((0.3, 0.2, 0.1))
    assert "texture file 'gone.png' not found; using the factor instead" in caplog.text
    assert any("gone.png" in w for w in m.report["warnings"])


def test_gltf_data_uri_buffer_and_missing_bin(tmp_path):
    g = Gltf()
    g.node(mesh=g.mesh(g.primitive(QUAD_POS, QUAD_FACES)))
    g.write_gltf(tmp_path / "u.gltf")
    m = load_mesh(tmp_path / "u.gltf")
    assert m.n_faces == 2
    np.testing.assert_allclose(m.normals, np.tile([0, 0, 1], (6, 1)), atol=1e-6)  # flat, 6 corners
    g.write_gltf(tmp_path / "b.gltf", bin_name="b.bin")
    (tmp_path / "b.bin").unlink()
    with pytest.raises(ScanlightError, match=r"b\.gltf: buffer 0 file 'b\.bin' not found"):
        load_mesh(tmp_path / "b.gltf")



def test_gltf_interleaved_normalised_uvs_and_triangle_strip(tmp_path):
    """byteStride, normalised uint16 UVs and mode 5 (strip): the accessor paths trimesh hides."""
    g = Gltf()
    pos = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], np.float32)
    uv16 = np.array([[0, 65535], [65535, 65535], [0, 0], [65535, 0]], np.uint16)  # glTF v down
    rec = np.zeros(4, dtype=[("p", "<f4", 3), ("uv", "<u2", 2)])
    rec["p"], rec["uv"] = pos, uv16
    bv = g.view(rec.tobytes())
    g.doc["bufferViews"][bv]["byteStride"] = rec.dtype.itemsize
    g.doc["accessors"] += [
        {"bufferView": bv, "byteOffset": 0, "componentType": 5126, "count": 4, "type": "VEC3"},
        {"bufferView": bv, "byteOffset": 12, "componentType": 5123, "count": 4, "type": "VEC2",
         "normalized": True}]
    g.node(mesh=g.mesh({"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "mode": 5}))
    g.write_glb(tmp_path / "s.glb")
    m = load_mesh(tmp_path / "s.glb")
    assert m.n_faces == 2
    fn = face_normals(m.positions, m.indices)
    assert np.all(fn[:, 2] > 0)  # both strip triangles counter-clockwise seen from +z
    # flat normals un-index the corners; each corner's UV is its position (OpenGL convention)
    np.testing.assert_allclose(m.uvs, m.positions[:, :2], atol=1e-6)
    np.testing.assert_allclose(m.tangents, np.tile([1, 0, 0, 1], (6, 1)), atol=1e-6)

# ------------------------------------------------------------------------------------ OBJ

OBJ = """mtllib a.mtl
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0 0 1
vt 0 0
vt 1 0
vt 1 1
vt 0 1
usemtl red
f 1/1 2/2 3/3
f 1/1 3/3 4/4
usemtl blue
f 1/1 5/4 2/2
"""


def test_obj_with_mtl(tmp_path, caplog):
    (tmp_path / "a.obj").write_text(OBJ)
    (tmp_path / "a.mtl").write_text("newmtl red\nKd 0.9 0.1 0.01\nNs 100\nmap_Kd tex.png\n"
                                    "newmtl blue\nKd 0.01 0.02 0.9\nPr 0.3\nPm 1\n"
                                    "map_Kd -bm 1 missing.png\n")
    Image.fromarray(np.array([[[255, 0, 0], [0, 255, 0]], [[0, 0, 255], [10, 20, 30]]],
                             np.uint8)).save(tmp_path / "tex.png")
    with caplog.at_level(logging.WARNING, logger="app.io.mesh"):
        m = load_mesh(tmp_path / "a.obj")
    by_name = {mat.name: mat for mat in m.materials}
    red, blue = by_name["red"], by_name["blue"]
    assert red.base_color == pytest.approx((0.9, 0.1, 0.01))  # exact, not via uint8
    assert red.roughness == pytest.approx((2 / 102) ** 0.25)
    assert (blue.roughness, blue.metallic) == (pytest.approx(0.3), 1.0)
    np.testing.assert_allclose(red.base_color_texture[0, 0], srgb_to_linear([0, 0, 1.0]),
                               atol=1e-6)  # bottom-left texel of the picture comes first
    assert blue.base_color_texture is None and "missing.png" in caplog.text
    assert m.n_faces == 3
    counts = np.bincount(m.material_ids, minlength=2)
    assert sorted(counts) == [1, 2] and counts[m.materials.index(red)] == 2
    # OBJ UVs are already OpenGL-style: vertex (1, 1, 0) has vt (1, 1)
    k = np.flatnonzero(np.all(m.positions == [1, 1, 0], axis=1))[0]
    np.testing.assert_allclose(m.uvs[k], [1, 1])
    np.testing.assert_allclose(np.linalg.norm(m.normals, axis=1), 1.0, atol=1e-6)


def test_obj_missing_mtl_is_a_warning(tmp_path):
    (tmp_path / "a.obj").write_text(OBJ)  # refers to a.mtl, which is not there
    m = load_mesh(tmp_path / "a.obj")
    assert m.n_faces == 3 and any("'a.mtl' not found" in w for w in m.report["warnings"])
    assert {mat.base_color for mat in m.materials} == {Material().base_color}


def test_obj_without_faces(tmp_path):
    (tmp_path / "p.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    with pytest.raises(ScanlightError, match=r"p\.obj: mesh has no faces"):
        load_mesh(tmp_path / "p.obj")


# ------------------------------------------------------------------------------- bad input

def _good_glb(path):
    g = Gltf()
    g.node(mesh=g.mesh(g.primitive(QUAD_POS, QUAD_FACES, UP)))
    g.write_glb(path)
    return path.read_bytes()


@pytest.mark.parametrize("case, expect", [
    ("missing", "mesh file not found"),
    ("empty", "mesh file is empty"),
    ("garbage", "corrupt glTF JSON"),
    ("truncated", "truncated GLB: header says"),
    ("truncated_chunk", "truncated GLB: chunk"),
    ("bad_accessor", "accessor 0 reads past its bufferView"),
    ("no_faces", "mesh has no faces"),
    ("points_only", "mesh has no faces"),
    ("bad_draco", "corrupt Draco mesh data"),
    ("index_range", "vertex indices out of range"),
])
def test_bad_glb(tmp_path, case, expect):
    p = tmp_path / f"{case}.glb"
    if case == "empty":
        p.write_bytes(b"")
    elif case == "garbage":
        p.write_bytes(b"\x00\x01 definitely not glTF")
    elif case == "truncated":
        p.write_bytes(_good_glb(tmp_path / "g.glb")[:-40])
    elif case == "truncated_chunk":
        data = bytearray(_good_glb(tmp_path / "g.glb")[:-40])
        data[8:12] = struct.pack("<I", len(data))  # header length fixed, chunk still too long
        p.write_bytes(bytes(data))
    elif case in ("bad_accessor", "index_range"):
        g = Gltf()
        g.node(mesh=g.mesh(g.primitive(QUAD_POS, [[0, 1, 9]] if case == "index_range"
                                       else QUAD_FACES)))
        if case == "bad_accessor":
            g.doc["accessors"][0]["count"] = 1000
        g.write_glb(p)
    elif case in ("no_faces", "points_only"):
        g = Gltf()
        prim = g.primitive(QUAD_POS, np.zeros((0, 3)))
        if case == "points_only":
            prim = {"attributes": prim["attributes"], "mode": 0}
        g.node(mesh=g.mesh(prim))
        g.write_glb(p)
    elif case == "bad_draco":
        g = Gltf()
        bv = g.view(b"DRACO" + b"\x07" * 64)
        g.doc["accessors"] += [{"componentType": 5125, "count": 3, "type": "SCALAR"},
                               {"componentType": 5126, "count": 3, "type": "VEC3"}]
        g.node(mesh=g.mesh({"attributes": {"POSITION": 1}, "indices": 0, "extensions": {
            "KHR_draco_mesh_compression": {"bufferView": bv, "attributes": {"POSITION": 0}}}}))
        g.write_glb(p)
    with pytest.raises(ScanlightError) as err:
        load_mesh(p)
    msg = str(err.value)
    assert msg.startswith(str(p)) and expect in msg and "\n" not in msg


@needs_data
def test_truncated_real_bunny(tmp_path):
    data = (DATA / "bunny.glb").read_bytes()
    (tmp_path / "b.glb").write_bytes(data[: len(data) // 2])
    with pytest.raises(ScanlightError, match=r"b\.glb: truncated GLB"):
        load_mesh(tmp_path / "b.glb")


def test_unsupported_mesh_extension(tmp_path):
    (tmp_path / "a.stl").write_bytes(b"solid a\nendsolid a\n")
    with pytest.raises(ScanlightError, match=r"a\.stl: unsupported mesh file extension '\.stl'"):
        load_mesh(tmp_path / "a.stl")


# ------------------------------------------------------------------------- frames, shapes

def test_tangents_follow_uv_directions_and_handedness():
    pos = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    n = np.tile([0, 0, 1.0], (4, 1))
    # u along +x, v along +y: right-handed (b = +1 * n x t = +y)
    t = compute_tangents(pos, n, pos[:, :2], QUAD_FACES)
    np.testing.assert_allclose(t, np.tile([1, 0, 0, 1], (4, 1)), atol=1e-12)
    # u along -x, v along +y (mirrored texture): t = -x, b must still be +y -> w = -1
    t = compute_tangents(pos, n, np.column_stack([1 - pos[:, 0], pos[:, 1]]), QUAD_FACES)
    np.testing.assert_allclose(t, np.tile([-1, 0, 0, -1], (4, 1)), atol=1e-12)
    np.testing.assert_allclose(t[0, 3] * np.cross(n[0], t[0, :3]), [0, 1, 0], atol=1e-12)
    # no UVs: any unit tangent orthogonal to n
    t = compute_tangents(pos, np.tile([0.6, 0, 0.8], (4, 1)), None, QUAD_FACES)
    np.testing.assert_allclose(np.linalg.norm(t[:, :3], axis=1), 1, atol=1e-12)
    np.testing.assert_allclose(t[:, :3] @ [0.6, 0, 0.8], 0, atol=1e-12)


def test_sphere_mesh():
    s = make_sphere_mesh(4)
    np.testing.assert_allclose(np.linalg.norm(s.positions, axis=1), 0.5, atol=1e-6)  # diameter 1
    np.testing.assert_allclose(s.normals, 2 * s.positions, atol=1e-6)
    fn = face_normals(s.positions, s.indices)
    assert np.all(np.sum(fn * s.positions[s.indices].mean(axis=1), axis=1) > 0)  # CCW outside
    assert s.n_faces == 2 * 32 * 64 - 2 * 64
    # tangents: the analytic d/dphi direction (cos phi, 0, -sin phi) away from the poles;
    # averaging face chords costs at most half a segment angle (pi/64) at the seam
    phi = np.arctan2(s.positions[:, 0], s.positions[:, 2])
    analytic = np.column_stack([np.cos(phi), np.zeros_like(phi), -np.sin(phi)])
    away = np.abs(s.positions[:, 1]) < 0.45
    err = np.linalg.norm(s.tangents[away, :3] - analytic[away], axis=1)
    assert err.max() < np.pi / 64 and np.median(err) < 1e-3
    assert np.all(s.tangents[:, 3] == 1.0)  # b = n x t points to the north pole (v up)


def test_default_asset_is_nonconvex_unit_size():
    import trimesh

    k = make_default_asset()
    lo, hi = k.bounds()
    assert np.max(hi - lo) == pytest.approx(1.0, abs=1e-6)
    np.testing.assert_allclose((lo + hi) / 2, 0, atol=1e-6)
    tm = trimesh.Trimesh(k.positions, k.indices, process=True)
    assert tm.volume > 0  # outward winding: positive signed volume
    assert tm.volume < 0.5 * tm.convex_hull.volume  # non-convex: a knot, not a blob
    fn = face_normals(k.positions, k.indices)
    assert np.mean(np.sum(fn * k.normals[k.indices[:, 0]], axis=1) > 0) == 1.0
    assert k.uvs is not None and np.all(np.isfinite(k.tangents))


def test_transform_mesh_mirror_flips_winding_and_handedness():
    s = make_sphere_mesh(2)
    mirror = np.diag([-1.0, 1.0, 1.0, 1.0])
    m = transform_mesh(s, mirror)
    fn = face_normals(m.positions, m.indices)
    assert np.all(np.sum(fn * m.positions[m.indices].mean(axis=1), axis=1) > 0)
    np.testing.assert_allclose(m.normals, 2 * m.positions, atol=1e-6)
    assert np.all(m.tangents[:, 3] == -1.0)
    # the bitangent rule still gives the transformed dP/dv (towards the north pole, +y)
    b = m.tangents[:, 3:] * np.cross(m.normals, m.tangents[:, :3])
    away = np.abs(m.positions[:, 1]) < 0.45
    assert np.all(b[away, 1] > 0)
