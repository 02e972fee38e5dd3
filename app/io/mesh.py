"""Triangle meshes for the asset: one flat layout for glTF, OBJ and the procedural shapes.

Conventions (the renderer relies on them):
- UVs are OpenGL-style: origin at the bottom-left of the texture, v up. Texture arrays in
  ``Material`` are stored bottom row first, so they upload to GL unchanged and sample at ``uvs``.
- ``tangents[:, :3]`` is the direction of increasing u, orthogonal to the normal;
  ``tangents[:, 3]`` = +-1 is the handedness: bitangent (increasing v) = w * cross(n, t), the
  MikkTSpace/glTF rule. Without UVs the tangent is an arbitrary orthonormal frame (Duff et al.
  2017), so the anisotropy direction is then undefined (a warning says so).
- Faces wind counter-clockwise seen from the side the normals point to.

glTF goes through app.io.gltf (our reader: Draco, exact factors); OBJ+MTL through trimesh for the
geometry and a small MTL parser for exact material values (trimesh stores Kd as uint8).
OBJ/MTL -> Disney: Kd -> base_color (linear), Pr or else Ns -> roughness = (2 / (Ns + 2))^(1/4)
(Blinn-Phong exponent -> Beckmann alpha = sqrt(2/(Ns+2)) -> Disney alpha = roughness^2),
Pm -> metallic, Ke -> emissive, map_Kd (sRGB) -> base_color_texture, norm -> normal_texture.
A missing texture file is a warning, not an error: the factor is used instead.
"""

from __future__ import annotations

import dataclasses
import logging
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from app.errors import ScanlightError
from app.io.files import require_file
from app.io.limits import MAX_COORD
from app.material import Material

log = logging.getLogger(__name__)

MESH_EXTENSIONS = (".glb", ".gltf", ".obj")


@dataclass
class Mesh:
    """positions (V,3) f64 (an asset placed a million metres from the origin keeps its shape:
    float32 there rounds to 6 cm; the renderers subtract their origin before the GPU's float32);
    normals (V,3) f32 unit; uvs (V,2) f32 or None; tangents (V,4) f32;
    indices (F,3) uint32; material_ids (F,) uint32 into ``materials``; report: what the loader
    did (warnings, counts)."""

    positions: np.ndarray
    normals: np.ndarray
    uvs: np.ndarray | None
    tangents: np.ndarray
    indices: np.ndarray
    material_ids: np.ndarray
    materials: list[Material]
    source: str | None = None
    report: dict = field(default_factory=dict)

    def __post_init__(self):
        self.positions = np.ascontiguousarray(self.positions, dtype=np.float64).reshape(-1, 3)
        self.normals = np.ascontiguousarray(self.normals, dtype=np.float32).reshape(-1, 3)
        self.tangents = np.ascontiguousarray(self.tangents, dtype=np.float32).reshape(-1, 4)
        if self.uvs is not None:
            self.uvs = np.ascontiguousarray(self.uvs, dtype=np.float32).reshape(-1, 2)
        self.indices = np.ascontiguousarray(self.indices, dtype=np.uint32).reshape(-1, 3)
        self.material_ids = np.ascontiguousarray(self.material_ids, dtype=np.uint32).reshape(-1)
        v, f = len(self.positions), len(self.indices)
        if len(self.normals) != v or len(self.tangents) != v or (
                self.uvs is not None and len(self.uvs) != v):
            raise ValueError("mesh vertex arrays differ in length")
        if len(self.material_ids) != f:
            raise ValueError("material_ids must have one entry per face")
        if f and (self.indices.max() >= v or self.material_ids.max() >= len(self.materials)):
            raise ValueError("mesh indices or material ids out of range")

    @property
    def n_faces(self) -> int:
        return len(self.indices)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        used = self.positions[np.unique(self.indices)] if self.n_faces else self.positions
        return used.min(axis=0), used.max(axis=0)


# ------------------------------------------------------------------------------ vertex frames

