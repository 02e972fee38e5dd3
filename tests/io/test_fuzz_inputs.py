"""Generated bad inputs for every reader and every JSON schema (issue #15), through one harness.

Each case is a file (or a command-line value) that must be refused: exit code 3 (2 for a usage
error), one line naming the file (or the flag), quickly, with the input's bytes unchanged and
nothing left beside it (no output, no temporary). Readers are called in-process where the
command line takes the same path (``scanlight`` only adds "scanlight CMD: error: " and the exit
code, which ``refused`` checks through ``ScanlightError.exit_code``); a representative set goes
through ``app.cli.main`` and a few through a real ``python -m app`` process.

Hypothesis generates the cases, derandomized (the same examples on every run, so CI is
deterministic), with an explicit example count and no per-example deadline (a slow CI machine
must not fail a case that is merely slow; ``refused`` has its own hang limit instead). Classes:

- PLY headers, ascii and binary: negative, huge, non-integer or lying counts, duplicated
  properties, unknown types and formats, no end_header, no vertex element, no x/y/z, list
  properties in the vertex, garbage rows;
- OBJ: face index 0, indices out of range, only zero-area triangles, NaN/infinite vertices, no
  faces;
- glTF (.gltf and .glb): node cycles, chains deeper than 64, shared-child DAGs expanding beyond
  100,000 instances, dangling node indices, accessor counts beyond their buffer or without data,
  buffers shorter than declared, JSON nested too deep;
- photos (EXR, PNG, JPEG): headers claiming more than 150 Mpixel, valid magic numbers followed
  by garbage;
- JSON schemas: camera, capture cameras, material, object, session: a field of the wrong type or
  out of range (the key named in the error), unknown keys, nesting too deep;
- ``expand --params``: wrong types and ranges, unknown fields (exit 2);
- numeric flags (``render --exposure 1e30`` ...): out of range or not finite (exit 2).
"""

from __future__ import annotations

import copy
import hashlib
import json
import struct
import subprocess
import sys
import tempfile
import time
import zlib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from app.errors import ScanlightError

EXAMPLES = 25           # generated examples per test (glTF and the JSON schemas: more)
HANG_LIMIT_S = 10.0     # a refusal slower than this is a hang (the worst took minutes or forever)
FUZZ = settings(max_examples=EXAMPLES, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture,
                                       HealthCheck.too_slow])
FUZZ_MORE = settings(FUZZ, max_examples=60)        # many fault classes in one test
FUZZ_MOST = settings(FUZZ, max_examples=150)       # every field of every JSON schema


# -- the harness ----------------------------------------------------------------------------------
def _snapshot(folder: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in folder.iterdir()}


def fresh(tmp_path: Path) -> Path:
    """A new empty folder per generated example (``tmp_path`` is shared by all of them)."""
    return Path(tempfile.mkdtemp(dir=tmp_path))


def refused(path: Path, load, *words: str, code: int = 3) -> str:
    """``load(path)`` raises one ScanlightError line of exit ``code`` naming ``path`` (and
    ``words``), within HANG_LIMIT_S; the folder holds exactly what it held, byte for byte."""
    before = _snapshot(path.parent)
    t0 = time.perf_counter()
    with pytest.raises(ScanlightError) as err:
        load(path)
    assert time.perf_counter() - t0 < HANG_LIMIT_S, "took too long to refuse"
    text = str(err.value)
    assert err.value.exit_code == code, text
    assert "\n" not in text and str(path) in text, text
    assert all(w in text for w in words), (words, text)
    assert _snapshot(path.parent) == before, "the input changed or something was left beside it"
    return text


def _load_cloud(p):
    from app.io.pointcloud import load_cloud
    return load_cloud(p)


def _load_mesh(p):
    from app.io.mesh import load_mesh
    return load_mesh(p)


def _read_image(p):
    from app.io.exr import read_image
    return read_image(p)


# -- PLY --------------------------------------------------------------------------------------------
PLY_FORMATS = ("ascii", "binary_little_endian", "binary_big_endian")
PLY_TYPES = {"char": "b", "uchar": "B", "short": "h", "ushort": "H", "int": "i", "uint": "I",
             "float": "f", "double": "d"}
PLY_FAULTS = ("negative count", "count beyond the file", "rows missing", "property twice",
              "unknown type", "unknown format", "no end_header", "no vertex element",
              "no z", "list in the vertex", "count not an integer", "garbage rows",
              "no rows")


