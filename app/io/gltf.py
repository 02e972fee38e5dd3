"""glTF 2.0 reader (.gltf / .glb), Draco included, down to flat numpy arrays and Disney materials.

Why our own reader rather than trimesh's: trimesh 4.x decodes no Draco (the real models in
../shared/data are all KHR_draco_mesh_compression) and stores ``baseColorFactor`` as uint8, which
quantises a linear factor (0.01 becomes 0.0118). The format is small enough to read exactly:
accessors (strides, normalised integers, sparse), the node hierarchy (matrix or TRS), triangle
primitives (lists, strips, fans) and the metallic-roughness material.

Conventions of the result (shared with app.io.mesh.Mesh): positions in world space (all node
transforms applied; a mirroring transform flips the winding, as the glTF spec says); UVs in
OpenGL convention (origin bottom-left, so v = 1 - v_gltf); texture arrays stored bottom row
first, so they upload to GL as they are. TANGENT attributes are ignored (tangents are recomputed
from UVs); primitives without NORMAL get flat normals, as the glTF spec requires.
"""

from __future__ import annotations

import base64
import logging
import struct
import urllib.parse
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from app.color import srgb_to_linear
from app.errors import ScanlightError
from app.io.limits import (MAX_GLTF_DEPTH, MAX_GLTF_INSTANCES, MAX_MESH_VERTICES,
                            MAX_TEXTURE_PIXELS)
from app.io.schema import parse_json, show
from app.material import Material

log = logging.getLogger(__name__)

_COMPONENT = {5120: "i1", 5121: "u1", 5122: "i2", 5123: "u2", 5125: "u4", 5126: "f4"}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_TRIANGLES, _STRIP, _FAN = 4, 5, 6
_DRACO = "KHR_draco_mesh_compression"
MAX_INSTANCES = MAX_GLTF_INSTANCES   # app.io.limits: a node shared by two parents is drawn
#                                     twice; forty levels of that would be 2^40 copies


@dataclass
class Primitive:
    """One triangle primitive in world space (float64), before normals/tangents are completed."""

    positions: np.ndarray
    indices: np.ndarray
    normals: np.ndarray | None
    uvs: np.ndarray | None
    material: int  # index into the materials list returned with it