def _scatter_add(index: np.ndarray, values: np.ndarray, n: int) -> np.ndarray:
    """Sum rows of ``values`` (M, C) into n rows by ``index`` (bincount: faster than add.at)."""
    return np.stack([np.bincount(index, weights=values[:, c], minlength=n)
                     for c in range(values.shape[1])], axis=1)


def face_normals(positions: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """Unnormalised face normals (length = twice the triangle area)."""
    p = np.asarray(positions, dtype=np.float64)
    f = np.asarray(indices, dtype=np.int64)
    return np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]])


def vertex_normals(positions: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """Area-weighted smooth normals; vertices on no (non-degenerate) face get zero."""
    f = np.asarray(indices, dtype=np.int64)
    fn = face_normals(positions, f)
    acc = _scatter_add(f.reshape(-1), np.repeat(fn, 3, axis=0), len(positions))
    length = np.linalg.norm(acc, axis=1)
    return acc / np.where(length > 0, length, 1.0)[:, None]


def any_tangent(normals: np.ndarray) -> np.ndarray:
    """A unit vector orthogonal to each normal, continuous except at n.z = -0 (Duff et al. 2017)."""
    n = np.asarray(normals, dtype=np.float64)
    sign = np.where(n[:, 2] >= 0, 1.0, -1.0)
    a = -1.0 / (sign + n[:, 2])
    b = n[:, 0] * n[:, 1] * a
    return np.stack([1.0 + sign * n[:, 0] ** 2 * a, sign * b, -sign * n[:, 0]], axis=1)


def compute_tangents(positions, normals, uvs, indices) -> np.ndarray:
    """(V, 4) tangents: xyz = dP/du made orthogonal to n, w = handedness of dP/dv.

    Per face, [dP/du dP/dv] = [e1 e2] [duv1 duv2]^-1; each face adds both vectors scaled by its
    |UV area| to its corners, so large faces dominate and UV-degenerate faces add nothing.
    Vertices left without a usable direction (no UVs, degenerate UVs) get ``any_tangent``.
    """
    n = np.asarray(normals, dtype=np.float64)
    out = np.zeros((len(n), 4))
    out[:, 3] = 1.0
    t = np.zeros_like(n)
    bsum = np.zeros_like(n)
    if uvs is not None and len(indices):
        p = np.asarray(positions, dtype=np.float64)
        uv = np.asarray(uvs, dtype=np.float64)
        f = np.asarray(indices, dtype=np.int64)
        e1, e2 = p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]]
        d1, d2 = uv[f[:, 1]] - uv[f[:, 0]], uv[f[:, 2]] - uv[f[:, 0]]
        det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
        s = np.sign(det)[:, None]  # (.)/det * |det|
        tf = (e1 * d2[:, 1:2] - e2 * d1[:, 1:2]) * s
        bf = (e2 * d1[:, 0:1] - e1 * d2[:, 0:1]) * s
        flat = f.reshape(-1)
        t = _scatter_add(flat, np.repeat(tf, 3, axis=0), len(n))
        bsum = _scatter_add(flat, np.repeat(bf, 3, axis=0), len(n))
    t = t - n * np.sum(t * n, axis=1, keepdims=True)
    length = np.linalg.norm(t, axis=1)
    scale = np.linalg.norm(bsum, axis=1) + length
    good = length > 1e-9 * np.maximum(scale, 1e-30)
    good &= length > 0
    out[good, :3] = t[good] / length[good, None]
    w = np.sign(np.sum(np.cross(n, out[:, :3]) * bsum, axis=1))
    out[good, 3] = np.where(w[good] < 0, -1.0, 1.0)
    out[~good, :3] = any_tangent(n[~good])
    return out