@st.composite
def bad_ply(draw):
    """(file bytes, fault): a small valid PLY with one fault that must make it unreadable."""
    fmt = draw(st.sampled_from(PLY_FORMATS))
    fault = draw(st.sampled_from(PLY_FAULTS))
    names = ["x", "y", "z"] + draw(st.lists(st.sampled_from(("red", "green", "blue", "nx",
                                                              "intensity")),
                                            max_size=3, unique=True))
    types = [draw(st.sampled_from(sorted(PLY_TYPES))) for _ in names]
    rows = draw(st.integers(1, 4))
    if fault == "garbage rows":
        fmt = "ascii"
    props = [f"property {t} {n}" for t, n in zip(types, names)]
    if fmt == "ascii":
        body = b"".join((" ".join("1" for _ in names) + "\n").encode() for _ in range(rows))
        if fault == "garbage rows":
            body = b"".join(b"a b c\n" for _ in range(rows))
    else:
        order = "<" if fmt.endswith("little_endian") else ">"
        row = struct.pack(order + "".join(PLY_TYPES[t] for t in types), *([1] * len(names)))
        body = row * rows
    count = str(rows)
    element = "vertex"
    fmt_word = fmt
    if fault == "negative count":
        count = str(draw(st.integers(-10**15, -1)))
    elif fault == "count beyond the file":
        count = str(draw(st.integers(len(body) + 1, 10**15)))
    elif fault == "rows missing":
        count = str(rows + draw(st.integers(1, 3)))
    elif fault == "no rows":
        count, body = "0", b""
    elif fault == "count not an integer":
        count = draw(st.sampled_from(("1.5", "1e3", "ten", "0x10", "")))
    elif fault == "property twice":
        props.append(draw(st.sampled_from(props)))
    elif fault == "unknown type":
        bad = draw(st.text("abcdefghijklmnopqrstuvwxyz0123456789", min_size=1, max_size=8)
                   .filter(lambda t: t not in PLY_TYPES and t not in (
                       "list", "int8", "uint8", "int16", "uint16", "int32", "uint32",
                       "float32", "float64")))
        i = draw(st.integers(0, len(props) - 1))
        props[i] = f"property {bad} {names[i]}"
    elif fault == "unknown format":
        fmt_word = draw(st.sampled_from(("ascii2", "binary", "BINARY_LITTLE_ENDIAN", "text",
                                         "")))
    elif fault == "no vertex element":
        element = draw(st.sampled_from(("points", "face", "vertices")))
    elif fault == "no z":
        props = [p for p in props if p != f"property {types[2]} z"]
    elif fault == "list in the vertex":
        props.append("property list uchar int vertex_indices")
    head = ["ply", f"format {fmt_word} 1.0", f"element {element} {count}", *props]
    if fault != "no end_header":
        head.append("end_header")
    return ("\n".join(head) + "\n").encode() + body, fault


@FUZZ_MORE
@given(case=bad_ply())
def test_ply_headers_and_bodies(case, tmp_path):
    data, _fault = case
    p = fresh(tmp_path) / "scan.ply"
    p.write_bytes(data)
    refused(p, _load_cloud)


# -- OBJ --------------------------------------------------------------------------------------------
OBJ_FAULTS = ("index 0", "index out of range", "collinear", "one point", "non-finite vertex",
              "no faces")


@st.composite
def bad_obj(draw):
    fault = draw(st.sampled_from(OBJ_FAULTS))
    n = draw(st.integers(3, 6))
    coords = st.integers(-50, 50)
    verts = [[draw(coords) for _ in range(3)] for _ in range(n)]
    faces = [[draw(st.integers(1, n)) for _ in range(3)] for _ in range(draw(st.integers(1, 4)))]
    word = ""
    if fault == "index 0":
        f, k = draw(st.integers(0, len(faces) - 1)), draw(st.integers(0, 2))
        faces[f][k] = draw(st.sampled_from((0, "0/1", "0//1", "-0")))
        word = "index 0"
    elif fault == "index out of range":
        faces[0][draw(st.integers(0, 2))] = draw(st.one_of(st.integers(n + 1, 10**6),
                                                           st.integers(-10**6, -n - 1)))
    elif fault in ("collinear", "one point"):
        p0, d = [draw(coords) for _ in range(3)], [draw(st.integers(-3, 3)) for _ in range(3)]
        if fault == "one point":
            d = [0, 0, 0]
        verts = [[p0[i] + k * d[i] for i in range(3)] for k in range(n)]   # exact in floats
        word = "area"
    elif fault == "non-finite vertex":
        verts[draw(st.integers(0, n - 1))][draw(st.integers(0, 2))] = draw(
            st.sampled_from(("nan", "inf", "-inf", "1e999")))
        faces = [[1, 2, 3]]
    elif fault == "no faces":
        faces = []
    text = "".join(f"v {' '.join(map(str, v))}\n" for v in verts)
    text += "".join(f"f {' '.join(map(str, f))}\n" for f in faces)
    return text, word