class _Reader:
    def __init__(self, path: Path, warn):
        self.path = path
        self.warn = warn
        self.doc, self.buffers = self._parse_container(path.read_bytes())
        self.images: dict[tuple[int, str], np.ndarray | None] = {}

    # -- container ----------------------------------------------------------------------------
    def _parse_container(self, data: bytes):
        p = self.path
        if data[:4] == b"glTF":
            if len(data) < 20:
                raise ScanlightError(p, "truncated GLB: shorter than its 12-byte header")
            _, version, length = struct.unpack_from("<4sII", data, 0)
            if version != 2:
                raise ScanlightError(p, f"unsupported GLB version {version} (need 2)")
            if length > len(data):
                raise ScanlightError(p, f"truncated GLB: header says {length} bytes, file has "
                                        f"{len(data)}")
            chunks, off = [], 12
            while off + 8 <= length:
                clen, ctype = struct.unpack_from("<I4s", data, off)
                if off + 8 + clen > length:
                    raise ScanlightError(p, f"truncated GLB: chunk {ctype!r} needs {clen} bytes, "
                                            f"{length - off - 8} left")
                chunks.append((ctype, data[off + 8: off + 8 + clen]))
                off += 8 + ((clen + 3) & ~3)
            if not chunks or chunks[0][0] != b"JSON":
                raise ScanlightError(p, "corrupt GLB: first chunk is not JSON")
            doc = self._json(chunks[0][1])
            bin_chunk = next((c for t, c in chunks[1:] if t == b"BIN\x00"), None)
        else:
            doc, bin_chunk = self._json(data), None
        version = str(doc.get("asset", {}).get("version", "")) if isinstance(doc, dict) else ""
        if not version.startswith("2"):
            raise ScanlightError(p, "not a glTF 2.0 file (asset.version is not 2.x)")
        unsupported = set(doc.get("extensionsRequired", [])) - {_DRACO}
        if unsupported:
            raise ScanlightError(p, f"glTF requires unsupported extensions: "
                                    f"{', '.join(sorted(unsupported))}")
        buffers = []
        for i, b in enumerate(doc.get("buffers", [])):
            if "uri" in b:
                buffers.append(self._uri_bytes(b["uri"], f"buffer {i}", required=True))
            elif i == 0 and bin_chunk is not None:
                buffers.append(bin_chunk)
            else:
                raise ScanlightError(p, f"corrupt glTF: buffer {i} has no data "
                                        "(no uri, no BIN chunk)")
            if len(buffers[-1]) < b.get("byteLength", 0):
                raise ScanlightError(p, f"truncated glTF: buffer {i} declares {b['byteLength']} "
                                        f"bytes, holds {len(buffers[-1])}")
        return doc, buffers

    def _json(self, raw: bytes):
        return parse_json(raw, self.path, "glTF JSON", invalid="corrupt glTF JSON")

    def _uri_bytes(self, uri: str, what: str, required: bool) -> bytes | None:
        if uri.startswith("data:"):
            try:
                return base64.b64decode(uri.split(",", 1)[1])
            except (IndexError, ValueError):
                raise ScanlightError(self.path, f"corrupt glTF: bad data URI in {what}") from None
        f = self.path.parent / urllib.parse.unquote(uri)
        if not f.is_file():
            if required:
                raise ScanlightError(self.path, f"{what} file {uri!r} not found")
            return None
        return f.read_bytes()

    # -- accessors ----------------------------------------------------------------------------
    def view_bytes(self, index: int) -> tuple[bytes, int, int, int | None]:
        """(buffer, byte offset, byte length, byte stride) of a bufferView, bounds-checked."""
        try:
            v = self.doc["bufferViews"][index]
            buf = self.buffers[v["buffer"]]
        except (KeyError, IndexError, TypeError):
            raise ScanlightError(self.path, f"corrupt glTF: bad bufferView {index}") from None
        off, length = v.get("byteOffset", 0), v["byteLength"]
        if off + length > len(buf):
            raise ScanlightError(self.path, f"truncated glTF: bufferView {index} ends at byte "
                                            f"{off + length}, its buffer holds {len(buf)}")
        return buf, off, length, v.get("byteStride")

    def accessor(self, index: int) -> np.ndarray:
        """(count, width) array; normalised integers become floats in [0, 1] / [-1, 1]."""
        try:
            a = self.doc["accessors"][index]
            comp = np.dtype("<" + _COMPONENT[a["componentType"]])
            width, count = _WIDTH[a["type"]], self._declared_count(index)
        except (KeyError, IndexError, TypeError):
            raise ScanlightError(self.path, f"corrupt glTF: bad accessor {show(index)}") from None
        if "bufferView" not in a and count > MAX_MESH_VERTICES:   # zeros, nothing to bound it
            raise ScanlightError(self.path, f"accessor {index} declares {count:,} elements, "
                                            f"more than the limit of {MAX_MESH_VERTICES:,}")
        if "bufferView" in a:
            buf, view_off, length, stride = self.view_bytes(a["bufferView"])
            off = view_off + a.get("byteOffset", 0)
            elem = comp.itemsize * width
            stride = stride or elem
            end = off + stride * (count - 1) + elem if count else off
            if end > view_off + length:
                raise ScanlightError(self.path, f"truncated glTF: accessor {index} reads past its "
                                                "bufferView")
            raw = np.zeros(count * stride, dtype=np.uint8)  # the last element may end early
            raw[: end - off] = np.frombuffer(buf, dtype=np.uint8, count=end - off, offset=off)
            out = raw.reshape(count, stride)[:, :elem].copy().view(comp).reshape(count, width)
        else:
            out = np.zeros((count, width), dtype=comp)
        if "sparse" in a:
            s = a["sparse"]
            n = int(s["count"])
            ib, io_, _, _ = self.view_bytes(s["indices"]["bufferView"])
            idx = np.frombuffer(ib, dtype="<" + _COMPONENT[s["indices"]["componentType"]], count=n,
                                offset=io_ + s["indices"].get("byteOffset", 0))
            vb, vo, _, _ = self.view_bytes(s["values"]["bufferView"])
            vals = np.frombuffer(vb, dtype=comp, count=n * width,
                                 offset=vo + s["values"].get("byteOffset", 0)).reshape(n, width)
            if n and idx.max() >= count:
                raise ScanlightError(self.path, f"corrupt glTF: sparse accessor {index} index "
                                                "out of range")
            out = out.copy()
            out[idx] = vals
        if a.get("normalized") and comp.kind in "iu":
            out = np.maximum(out.astype(np.float64) / np.iinfo(comp).max, -1.0)
        return out

    # -- Draco --------------------------------------------------------------------------------
    def draco(self, prim: dict):
        """(attributes by semantic, indices) of a KHR_draco_mesh_compression primitive."""
        import DracoPy

        ext = prim["extensions"][_DRACO]
        buf, off, length, _ = self.view_bytes(ext["bufferView"])
        try:
            dm = DracoPy.decode(buf[off: off + length])
        except Exception as exc:  # DracoPy raises its own exception classes
            raise ScanlightError(self.path, f"corrupt Draco mesh data ({exc})") from None
        attrs = {}
        for semantic, uid in ext.get("attributes", {}).items():
            att = dm.get_attribute_by_unique_id(uid)
            if att is None:
                raise ScanlightError(self.path, f"corrupt Draco mesh: no attribute {semantic}")
            data = np.asarray(att["data"])
            attrs[semantic] = data.reshape(len(data), -1)
        faces = np.asarray(dm.faces, dtype=np.int64).reshape(-1, 3)
        return attrs, faces

    # -- images -------------------------------------------------------------------------------
    def texture(self, ref: dict | None, kind: str, material: str) -> np.ndarray | None:
        """Float32 texture (H, W, C) bottom row first; None (with a warning) when unusable.

        kind "srgb": base colour, RGB decoded from sRGB, alpha kept; "linear": data textures.
        """
        if not ref:
            return None
        if ref.get("texCoord", 0) != 0:
            self.warn(f"material {material!r}: texture uses TEXCOORD_{ref['texCoord']}, only "
                      "TEXCOORD_0 is supported; using the factor instead")
            return None
        if "KHR_texture_transform" in ref.get("extensions", {}):
            self.warn(f"material {material!r}: KHR_texture_transform is ignored")
        try:
            source = self.doc["textures"][ref["index"]]["source"]
            image = self.doc["images"][source]
        except (KeyError, IndexError, TypeError):
            self.warn(f"material {material!r}: texture {ref.get('index')} has no image; "
                      "using the factor instead")
            return None
        key = (source, kind)
        if key in self.images:
            return self.images[key]
        name = image.get("uri", f"image {source}")
        if "bufferView" in image:
            buf, off, length, _ = self.view_bytes(image["bufferView"])
            blob = buf[off: off + length]
        elif "uri" in image:
            blob = self._uri_bytes(image["uri"], f"image {source}", required=False)
        else:
            blob = None
        tex = None
        if blob is None:
            self.warn(f"material {material!r}: texture file {name!r} not found; "
                      "using the factor instead")
        else:
            tex = decode_texture(blob, kind)
            if tex is None:
                self.warn(f"material {material!r}: texture {name!r} could not be decoded; "
                          "using the factor instead")
        self.images[key] = tex
        return tex

    def material(self, index: int | None) -> Material:
        """Disney parameters from a glTF metallic-roughness material (glTF defaults when absent).

        Factors and textures are kept apart (the renderer multiplies them, as glTF does);
        specular stays 0.5 (glTF's fixed F0 = 4%); emissive strength is folded into emissive.
        """
        if index is None:
            return Material(name="gltf default", base_color=(1.0, 1.0, 1.0), metallic=1.0,
                            roughness=1.0)
        try:
            m = self.doc["materials"][index]
        except (KeyError, IndexError, TypeError):
            raise ScanlightError(self.path, f"corrupt glTF: material {index} does not "
                                            "exist") from None
        name = str(m.get("name") or f"material {index}")
        pbr = m.get("pbrMetallicRoughness", {})
        if "KHR_materials_pbrSpecularGlossiness" in m.get("extensions", {}) and not pbr:
            self.warn(f"material {name!r}: specular-glossiness is not supported; using defaults")
        factor = np.asarray(pbr.get("baseColorFactor", [1, 1, 1, 1]), dtype=np.float64)
        emissive = np.asarray(m.get("emissiveFactor", [0, 0, 0]), dtype=np.float64)
        strength = m.get("extensions", {}).get("KHR_materials_emissive_strength", {})
        emissive = emissive * float(strength.get("emissiveStrength", 1.0))
        if m.get("emissiveTexture"):
            self.warn(f"material {name!r}: emissive texture is ignored (factor used)")
        if m.get("occlusionTexture"):
            log.info("%s: material %r: occlusion texture ignored (PBGI computes occlusion)",
                     self.path, name)
        return Material(
            name=name,
            base_color=tuple(float(c) for c in np.clip(factor[:3], 0.0, 1.0)),
            metallic=float(np.clip(pbr.get("metallicFactor", 1.0), 0.0, 1.0)),
            roughness=float(np.clip(pbr.get("roughnessFactor", 1.0), 0.0, 1.0)),
            specular=0.5,
            emissive=tuple(float(c) for c in np.maximum(emissive, 0.0)),
            base_color_texture=self.texture(pbr.get("baseColorTexture"), "srgb", name),
            metallic_roughness_texture=self.texture(pbr.get("metallicRoughnessTexture"),
                                                    "linear", name),
            normal_texture=self.texture(m.get("normalTexture"), "linear", name),
        )

    # -- scene --------------------------------------------------------------------------------
    def primitives(self):
        """Yield (Primitive, glTF material index or None) for every node instance in the scene."""
        doc = self.doc
        nodes = doc.get("nodes", [])
        if doc.get("scenes"):
            roots = doc["scenes"][doc.get("scene", 0)].get("nodes", [])
        else:  # no scene: every node that is nobody's child
            children = {c for n in nodes for c in n.get("children", [])}
            roots = [i for i in range(len(nodes)) if i not in children]
        self._check_graph(nodes, roots)
        stack = [(r, np.eye(4)) for r in roots]
        while stack:
            ni, parent = stack.pop()
            node = nodes[ni]
            world = parent @ _local_matrix(node)
            stack.extend((c, world) for c in node.get("children", []))
            if "mesh" in node:
                for k, prim in enumerate(doc["meshes"][node["mesh"]]["primitives"]):
                    out = self._primitive(prim, world, f"mesh {node['mesh']} primitive {k}")
                    if out is not None:
                        yield out, prim.get("material")

    def _children(self, nodes, i) -> list:
        try:
            kids = nodes[i].get("children", [])
        except (IndexError, TypeError, AttributeError):
            raise ScanlightError(self.path, f"corrupt glTF: node {show(i)} does not "
                                            "exist") from None
        if not isinstance(kids, list) or not all(isinstance(c, int) and not isinstance(
                c, bool) and c >= 0 for c in kids):
            raise ScanlightError(self.path, f"corrupt glTF: node {i} children must be a "
                                            "list of node indices")
        return kids

    def _check_graph(self, nodes, roots) -> None:
        """The node graph, checked before it is expanded: no cycle and no dangling index, at
        most MAX_GLTF_DEPTH levels, at most MAX_GLTF_INSTANCES node instances, and at most
        MAX_MESH_VERTICES vertices over all instanced primitives (from the accessors' declared
        counts). A tree (what the glTF spec requires) has one instance per node; a file whose
        nodes share children would otherwise expand exponentially. Each node is visited once
        (its subtree's instance count and height memoised), so a shared subtree costs one visit."""
        if not isinstance(roots, list) or not all(
                isinstance(r, int) and not isinstance(r, bool) and 0 <= r < len(nodes)
                for r in roots):
            raise ScanlightError(self.path, f"corrupt glTF: scene nodes must be a list of node "
                                            f"indices, got {show(roots)}")
        count: dict[int, int] = {}          # instances in the node's subtree
        height: dict[int, int] = {}         # levels in the node's subtree
        state: dict[int, int] = {}          # 1 = being counted (on the current path), 2 = done
        order: list[int] = []               # post-order: children before parents
        for root in roots:
            if state.get(root) == 2:
                continue
            stack = [(root, iter(self._children(nodes, root)))]
            state[root] = 1
            while stack:
                node, it = stack[-1]
                nxt = next(it, None)
                if nxt is None:
                    stack.pop()
                    state[node] = 2
                    order.append(node)
                    kids = nodes[node].get("children", [])
                    count[node] = 1 + sum(count[c] for c in kids)
                    height[node] = 1 + max((height[c] for c in kids), default=0)
                    if height[node] > MAX_GLTF_DEPTH:
                        raise ScanlightError(self.path, f"the node hierarchy is deeper than "
                                                        f"{MAX_GLTF_DEPTH} levels")
                    if count[node] > MAX_GLTF_INSTANCES:
                        raise ScanlightError(self.path, f"the node graph expands to more than "
                                                        f"{MAX_GLTF_INSTANCES:,} instances (nodes "
                                                        "shared by several parents)")
                elif state.get(nxt) == 1:
                    raise ScanlightError(self.path, "corrupt glTF: node hierarchy has a cycle")
                elif state.get(nxt) != 2:
                    state[nxt] = 1
                    stack.append((nxt, iter(self._children(nodes, nxt))))
        total = sum(count[r] for r in roots)
        if total > MAX_GLTF_INSTANCES:
            raise ScanlightError(self.path, f"the scene expands to {total:,} node instances "
                                            f"(limit {MAX_GLTF_INSTANCES:,})")
        # instances of each node (parents before children: reversed post-order)
        mult = dict.fromkeys(order, 0)
        for r in roots:
            mult[r] += 1
        for node in reversed(order):
            for c in nodes[node].get("children", []):
                mult[c] += mult[node]
        vertices = sum(m * self._mesh_vertices(nodes[n]["mesh"]) for n, m in mult.items()
                       if m and "mesh" in nodes[n])
        if vertices > MAX_MESH_VERTICES:
            raise ScanlightError(self.path, f"the scene's primitives hold {vertices:,} vertices "
                                            f"once instanced, more than the limit of "
                                            f"{MAX_MESH_VERTICES:,}")

    def _declared_count(self, index) -> int:
        """An accessor's declared ``count`` (a whole number >= 0), before reading it."""
        try:
            n = self.doc["accessors"][index]["count"]
        except (KeyError, IndexError, TypeError):
            raise ScanlightError(self.path, f"corrupt glTF: bad accessor {show(index)}") from None
        if not isinstance(n, int) or isinstance(n, bool) or n < 0:
            raise ScanlightError(self.path, f"corrupt glTF: accessor {index} count must be a "
                                            f"whole number >= 0, got {show(n)}")
        return n

    def _mesh_vertices(self, mesh) -> int:
        """Vertices (or indices, when more) a mesh's triangle primitives declare."""
        try:
            prims = self.doc["meshes"][mesh]["primitives"]
        except (KeyError, IndexError, TypeError):
            raise ScanlightError(self.path, f"corrupt glTF: mesh {show(mesh)} does not "
                                            "exist") from None
        total = 0
        for prim in prims if isinstance(prims, list) else []:
            attrs = prim.get("attributes", {}) if isinstance(prim, dict) else {}
            n = self._declared_count(attrs["POSITION"]) if "POSITION" in attrs else 0
            if "indices" in prim:
                n = max(n, self._declared_count(prim["indices"]))
            total += n
        return total

    def _primitive(self, prim: dict, world: np.ndarray, label: str) -> Primitive | None:
        mode = prim.get("mode", _TRIANGLES)
        if mode not in (_TRIANGLES, _STRIP, _FAN):
            self.warn(f"{label}: points/lines primitive (mode {mode}) skipped")
            return None
        if _DRACO in prim.get("extensions", {}):
            attrs, faces = self.draco(prim)
            if "POSITION" not in attrs:
                raise ScanlightError(self.path, f"corrupt glTF: {label} has no POSITION")
            flat = faces.reshape(-1)
            mode = _TRIANGLES
        else:
            attrs = {k: self.accessor(v) for k, v in prim.get("attributes", {}).items()
                     if k in ("POSITION", "NORMAL", "TEXCOORD_0")}
            if "POSITION" not in attrs:
                raise ScanlightError(self.path, f"corrupt glTF: {label} has no POSITION")
            flat = (self.accessor(prim["indices"]).reshape(-1).astype(np.int64)
                    if "indices" in prim else np.arange(len(attrs["POSITION"])))
        pos = attrs["POSITION"].astype(np.float64)
        faces = _triangles(flat, mode)
        if len(faces) and (faces.min() < 0 or faces.max() >= len(pos)):
            raise ScanlightError(self.path, f"corrupt glTF: {label} has vertex indices out "
                                            "of range")
        normals = attrs.get("NORMAL")
        uvs = attrs.get("TEXCOORD_0")
        if uvs is not None:
            uvs = uvs[:, :2].astype(np.float64).copy()
            uvs[:, 1] = 1.0 - uvs[:, 1]
        lin = world[:3, :3]
        # A node transform that overflows (a scale of 1e300) leaves vertices beyond MAX_COORD,
        # which load_mesh refuses in one line: no numpy warnings on the way there.
        with np.errstate(over="ignore", invalid="ignore"):
            pos = pos @ lin.T + world[:3, 3]
            if normals is not None:
                normals = normals[:, :3].astype(np.float64) @ np.linalg.inv(lin)
            if np.linalg.det(lin) < 0:
                faces = faces[:, ::-1]
        return Primitive(pos, faces, normals, uvs, -1)