def build_mesh(positions, indices, normals=None, uvs=None, material_ids=None, materials=None,
               source=None, report=None) -> Mesh:
    """A Mesh with the missing parts completed: smooth normals, tangents, one default material.

    Faces touching non-finite positions are dropped; zero-length or non-finite normals are
    replaced by the smooth normal; both are counted in the report.
    """
    report = {} if report is None else report
    pos = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    idx = np.asarray(indices, dtype=np.int64).reshape(-1, 3)
    mids = (np.zeros(len(idx), dtype=np.int64) if material_ids is None
            else np.asarray(material_ids, dtype=np.int64).reshape(-1))
    materials = list(materials) if materials else [Material(name="default")]
    bad_vertex = ~np.all(np.isfinite(pos), axis=1)
    if bad_vertex.any():
        keep = ~bad_vertex[idx].any(axis=1)
        report["dropped_nonfinite_faces"] = int((~keep).sum())
        _warn(report, source, f"dropped {int((~keep).sum())} faces with NaN/Inf vertex positions")
        idx, mids = idx[keep], mids[keep]
        pos = np.where(bad_vertex[:, None], 0.0, pos)
    smooth = vertex_normals(pos, idx)
    if normals is None:
        nrm = smooth
    else:
        nrm = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
        length = np.linalg.norm(nrm, axis=1)
        bad = ~np.isfinite(length) | (length < 1e-12)
        nrm = np.where(bad[:, None], smooth, nrm / np.where(bad, 1.0, length)[:, None])
        if bad.any():
            report["replaced_bad_normals"] = int(bad.sum())
            _warn(report, source, f"replaced {int(bad.sum())} zero-length or NaN normals")
    unset = np.linalg.norm(nrm, axis=1) < 0.5  # unreferenced or degenerate-only vertices
    nrm[unset] = (0.0, 0.0, 1.0)
    tangents = compute_tangents(pos, nrm, uvs, idx)
    return Mesh(pos, nrm, uvs, tangents, idx, mids, materials, source, report)


def _warn(report: dict, source, msg: str) -> None:
    report.setdefault("warnings", []).append(msg)
    log.warning("%s: %s", source or "mesh", msg)


# ------------------------------------------------------------------------------- transforms

def transform_mesh(mesh: Mesh, matrix) -> Mesh:
    """The mesh under a 4x4 affine ``matrix``: normals by the inverse transpose, tangents by the
    linear part; a mirroring matrix flips the winding and the handedness."""
    m = np.asarray(matrix, dtype=np.float64)
    lin = m[:3, :3]
    det = np.linalg.det(lin)
    if not np.isfinite(det) or abs(det) < 1e-300:
        raise ValueError("transform_mesh needs an invertible matrix")
    pos = mesh.positions.astype(np.float64) @ lin.T + m[:3, 3]
    nrm = mesh.normals.astype(np.float64) @ np.linalg.inv(lin)
    nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-300)
    tan = mesh.tangents[:, :3].astype(np.float64) @ lin.T
    tan -= nrm * np.sum(tan * nrm, axis=1, keepdims=True)
    tl = np.linalg.norm(tan, axis=1, keepdims=True)
    tan = np.where(tl > 1e-12, tan / np.maximum(tl, 1e-300), any_tangent(nrm))
    w = mesh.tangents[:, 3:4] * np.sign(det)
    idx = mesh.indices[:, ::-1] if det < 0 else mesh.indices
    return dataclasses.replace(mesh, positions=pos, normals=nrm,
                               tangents=np.concatenate([tan, w], axis=1), indices=idx)


def normalizing_matrix(positions, indices, source=None) -> np.ndarray:
    """4x4 matrix centring the AABB of the faces' vertices on 0 and scaling its largest extent
    to 1 (unreferenced vertices do not count)."""
    used = np.asarray(positions, dtype=np.float64)[np.unique(np.asarray(indices).reshape(-1))]
    if len(used) == 0:
        raise ScanlightError(source, "mesh has no faces")
    lo, hi = used.min(axis=0), used.max(axis=0)
    extent = float(np.max(hi - lo))
    if not np.isfinite(extent) or extent <= 0:
        raise ScanlightError(source, "mesh has zero size (all vertices at one point)")
    m = np.eye(4) / extent
    m[3, 3] = 1.0
    m[:3, 3] = -(lo + hi) / 2 / extent
    return m