@FUZZ
@given(case=bad_obj())
def test_obj_meshes(case, tmp_path):
    text, word = case
    p = fresh(tmp_path) / "asset.obj"
    p.write_text(text)
    refused(p, _load_mesh, word)


# -- glTF -------------------------------------------------------------------------------------------
def gltf_doc(nodes, roots=(0,), count=3, with_view=True, byte_length=36) -> dict:
    """A one-triangle glTF (positions in a data URI) over the node graph ``nodes``."""
    pos = struct.pack("<9f", 0, 0, 0, 1, 0, 0, 0, 1, 0)
    import base64
    uri = "data:application/octet-stream;base64," + base64.b64encode(pos).decode()
    accessor = {"componentType": 5126, "count": count, "type": "VEC3"}
    if with_view:
        accessor["bufferView"] = 0
    return {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": list(roots)}],
            "nodes": nodes, "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
            "accessors": [accessor],
            "bufferViews": [{"buffer": 0, "byteLength": 36}],
            "buffers": [{"byteLength": byte_length, "uri": uri}]}


def glb_bytes(doc: dict) -> bytes:
    js = dumps(doc).encode()
    js += b" " * (-len(js) % 4)
    return (b"glTF" + struct.pack("<II", 2, 12 + 8 + len(js))
            + struct.pack("<I4s", len(js), b"JSON") + js)


def _nest(depth: int) -> str:
    """A placeholder that ``dumps`` turns into JSON lists nested ``depth`` deep (json.dumps
    itself gives up near 1000 levels)."""
    return f"@deep{depth}@"


def dumps(doc) -> str:
    import re
    return re.sub(r'"@deep(\d+)@"', lambda m: "[" * int(m.group(1)) + "0" + "]" * int(m.group(1)),
                  json.dumps(doc))


GLTF_FAULTS = ("cycle", "deep chain", "shared-child DAG", "dangling child", "bad root",
               "accessor beyond its buffer", "accessor without data", "short buffer",
               "deep JSON")


@st.composite
def bad_gltf(draw):
    fault = draw(st.sampled_from(GLTF_FAULTS))
    word = ""
    if fault == "cycle":
        n = draw(st.integers(1, 12))
        nodes = [{"children": [i + 1]} for i in range(n - 1)] + [{"mesh": 0}]
        nodes[-1]["children"] = [draw(st.integers(0, n - 1))]
        doc, word = gltf_doc(nodes), "cycle"
    elif fault == "deep chain":
        n = draw(st.integers(65, 400))
        doc = gltf_doc([{"children": [i + 1]} for i in range(n - 1)] + [{"mesh": 0}])
        word = "deeper"
    elif fault == "shared-child DAG":
        levels, fan = draw(st.integers(17, 60)), draw(st.integers(2, 4))
        if fan ** levels <= 10**5:
            levels = 17
        doc = gltf_doc([{"children": [i + 1] * fan} for i in range(levels)] + [{"mesh": 0}])
        word = "instances"
    elif fault == "dangling child":
        doc = gltf_doc([{"children": [draw(st.one_of(st.integers(1, 10**9),
                                                      st.integers(-10**9, -1)))]}])
    elif fault == "bad root":
        doc = gltf_doc([{"mesh": 0}], roots=[draw(st.one_of(
            st.integers(1, 10**9), st.integers(-10**9, -1), st.text(max_size=3),
            st.booleans(), st.floats(allow_nan=False)))])
    elif fault == "accessor beyond its buffer":
        doc = gltf_doc([{"mesh": 0}], count=draw(st.integers(4, 10**15)))
    elif fault == "accessor without data":
        doc = gltf_doc([{"mesh": 0}], count=draw(st.integers(50_000_001, 10**15)),
                       with_view=False)
    elif fault == "short buffer":
        doc = gltf_doc([{"mesh": 0}], byte_length=draw(st.integers(37, 10**12)))
    else:
        doc = gltf_doc([{"mesh": 0, "extras": _nest(draw(st.integers(65, 3000)))}])
        word = "nested"
    return doc, word, draw(st.sampled_from((".gltf", ".glb")))


@FUZZ_MORE
@given(case=bad_gltf())
def test_gltf_documents(case, tmp_path):
    doc, word, ext = case
    p = fresh(tmp_path) / f"asset{ext}"
    p.write_bytes(glb_bytes(doc) if ext == ".glb" else dumps(doc).encode())
    refused(p, _load_mesh, word)


# -- photos -----------------------------------------------------------------------------------------
def png_header_only(width: int, height: int) -> bytes:
    def chunk(kind: bytes, data: bytes) -> bytes:
        return (struct.pack(">I", len(data)) + kind + data
                + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b""))
            + chunk(b"IEND", b""))