def _local_matrix(node: dict) -> np.ndarray:
    if "matrix" in node:
        return np.asarray(node["matrix"], dtype=np.float64).reshape(4, 4).T  # column-major
    m = np.eye(4)
    x, y, z, w = node.get("rotation", [0, 0, 0, 1])
    r = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                  [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                  [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    m[:3, :3] = r * np.asarray(node.get("scale", [1, 1, 1]), dtype=np.float64)[None, :]
    m[:3, 3] = node.get("translation", [0, 0, 0])
    return m


def _triangles(flat: np.ndarray, mode: int) -> np.ndarray:
    if mode == _TRIANGLES:
        n = len(flat) // 3
        return flat[: 3 * n].reshape(n, 3)
    if len(flat) < 3:
        return np.zeros((0, 3), dtype=np.int64)
    k = np.arange(len(flat) - 2)
    if mode == _STRIP:  # every other triangle swaps two vertices to keep the winding
        even = (k % 2) == 0
        a = np.where(even, flat[k], flat[k + 1])
        b = np.where(even, flat[k + 1], flat[k])
        return np.stack([a, b, flat[k + 2]], axis=1)
    return np.stack([np.full_like(k, flat[0]), flat[k + 1], flat[k + 2]], axis=1)  # fan


def decode_texture(blob: bytes, kind: str) -> np.ndarray | None:
    """PNG/JPEG bytes -> float32 (H, W, C), bottom row first; RGB sRGB-decoded for kind "srgb".
    None when the bytes are no image, or one larger than MAX_TEXTURE_PIXELS (read from its
    header, nothing decoded); the caller warns."""
    import io

    from PIL import Image

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)  # our limit below
            with Image.open(io.BytesIO(blob)) as im:
                if im.size[0] * im.size[1] > MAX_TEXTURE_PIXELS:
                    return None
                im.load()
                mode = "RGBA" if "A" in im.getbands() else "RGB"
                a = np.asarray(im.convert(mode), dtype=np.float32) / 255.0
    except Exception:  # Pillow raises many types for bad data; the caller warns
        return None
    if kind == "srgb":
        a = a.copy()
        a[..., :3] = srgb_to_linear(a[..., :3])
    return np.ascontiguousarray(a[::-1])


def read_gltf(path: Path, warn) -> tuple[list[Primitive], list[Material]]:
    """Primitives in world space and one Disney material per glTF material they use."""
    prims, materials, index_of = [], [], {}
    try:
        reader = _Reader(path, warn)
        for prim, mat in reader.primitives():
            if mat not in index_of:
                index_of[mat] = len(materials)
                materials.append(reader.material(mat))
            prim.material = index_of[mat]
            prims.append(prim)
    except (KeyError, IndexError, TypeError, ValueError, AttributeError) as exc:  # bad structure
        raise ScanlightError(path, f"corrupt glTF ({type(exc).__name__}: {exc})") from None
    return prims, materials