def normalize_mesh(mesh: Mesh) -> Mesh:
    """Centred on its bounding-box centre, largest extent 1."""
    return transform_mesh(mesh, normalizing_matrix(mesh.positions, mesh.indices, mesh.source))


# ---------------------------------------------------------------------------------- loading

def load_mesh(path, normalize: bool = False) -> Mesh:
    """Read a .glb/.gltf/.obj asset; ``normalize`` centres and scales it (in float64, so assets
    far from the origin keep their precision) to largest extent 1."""
    p = require_file(path, "mesh", MESH_EXTENSIONS)
    report: dict = {}

    def warn(msg):
        _warn(report, p, msg)

    if p.suffix.lower() in (".glb", ".gltf"):
        pos, idx, nrm, uvs, mids, materials = _gltf_arrays(p, warn)
    else:
        pos, idx, nrm, uvs, mids, materials = _obj_arrays(p, warn)
    if len(idx) == 0:
        raise ScanlightError(p, "mesh has no faces")
    _check_finite(p, pos)
    twice_area = np.linalg.norm(face_normals(pos, idx), axis=1)
    if not np.any(np.isfinite(twice_area) & (twice_area > 0)):
        raise ScanlightError(p, f"mesh has no triangle with an area (all {len(idx):,} faces are "
                                "degenerate): nothing to render")
    if uvs is None:
        warn("no texture coordinates: tangents use an arbitrary frame (anisotropy direction "
             "undefined)")
        if any(_textures(m) for m in materials):
            warn("textures ignored: the mesh has no texture coordinates")
            materials = [_without_textures(m) for m in materials]
    if normalize:
        m = normalizing_matrix(pos, idx, p)
        pos = pos @ m[:3, :3].T + m[:3, 3]
    report["faces"], report["vertices"] = int(len(idx)), int(len(pos))
    report["materials"] = [m.name for m in materials]
    return build_mesh(pos, idx, nrm, uvs, mids, materials, str(p), report)


def _check_finite(p: Path, positions: np.ndarray) -> None:
    """Refuse NaN or infinite vertices, or vertices beyond MAX_COORD (a "nan" or "1e999" in the
    file, or glTF node transforms that overflow): they would render as nothing, with numpy
    warnings, instead of an error (a scale of 1e300 said "no triangle with an area")."""
    with np.errstate(invalid="ignore"):
        bad = ~(np.isfinite(positions) & (np.abs(positions) <= MAX_COORD)).all(axis=1)
    if bad.any():
        raise ScanlightError(p, f"mesh has {int(bad.sum()):,} vertices with NaN or infinite "
                                f"coordinates or beyond {MAX_COORD:g} m")


def _textures(m: Material) -> bool:
    return any(t is not None for t in (m.base_color_texture, m.metallic_roughness_texture,
                                       m.normal_texture))


def _without_textures(m: Material) -> Material:
    return dataclasses.replace(m, base_color_texture=None, metallic_roughness_texture=None,
                               normal_texture=None)


def _concat(parts, warn, label):
    """Stack (positions, faces, normals|None, uvs|None, material id) parts into flat arrays."""
    offs = np.cumsum([0] + [len(q[0]) for q in parts])
    pos = np.concatenate([q[0] for q in parts])
    idx = np.concatenate([q[1] + o for q, o in zip(parts, offs)])
    mids = np.concatenate([np.full(len(q[1]), q[4]) for q in parts])
    with_uv = [q[3] is not None for q in parts]
    uvs = None
    if any(with_uv):
        if not all(with_uv):
            warn(f"{with_uv.count(False)} of {len(parts)} {label} have no texture coordinates "
                 "(set to 0; their textures show one texel)")
        uvs = np.concatenate([q[3] if q[3] is not None else np.zeros((len(q[0]), 2))
                              for q in parts])
    nrm = np.concatenate([q[2] for q in parts])
    return pos, idx, nrm, uvs, mids