def exr_claiming(width: int, height: int) -> bytes:
    """A valid 8x8 EXR whose header's dataWindow is patched to width x height."""
    from app.io.exr import write_exr
    with tempfile.TemporaryDirectory() as d:
        write_exr(Path(d) / "s.exr", np.ones((8, 8, 3), np.float32))
        data = bytearray((Path(d) / "s.exr").read_bytes())
    key = b"dataWindow\x00box2i\x00"
    struct.pack_into("<4i", data, data.index(key) + len(key) + 4, 0, 0, width - 1, height - 1)
    return bytes(data)


MAX_SIDE = 2**31 - 1


@st.composite
def huge_size(draw):
    """(width, height) of more than 150 Mpixel, each side a valid PNG/EXR dimension."""
    w = draw(st.integers(1, MAX_SIDE))
    return w, draw(st.integers(150_000_000 // w + 1, MAX_SIDE))


@FUZZ
@given(size=huge_size(), ext=st.sampled_from((".png", ".exr")))
def test_photos_claiming_more_pixels_than_the_limit(size, ext, tmp_path):
    """Decompression bombs and lying headers: refused from the header, nothing decoded."""
    if ext == ".exr":
        size = (min(size[0], 2**30), min(size[1], 2**30))      # int32 box, w - 1 must fit
        if size[0] * size[1] <= 150_000_000:
            size = (2**30, 2**30)
    p = fresh(tmp_path) / f"photo{ext}"
    p.write_bytes(png_header_only(*size) if ext == ".png" else exr_claiming(*size))
    refused(p, _read_image)


MAGIC = {".png": b"\x89PNG\r\n\x1a\n", ".exr": b"v/1\x01", ".jpg": b"\xff\xd8\xff"}


@FUZZ
@given(ext=st.sampled_from(sorted(MAGIC)), tail=st.binary(max_size=200))
def test_photos_of_garbage_behind_a_valid_magic_number(ext, tail, tmp_path):
    p = fresh(tmp_path) / f"photo{ext}"
    p.write_bytes(MAGIC[ext] + tail)
    refused(p, _read_image)


# -- JSON schemas -----------------------------------------------------------------------------------
# Wrong values by the kind of field they replace; none of them is valid for that kind.
_JUNK = st.one_of(st.none(), st.booleans(), st.text(max_size=6), st.just("1.5"),
                  st.lists(st.integers(), max_size=2),
                  st.dictionaries(st.text(max_size=2), st.integers(), max_size=1))
NOT_NUMBER = st.one_of(_JUNK, st.just(float("nan")), st.just(float("inf")), st.just(10**400))
NOT_INT = st.one_of(NOT_NUMBER, st.floats(0.01, 0.99).map(lambda f: 64 + f))
NOT_STRING = st.one_of(st.booleans(), st.integers(), st.floats(allow_nan=False),
                       st.lists(st.text(max_size=2), max_size=2), st.none())
NOT_PATH = st.one_of(st.booleans(), st.integers(), st.lists(st.text(max_size=2), max_size=2),
                     st.just(""), st.just("  "), st.just("a\0b.ply"))
_BAD_ELEMENT = st.one_of(st.booleans(), st.text(max_size=3), st.none(), st.just([1]))
NOT_VEC3 = st.one_of(
    _JUNK, st.just("1,2,3"),
    st.lists(st.floats(-10, 10), min_size=0, max_size=2),
    st.lists(st.floats(-10, 10), min_size=4, max_size=5),
    st.tuples(st.floats(-10, 10), _BAD_ELEMENT, st.floats(-10, 10)).map(list),
    st.tuples(st.just(float("nan")), st.just(0), st.just(0)).map(list))
FAR = st.floats(1.01e9, 1e308)
NOT_COORD = st.one_of(NOT_VEC3, st.tuples(FAR, st.just(0.0), st.just(0.0)).map(list),
                      st.tuples(st.just(0.0), FAR.map(lambda v: -v), st.just(0.0)).map(list))


def _number_outside(lo, hi):
    return st.one_of(NOT_NUMBER, st.floats(hi * 1.01 + 1e-9, 1e300),
                     st.floats(-1e300, lo - abs(lo) * 0.01 - 1e-9))


def _int_outside(lo, hi):
    return st.one_of(NOT_INT, st.integers(hi + 1, 10**12), st.integers(-10**12, lo - 1))


CAMERA = {"position": [0.3, 1.0, 0.9], "look_at": [0.0, 0.8, 0.0], "up": [0.0, 1.0, 0.0],
          "fov_y_deg": 40, "width": 8, "height": 6}
CAMERA_FIELDS = {"position": NOT_COORD, "look_at": NOT_COORD, "up": NOT_COORD,
                 "fov_y_deg": _number_outside(0.1, 179), "width": _int_outside(1, 16384),
                 "height": _int_outside(1, 16384), "name": NOT_STRING}
MATERIAL = {"name": "m", "base_color": [0.5, 0.5, 0.5], "roughness": 0.5, "metallic": 0.0}
MATERIAL_FIELDS = {"name": NOT_STRING, "base_color": NOT_VEC3,
                   **{k: NOT_NUMBER for k in ("subsurface", "metallic", "specular",
                                               "specular_tint", "roughness", "anisotropic",
                                               "sheen", "sheen_tint", "clearcoat",
                                               "clearcoat_gloss")}}
OBJECT = {"mesh": "sphere", "translate": [0.0, 0.8, 0.0], "scale": 0.6, "rotate_deg": [0, 0, 0]}
OBJECT_FIELDS = {"mesh": NOT_PATH, "translate": NOT_COORD, "scale": _number_outside(1e-6, 1e6),
                 "rotate_deg": NOT_VEC3}
CAPTURE = [{"name": "a", "position": [0.0, 1.0, 0.0]}, dict(CAMERA)]
SESSION = {"scanlight_session": 1,
           "files": {"cloud": "demo", "photo": "demo", "hdr_cloud": None, "asset": "sphere"},
           "capture_cameras": [{"name": "c", "position": [0.0, 1.0, 0.0]}],
           "asset_transform": {"translate": [0, 0.6, 0], "rotate_deg": [0, 0, 0], "scale": 0.8},
           "materials": [dict(MATERIAL)], "mode": "hybrid", "camera": dict(CAMERA),
           "settings": {"pbgi.microbuffer": 16, "view.exposure": 0.5, "view.tonemap": "clamp",
                        "view.show_cameras": True}}


def _session_fields():
    from app.params import BY_KEY
    out = {("files", k): NOT_PATH for k in ("cloud", "photo", "hdr_cloud", "asset")}
    out.update({("capture_cameras", 0, "position"): NOT_COORD,
                ("capture_cameras", 0, "name"): NOT_STRING,
                ("asset_transform", "translate"): NOT_COORD,
                ("asset_transform", "rotate_deg"): NOT_VEC3,
                ("asset_transform", "scale"): _number_outside(1e-6, 1e6),
                ("mode",): st.one_of(st.integers(), st.booleans(), st.just("fast"),
                                     st.just("Hybrid"))})
    out.update({("camera", k): v for k, v in CAMERA_FIELDS.items()})
    out.update({("materials", 0, k): v for k, v in MATERIAL_FIELDS.items()})
    wrong = {"float": st.one_of(_JUNK.filter(lambda v: v is not None),
                                st.just(float("nan"))),
             "int": _JUNK.filter(lambda v: v is not None),
             "choice": st.one_of(st.integers(), st.booleans(), st.just("nope")),
             "bool": st.one_of(st.text(max_size=3), st.just(2), st.just([True]))}
    for key in ("pbgi.microbuffer", "view.exposure", "view.tonemap", "view.show_cameras",
                "hdr.method", "hdr.threshold_ldr"):
        out[("settings", key)] = wrong[BY_KEY[key].kind]
    return out


def _load_camera(p):
    from app.camera import load_camera
    return load_camera(p)


def _load_material(p):
    from app.material import load_material
    return load_material(p)


def _load_object(p):
    from app.io.formats import load_object
    return load_object(p)


def _load_cameras(p):
    from app.hdr.job import load_cameras
    return load_cameras(p)


def _load_session(p):
    from app.settings import load_session
    return load_session(p)


# kind -> (valid document, {key path: wrong values}, loader, unknown keys refused)
SCHEMAS = {
    "camera": (CAMERA, {(k,): v for k, v in CAMERA_FIELDS.items()}, _load_camera, True),
    "material": (MATERIAL, {(k,): v for k, v in MATERIAL_FIELDS.items()}, _load_material, True),
    "object": (OBJECT, {(k,): v for k, v in OBJECT_FIELDS.items()}, _load_object, True),
    "capture cameras": (CAPTURE, {(0, "position"): NOT_COORD, (0, "name"): NOT_STRING,
                                  **{(1, k): v for k, v in CAMERA_FIELDS.items()}},
                        _load_cameras, True),
    "session": (SESSION, None, _load_session, False),
}


def _set(doc, path, value):
    for key in path[:-1]:
        doc = doc[key]
    doc[path[-1]] = value


@st.composite
def bad_json_input(draw):
    """(kind, document, word the error must contain): one field of a valid document replaced by
    a value of the wrong type or out of range, or an unknown key, or nesting too deep."""
    kind = draw(st.sampled_from(sorted(SCHEMAS)))
    valid, fields, _, strict = SCHEMAS[kind]
    fields = fields or _session_fields()
    doc = copy.deepcopy(valid)
    how = draw(st.sampled_from(("wrong value",) * 4 + ("unknown key", "too deep")
                               if strict else ("wrong value",) * 4 + ("too deep",)))
    if how == "too deep":
        target = doc[0] if isinstance(doc, list) else doc
        target["position" if kind == "capture cameras" else "look_at" if kind == "camera"
               else "name" if kind == "material" else "translate" if kind == "object"
               else "settings"] = _nest(draw(st.integers(65, 3000)))
        return kind, doc, "nested"
    if how == "unknown key":
        key = draw(st.sampled_from(("translation", "fov", "Width", "colour", "positon", "")))
        _set(doc, ((0,) if kind == "capture cameras" else ()) + (key,), 1)
        return kind, doc, "unknown"
    path = draw(st.sampled_from(sorted(fields, key=str)))
    _set(doc, path, draw(fields[path]))
    return kind, doc, str(path[-1])


@FUZZ_MOST
@given(case=bad_json_input())
def test_json_inputs_of_the_wrong_type_or_shape(case, tmp_path):
    kind, doc, word = case
    p = fresh(tmp_path) / f"{kind.replace(' ', '_')}.json"
    p.write_text(dumps(doc))
    refused(p, SCHEMAS[kind][2], word)


@FUZZ
@given(w=st.integers(8193, 16384), h=st.integers(8193, 16384),
       where=st.sampled_from(("camera", "capture cameras", "session")))
def test_camera_images_beyond_the_pixel_limit(w, h, where, tmp_path):
    """A 16384x16384 capture camera grew expand to 24 GB before the kernel killed it."""
    cam = {**CAMERA, "width": w, "height": h}
    doc = {"camera": cam, "capture cameras": [cam], "session": {**SESSION, "camera": cam}}[where]
    p = fresh(tmp_path) / "cams.json"
    p.write_text(json.dumps(doc))
    refused(p, SCHEMAS[where][2], "limit")


# -- expand --params and numeric flags (usage errors, exit 2) -------------------------------------
def _params_field():
    from app.params import EXPAND_KEYS, BY_KEY
    return st.sampled_from([BY_KEY[k] for k in EXPAND_KEYS])


@st.composite
def bad_params(draw):
    p = draw(_params_field())
    if draw(st.integers(0, 5)) == 0:
        return {draw(st.sampled_from(("neighbors", "tl", "hdr.nope", "face"))): 1}, "unknown"
    if p.kind == "float":
        value = draw(st.one_of(_JUNK.filter(lambda v: v is not None or not p.optional),
                               _number_outside(p.lo, p.hi)).filter(
            lambda v: not (v is None and p.optional)))
    elif p.kind == "int":
        value = draw(_int_outside(int(p.lo), int(p.hi)).filter(
            lambda v: not (v is None and p.optional)))
    elif p.kind == "choice":
        value = draw(st.one_of(st.integers(), st.booleans(), st.just("nope"),
                               st.just(p.choices[0].upper())))
    else:
        value = draw(st.one_of(st.text(max_size=3), st.just(2), st.just([True]), st.none()))
    return {draw(st.sampled_from((p.name, p.key))): value}, p.name


def _expand_argv(folder: Path, *extra: str) -> list[str]:
    return ["expand", "--cloud", str(folder / "room.ply"), "--photo", str(folder / "photo.exr"),
            "--cameras", str(folder / "cams.json"), "--out", str(folder / "hdr.ply"), *extra]


@FUZZ_MORE
@given(case=bad_params())
def test_expand_params_of_the_wrong_type_or_range(case, tmp_path):
    """--params is a JSON object of ExpandParams fields: each wrong one is a usage error."""
    from app.cli import build_parser
    from app.commands.expand import expand_params
    extra, word = case
    args = build_parser().parse_args(_expand_argv(tmp_path, "--params", json.dumps(extra)))
    with pytest.raises(ScanlightError) as err:
        expand_params(args)
    text = str(err.value)
    assert err.value.exit_code == 2 and "\n" not in text and "--params" in text, text
    assert word in text, text


def test_expand_params_nested_too_deep_is_a_usage_error(tmp_path):
    from app.cli import build_parser
    from app.commands.expand import expand_params
    args = build_parser().parse_args(_expand_argv(tmp_path, "--params",
                                                  dumps({"seed": _nest(5000)})))
    with pytest.raises(ScanlightError, match="--params is JSON nested deeper") as err:
        expand_params(args)
    assert err.value.exit_code == 2


def _numeric_flags():
    from app.commands.options import COMMAND_FLAGS
    from app.params import BY_KEY
    return [(cmd, flag, BY_KEY[key]) for cmd in ("render", "expand", "evaluate")
            for flag, key in COMMAND_FLAGS[cmd].items() if BY_KEY[key].kind in ("float", "int")]


@st.composite
def extreme_flag(draw):
    cmd, flag, p = draw(st.sampled_from(_numeric_flags()))
    if p.kind == "int":
        value = draw(st.one_of(st.integers(int(p.hi) + 1, 10**30),
                               st.integers(-10**30, int(p.lo) - 1)))
    else:
        value = draw(st.one_of(st.floats(p.hi * 1.01 + 1e-9, 1e308), st.just(float("inf")),
                               st.floats(-1e308, p.lo - abs(p.lo) * 0.01 - 1e-9),
                               st.just(float("nan")), st.just(1e30)))
    return cmd, flag, repr(value) if p.kind == "float" else str(value)


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    """Valid inputs of every command: a small room, a photo, cameras, an object, a material."""
    from tests.support import scenes as S

    from app.io.exr import write_exr
    from app.io.pointcloud import save_cloud
    d = tmp_path_factory.mktemp("good")
    save_cloud(S.box_room(0.1), d / "room.ply")
    save_cloud(S.box_room(0.1), d / "gt.ply")
    ramp = np.geomspace(0.01, 8.0, 32, dtype=np.float32)
    write_exr(d / "photo.exr", np.repeat(np.tile(ramp, (32, 1))[..., None], 3, axis=-1))
    (d / "cams.json").write_text(json.dumps([{"position": [0.0, 1.0, 0.0]}]))
    (d / "obj.json").write_text(json.dumps(OBJECT))
    (d / "cam.json").write_text(json.dumps(CAMERA))
    (d / "mat.json").write_text(json.dumps(MATERIAL))
    return d


def _argv(cmd: str, good: Path, out: Path) -> list[str]:
    if cmd == "render":
        return ["render", "--cloud", str(good / "room.ply"), "--object", str(good / "obj.json"),
                "--camera", str(good / "cam.json"), "--out", str(out / "o.exr")]
    if cmd == "expand":
        return ["expand", "--cloud", str(good / "room.ply"), "--photo", str(good / "photo.exr"),
                "--cameras", str(good / "cams.json"), "--out", str(out / "o.ply")]
    return ["evaluate", "expansion", "--cloud", str(good / "room.ply"), "--gt",
            str(good / "gt.ply"), "--no-render", "--json", str(out / "o.json")]


def _cli(argv, capsys) -> tuple[int, str]:
    from app.cli import main
    code = main(argv)
    return code, capsys.readouterr().err.strip()


def _one_error_line(err: str) -> str:
    lines = [ln for ln in err.splitlines() if ln.strip()]
    errors = [ln for ln in lines if "error:" in ln]
    assert len(errors) == 1 and "Traceback" not in err and errors[0] == lines[-1], err
    return errors[0]


@FUZZ
@given(case=extreme_flag())
def test_extreme_numeric_flags_are_usage_errors(case, good, tmp_path, capsys):
    """``--exposure 1e30`` and its kind: exit 2, one line naming the flag, nothing written."""
    cmd, flag, value = case
    out = fresh(tmp_path)
    before = _snapshot(good)
    code, err = _cli(_argv(cmd, good, out) + [f"{flag}={value}"], capsys)   # "-1e+308" too
    line = _one_error_line(err)
    assert code == 2 and flag in line, err
    assert not list(out.iterdir()) and _snapshot(good) == before


# -- the same kinds of file through the command line ----------------------------------------------
def _gltf_dag() -> bytes:
    return json.dumps(gltf_doc([{"children": [i + 1, i + 1]} for i in range(40)]
                               + [{"mesh": 0}])).encode()


CLI_CASES = {
    "render --cloud: PLY claiming 10^12 rows": (
        "render", "--cloud", "bad.ply", b"ply\nformat ascii 1.0\nelement face 1000000000000\n"
        b"property list uchar int vertex_indices\nelement vertex 1\nproperty float x\n"
        b"property float y\nproperty float z\nend_header\n0 0 0\n"),
    "render --camera: width true": ("render", "--camera", "bad.json",
                                    json.dumps({**CAMERA, "width": True}).encode()),
    "render --camera: at 1e308": ("render", "--camera", "bad.json",
                                  json.dumps({**CAMERA, "position": [1e308, 0, 0]}).encode()),
    "render --material: base_color '123'": ("render", "--material", "bad.json",
                                            b'{"base_color": "123"}'),
    "render --object: a 2^40-path glTF": ("render", "--object", "bad.gltf", _gltf_dag()),
    "render --object: OBJ face index 0": ("render", "--object", "bad.obj",
                                          b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n"),
    "render --object: zero-area OBJ": ("render", "--object", "bad.obj",
                                       b"v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n"),
    "render --object: object nested too deep": ("render", "--object", "bad.json",
                                                ("[" * 5000 + "]" * 5000).encode()),
    "expand --cameras: 16384x16384 capture camera": (
        "expand", "--cameras", "bad.json",
        json.dumps([{**CAMERA, "width": 16384, "height": 16384}]).encode()),
    "expand --photo: decompression bomb PNG": ("expand", "--photo", "bad.png",
                                               png_header_only(30000, 30000)),
    "expand --cloud: element vertex -5": (
        "expand", "--cloud", "bad.ply", b"ply\nformat ascii 1.0\nelement vertex -5\n"
        b"property float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n"),
    "evaluate --gt: duplicated PLY property": (
        "evaluate", "--gt", "bad.ply", b"ply\nformat ascii 1.0\nelement vertex 1\n"
        b"property float x\nproperty float y\nproperty float z\nproperty float x\n"
        b"end_header\n0 0 0 0\n"),
}


def _cli_case(case: str, good: Path, folder: Path) -> tuple[list[str], Path]:
    cmd, flag, name, data = CLI_CASES[case]
    bad = folder / name
    bad.write_bytes(data)
    argv = _argv(cmd, good, folder)
    if flag == "--object" and name != "bad.json":
        (folder / "obj.json").write_text(json.dumps({"mesh": str(bad)}))
        bad_arg = folder / "obj.json"
    else:
        bad_arg = bad
    if flag in argv:
        argv[argv.index(flag) + 1] = str(bad_arg)
    else:
        argv += [flag, str(bad_arg)]
    return argv, bad


@pytest.mark.parametrize("case", sorted(CLI_CASES))
def test_each_reader_through_the_command_line(case, good, tmp_path, capsys):
    """Exit 3, one line naming the bad file, no output or temporary, inputs unchanged."""
    argv, bad = _cli_case(case, good, tmp_path)
    before, before_good = _snapshot(tmp_path), _snapshot(good)
    t0 = time.perf_counter()
    code, err = _cli(argv, capsys)
    assert time.perf_counter() - t0 < 60
    line = _one_error_line(err)
    assert code == 3 and str(bad) in line, err
    assert _snapshot(tmp_path) == before and _snapshot(good) == before_good


def test_an_all_black_ground_truth_is_refused_by_evaluate(good, tmp_path, capsys):
    """Relative errors against zero are undefined: evaluate refuses (exit 3) rather than
    report 1e12."""
    from tests.support import scenes as S

    from app.io.pointcloud import save_cloud
    black = S.box_room(0.1)
    black.colors[:] = 0.0
    save_cloud(black, tmp_path / "black.ply")
    before = _snapshot(tmp_path)
    argv = _argv("evaluate", good, tmp_path)
    argv[argv.index("--gt") + 1] = str(tmp_path / "black.ply")
    code, err = _cli(argv, capsys)
    line = _one_error_line(err)
    assert code == 3 and "black" in line and str(tmp_path / "black.ply") in line, err
    assert _snapshot(tmp_path) == before


@pytest.mark.parametrize("case", ["render --camera: width true",
                                  "render --object: a 2^40-path glTF",
                                  "expand --cameras: 16384x16384 capture camera",
                                  "evaluate --gt: duplicated PLY property"])
def test_a_real_process(case, good, tmp_path):
    """The same through ``python -m app``: the exit code and stderr a user sees."""
    argv, bad = _cli_case(case, good, tmp_path)
    before = _snapshot(tmp_path)
    res = subprocess.run([sys.executable, "-m", "app", *argv], capture_output=True, text=True,
                         timeout=120, cwd=Path(__file__).resolve().parents[2])
    line = _one_error_line(res.stderr)
    assert res.returncode == 3 and str(bad) in line, res.stderr
    assert _snapshot(tmp_path) == before


def test_capture_cube_maps_beyond_the_pixel_limit(good, tmp_path, capsys):
    """Two cube maps of 8192^2 faces are 805 Mpixel of captures: refused before rendering."""
    (tmp_path / "cams.json").write_text(json.dumps([[0.0, 1.0, 0.0], [0.5, 1.0, 0.0]]))
    argv = _argv("expand", good, tmp_path)
    argv[argv.index("--cameras") + 1] = str(tmp_path / "cams.json")
    before = _snapshot(tmp_path)
    t0 = time.perf_counter()
    code, err = _cli(argv + ["--face-size", "8192", "--report", str(tmp_path / "r.json")],
                     capsys)
    assert time.perf_counter() - t0 < 60
    line = _one_error_line(err)
    assert code == 3 and str(tmp_path / "cams.json") in line and "limit" in line, err
    assert _snapshot(tmp_path) == before