def _gltf_arrays(p: Path, warn):
    from app.io.gltf import read_gltf

    prims, materials = read_gltf(p, warn)
    parts = []
    for pr in prims:
        pos, faces, nrm, uvs = pr.positions, pr.indices, pr.normals, pr.uvs
        _check_finite(p, pos)
        if nrm is None:  # glTF: missing normals mean flat shading -> one vertex per corner
            flat = faces.reshape(-1)
            pos, uvs = pos[flat], None if uvs is None else uvs[flat]
            faces = np.arange(len(flat)).reshape(-1, 3)
            fn = face_normals(pos, faces)
            nrm = np.repeat(fn, 3, axis=0)
        parts.append((pos, faces, nrm, uvs, pr.material))
    if any(pr.normals is None for pr in prims):
        warn("some primitives have no normals: flat normals computed (glTF rule)")
    if not parts:
        raise ScanlightError(p, "mesh has no faces (no triangle primitives in the scene)")
    pos, idx, nrm, uvs, mids = _concat(parts, warn, "primitives")
    return pos, idx, nrm, uvs, mids, materials


def _check_obj_lines(p: Path, data: bytes) -> None:
    """OBJ indices are 1-based (negative: from the end); 0 is no vertex. trimesh would read it
    as the last vertex and the asset would render silently wrong. A vertex needs x, y and z:
    trimesh reads "v 0 0" as a 2-D point, which failed deep in the normals."""
    for n, line in enumerate(data.splitlines(), 1):
        if line[:2] in (b"v ", b"v\t") and len(line.split()) < 4:
            raise ScanlightError(p, f"line {n}: a vertex needs 3 coordinates, got "
                                    f"{len(line.split()) - 1}")
        if line[:2] not in (b"f ", b"f\t"):
            continue
        for word in line.split()[1:]:
            if word.split(b"/")[0] in (b"0", b"-0", b"+0"):
                raise ScanlightError(p, f"line {n}: face index 0 (OBJ indices start at 1)")


def _obj_arrays(p: Path, warn):
    import trimesh

    data = p.read_bytes()
    _check_obj_lines(p, data)
    library = _read_mtl_libraries(p, data, warn)
    try:
        scene = trimesh.load_scene(str(p), file_type="obj", process=False, group_material=True)
        geoms = [g for g in scene.dump(concatenate=False)
                 if isinstance(g, trimesh.Trimesh) and len(g.faces)]
    except ScanlightError:
        raise
    except Exception as exc:  # trimesh raises many types on malformed OBJ
        raise ScanlightError(p, f"corrupt OBJ ({type(exc).__name__}: {exc})") from None
    if not geoms:
        raise ScanlightError(p, "mesh has no faces")
    has_vn = re.search(rb"^\s*vn\s", data, re.M) is not None
    materials, index_of, parts = [], {}, []
    for g in geoms:
        mat = getattr(getattr(g.visual, "material", None), "name", None)
        if mat not in index_of:
            index_of[mat] = len(materials)
            if mat in library:
                materials.append(library[mat])
            else:
                if mat is not None and library:
                    warn(f"material {mat!r} is not defined in the MTL file: default material")
                materials.append(Material(name=str(mat or "default")))
        uv = getattr(g.visual, "uv", None)
        uv = None if uv is None or len(uv) != len(g.vertices) else np.asarray(uv, np.float64)
        nrm = np.asarray(g.vertex_normals, np.float64) if has_vn else None
        parts.append((np.asarray(g.vertices, np.float64), np.asarray(g.faces, np.int64), nrm, uv,
                      index_of[mat]))
    for q in parts:
        _check_finite(p, q[0])     # before the normals are computed from them
    if not has_vn:
        parts = [(q[0], q[1], vertex_normals(q[0], q[1]), q[3], q[4]) for q in parts]
    pos, idx, nrm, uvs, mids = _concat(parts, warn, "material groups")
    return pos, idx, nrm, uvs, mids, materials


def _read_mtl_libraries(obj: Path, data: bytes, warn) -> dict[str, Material]:
    library: dict[str, Material] = {}
    for lib in re.findall(rb"^\s*mtllib\s+(.+?)\s*$", data, re.M):
        mtl = obj.parent / lib.decode("utf-8", "replace")
        if not mtl.is_file():
            warn(f"material library {mtl.name!r} not found: default material")
            continue
        library.update(_parse_mtl(mtl, warn))
    return library


def _parse_mtl(mtl: Path, warn) -> dict[str, Material]:
    from app.io.gltf import decode_texture

    out: dict[str, dict] = {}
    cur = None
    for line in mtl.read_text(encoding="utf-8", errors="replace").splitlines():
        words = line.split()
        if not words or words[0].startswith("#"):
            continue
        key, args = words[0], words[1:]
        if key == "newmtl":
            cur = out.setdefault(" ".join(args), {})
        elif cur is not None and args:
            cur[key] = args
    materials = {}
    for name, d in out.items():
        def floats(key, n, default):
            if key not in d:
                return default
            try:
                vals = [float(v) for v in d[key][:n]]
            except ValueError:
                vals = []
            if len(vals) == 1 and len(default) == 3:    # "Kd r": g and b equal r (MTL spec)
                vals = vals * 3
            if len(vals) != len(default) or not np.all(np.isfinite(vals)):   # "nan", "1e999"
                warn(f"{mtl.name}: material {name!r}: bad {key} value {d[key]!r}; using default")
                return default
            return vals

        kd = floats("Kd", 3, list(Material().base_color))
        if "Pr" in d:
            roughness = floats("Pr", 1, [0.5])[0]
        elif "Ns" in d:
            roughness = (2.0 / (max(floats("Ns", 1, [0.0])[0], 0.0) + 2.0)) ** 0.25
        else:
            roughness = 0.5
        for key in ("map_Bump", "bump", "map_bump", "map_Pr", "map_Pm", "map_Ke", "map_Ks"):
            if key in d:
                warn(f"{mtl.name}: material {name!r}: {key} is not supported (ignored)")

        def texture(key, kind):
            if key not in d:
                return None
            fname = d[key][-1]  # options such as -bm 1.0 come first
            f = mtl.parent / fname
            if not f.is_file():
                warn(f"material {name!r}: texture file {fname!r} not found; using the factor")
                return None
            tex = decode_texture(f.read_bytes(), kind)
            if tex is None:
                warn(f"material {name!r}: texture {fname!r} could not be decoded; using the factor")
            return tex

        materials[name] = Material(
            name=name,
            base_color=tuple(float(c) for c in np.clip(kd, 0.0, 1.0)),
            roughness=float(np.clip(roughness, 0.0, 1.0)),
            metallic=float(np.clip(floats("Pm", 1, [0.0])[0], 0.0, 1.0)),
            emissive=tuple(float(c) for c in np.maximum(floats("Ke", 3, [0.0, 0.0, 0.0]), 0.0)),
            base_color_texture=texture("map_Kd", "srgb"),
            normal_texture=texture("norm", "linear"),
        )
    return materials


# ------------------------------------------------------------------------------- procedural

def make_sphere_mesh(subdivisions: int = 4) -> Mesh:
    """UV sphere of diameter 1 at the origin, y up: 2^(s+1) rings x 2^(s+2) segments
    (s=4: 32 x 64, 3968 triangles). u runs with longitude, v from the south (0) to north pole (1);
    normals are exact. The seam column and pole rows are duplicated so UVs stay continuous."""
    if subdivisions < 1:
        raise ValueError("make_sphere_mesh needs subdivisions >= 1")
    rings, segs = 2 ** (subdivisions + 1), 2 ** (subdivisions + 2)
    theta = np.linspace(0.0, np.pi, rings + 1)[:, None]  # from the north pole down
    phi = np.linspace(0.0, 2 * np.pi, segs + 1)[None, :]
    n = np.stack(np.broadcast_arrays(np.sin(theta) * np.sin(phi), np.cos(theta),
                                     np.sin(theta) * np.cos(phi)), axis=-1).reshape(-1, 3)
    uv = np.stack(np.broadcast_arrays(phi / (2 * np.pi), 1.0 - theta / np.pi), axis=-1)
    uv = uv.reshape(-1, 2)
    i, j = np.meshgrid(np.arange(rings), np.arange(segs), indexing="ij")
    a = i * (segs + 1) + j  # top-left of each quad
    b, c, d = a + segs + 1, a + segs + 2, a + 1  # bottom-left, bottom-right, top-right
    upper = np.stack([a, b, d], axis=-1)[1:]  # the triangle touching the north pole is degenerate
    lower = np.stack([d, b, c], axis=-1)[:-1]  # ... and the one touching the south pole
    idx = np.concatenate([upper.reshape(-1, 3), lower.reshape(-1, 3)])
    return build_mesh(0.5 * n, idx, n, uv, source="sphere",
                      materials=[Material(name="default")])


def make_default_asset(segments: int = 384, sides: int = 32) -> Mesh:
    """A trefoil knot tube (non-convex, self-occluding, genus 1), largest extent 1, with UVs.

    Curve: ((2 + cos 3t) cos 2t, (2 + cos 3t) sin 2t, -sin 3t) in the x-y plane, swept by a
    circle of radius 0.4 in the Frenet frame (the trefoil's curvature never vanishes, and the
    frame is periodic, so the tube closes without a twist). u runs along the curve, v around it.
    """
    t = np.linspace(0.0, 2 * np.pi, segments + 1)[:, None]
    r = 2.0 + np.cos(3 * t)
    c = np.concatenate([r * np.cos(2 * t), r * np.sin(2 * t), -np.sin(3 * t)], axis=1)
    # analytic first and second derivatives of the curve
    dr, ddr = -3 * np.sin(3 * t), -9 * np.cos(3 * t)
    d1 = np.concatenate([dr * np.cos(2 * t) - 2 * r * np.sin(2 * t),
                         dr * np.sin(2 * t) + 2 * r * np.cos(2 * t), -3 * np.cos(3 * t)], axis=1)
    d2 = np.concatenate([ddr * np.cos(2 * t) - 4 * dr * np.sin(2 * t) - 4 * r * np.cos(2 * t),
                         ddr * np.sin(2 * t) + 4 * dr * np.cos(2 * t) - 4 * r * np.sin(2 * t),
                         9 * np.sin(3 * t)], axis=1)
    tangent = d1 / np.linalg.norm(d1, axis=1, keepdims=True)
    normal = d2 - tangent * np.sum(d2 * tangent, axis=1, keepdims=True)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    binormal = np.cross(tangent, normal)
    a = np.linspace(0.0, 2 * np.pi, sides + 1)[None, :, None]
    ring = np.cos(a) * normal[:, None, :] + np.sin(a) * binormal[:, None, :]  # (S+1, K+1, 3)
    pos = (c[:, None, :] + 0.4 * ring).reshape(-1, 3)
    nrm = ring.reshape(-1, 3)
    uv = np.stack(np.broadcast_arrays(t[:, :, None] / (2 * np.pi) * 8.0,
                                      a / (2 * np.pi)), axis=-1).reshape(-1, 2)
    i, j = np.meshgrid(np.arange(segments), np.arange(sides), indexing="ij")
    q = i * (sides + 1) + j
    q1, q2, q3 = q + sides + 1, q + sides + 2, q + 1
    idx = np.concatenate([np.stack([q, q1, q2], -1).reshape(-1, 3),
                          np.stack([q, q2, q3], -1).reshape(-1, 3)])
    # wind counter-clockwise around the outward normal
    if np.sum(face_normals(pos, idx) * nrm[idx[:, 0]]) < 0:
        idx = idx[:, ::-1]
    m = normalizing_matrix(pos, idx)
    pos = pos @ m[:3, :3].T + m[:3, 3]
    return build_mesh(pos, idx, nrm, uv, source="trefoil knot",
                      materials=[Material(name="default")])
