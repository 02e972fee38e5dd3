"""Point cloud files: PLY, PCD, XYZ/XYZN/XYZRGB/PTS in, PLY out.

Colour meaning follows the stored type, because that is the only thing that tells a clipped 8-bit
scan from HDR radiance:
- integer colours (uchar, ushort; PCD's packed rgb; 0-255 text columns) are sRGB-encoded LDR:
  normalised, linearised on load, ``hdr=False``;
- float colours (PLY float/double) are linear HDR radiance kept as they are, values > 1 included,
  ``hdr=True``.

PLY is read by the small numpy reader below, not open3d: open3d 0.20 divides float PLY colours by
255 (measured: a stored red of 5.0 comes back as 0.0196), which destroys HDR, and it hides whether
the colours were uchar or float. PCD goes through open3d after our own header check (open3d
silently pads a truncated ASCII PCD). Text formats carry no types: see ``_text_colors``.

What the loader repairs is counted in ``cloud.report`` and logged as a warning:
``dropped_nonfinite_positions`` (NaN, Inf, or beyond app.io.limits.MAX_COORD: a point at 1e30
m made the near and far planes of every camera meet), ``dropped_stray_points`` (``_not_stray``:
a few points far out of a scan), ``clamped_{negative,nan,inf,huge}_colors`` (see app.io.clean),
``replaced_bad_normals`` (zero-length or non-finite normals, re-estimated), ``normals`` ("file" or
"estimated"), and ``warnings`` (the human lines).

Per-point attributes (``PointCloud.attributes``) are extra PLY vertex properties of the same
names: save_cloud writes every 1-D uint8 (uchar), int32 (int) and float (float) attribute, and the
PLY reader reads back the HDR expansion's provenance, ``provenance`` (uchar label codes of
app.hdr.result.PROVENANCE) and ``provenance_score`` (float, NaN where a label has no score); other
unknown properties are ignored. Provenance that is not valid (a code outside PROVENANCE, a float
label, an integer score) is dropped with a warning: the cloud itself is still good.

Estimated normals are oriented towards the centre of the cloud's bounding box: a room scan is seen
from inside, so its walls, floor and ceiling face inwards. Surfaces that face away from the centre
(the far side of a box standing in the room) get flipped normals; rescanning with normals avoids it.
"""

from __future__ import annotations

import io
import logging
import re
import struct
import warnings
from pathlib import Path

import numpy as np

from app.cloud import PointCloud
from app.color import srgb_to_linear, to_uint8_srgb
from app.errors import ScanlightError
from app.hdr.result import LABEL_NAMES, PROVENANCE, PROVENANCE_ATTR, SCORE_ATTR
from app.io.clean import clean_rgb, describe_counts
from app.io.files import atomic_output, require_file
from app.io.limits import MAX_COORD, MAX_PCD_HEADER, MAX_PLY_HEADER

log = logging.getLogger(__name__)

CLOUD_EXTENSIONS = (".ply", ".pcd", ".xyz", ".xyzn", ".xyzrgb", ".pts")
# Below this |coordinate| float32 keeps 0.12 mm (half an ulp at 2048..4096 m is 2^-13 m); further
# out (georeferenced scans, 1e6 m offsets) save_cloud writes doubles.
FLOAT32_COORD_LIMIT = 4096.0
FLOAT32_FAR = 1e5   # metres: beyond this a float32 coordinate is rounded to 8 mm or worse
NORMAL_NEIGHBOURS = 20  # k nearest neighbours for the normal estimation plane fit
DEFAULT_COLOR = 0.5  # linear grey for clouds stored without colours

_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}
_NORMAL_NAMES = (("nx", "ny", "nz"), ("normal_x", "normal_y", "normal_z"))
_COLOR_NAMES = (("red", "green", "blue"), ("r", "g", "b"),
                ("diffuse_red", "diffuse_green", "diffuse_blue"))
# what save_cloud writes a point attribute as: numpy dtype -> (PLY type, stored dtype)
_ATTR_UCHAR, _ATTR_INT, _ATTR_FLOAT = ("uchar", "u1"), ("int", "<i4"), ("float", "<f4")


# ---------------------------------------------------------------------------------------- PLY

def _ply_header(f, p: Path):
    """(format, elements) where elements = [(name, count, [(prop, type) | ('list', ...)])]."""
    if f.readline(16).strip() != b"ply":
        raise ScanlightError(p, "not a PLY file (first line is not 'ply')")
    fmt, elements = None, []
    while True:
        raw = f.readline(MAX_PLY_HEADER + 1)    # a header line never outgrows the header
        if not raw:
            raise ScanlightError(p, "corrupt PLY: header has no 'end_header' line")
        if f.tell() > MAX_PLY_HEADER:
            raise ScanlightError(p, f"corrupt PLY: header longer than {MAX_PLY_HEADER:,} bytes")
        words = raw.decode("ascii", "replace").split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        key = words[0]
        if key == "end_header":
            break
        try:
            if key == "format":
                fmt = words[1]
            elif key == "element":
                count = int(words[2])
                if count < 0:
                    raise ValueError("a negative element count")
                elements.append((words[1], count, []))
            elif key == "property":
                if not elements:
                    raise ValueError("property before any element")
                if words[1] == "list":
                    elements[-1][2].append(("list", words[2], words[3], words[4]))
                else:
                    if words[1] not in _PLY_TYPES:
                        raise ValueError(f"unknown property type {words[1]!r}")
                    if any(pr[0] == words[2] for pr in elements[-1][2]):
                        raise ValueError(f"property {words[2]!r} declared twice")
                    elements[-1][2].append((words[2], words[1]))
        except (IndexError, ValueError) as exc:
            raise ScanlightError(p, f"corrupt PLY header line {raw.strip()[:60]!r} "
                                    f"({exc})") from None
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise ScanlightError(p, f"corrupt PLY: unknown format {fmt!r}")
    # Counts against the file size before anything is read or allocated: every row takes at
    # least one byte (an ASCII line, or a binary property), so a header claiming more rows than
    # the file has bytes is a lie (it used to loop for ever over a 300-byte file).
    body = p.stat().st_size - f.tell()
    rows = sum(count for _, count, _ in elements)
    if rows > body:
        raise ScanlightError(p, f"corrupt PLY: the header declares {rows:,} rows but only "
                                f"{max(body, 0):,} bytes follow it")
    return fmt, elements


def _read_ply(p: Path) -> dict:
    with open(p, "rb") as f:
        fmt, elements = _ply_header(f, p)
        names = [e[0] for e in elements]
        if "vertex" not in names:
            raise ScanlightError(p, "PLY has no 'vertex' element")
        vi = names.index("vertex")
        _, n, props = elements[vi]
        if any(pr[0] == "list" for pr in props):
            raise ScanlightError(p, "PLY vertex element with list properties is not supported")
        endian = ">" if fmt == "binary_big_endian" else "<"
        dtype = np.dtype([(name, endian + _PLY_TYPES[t]) for name, t in props])
        if fmt == "ascii" and n == 0:
            data = {name: np.zeros(0) for name, _ in props}
        elif fmt == "ascii":
            text = io.TextIOWrapper(f, encoding="ascii", errors="replace")
            for _, count, _ in elements[:vi]:
                for _ in range(count):
                    text.readline()
            try:
                with warnings.catch_warnings():  # "input contained no data" is our check below
                    warnings.simplefilter("ignore", UserWarning)
                    rows = np.loadtxt(text, dtype=np.float64, max_rows=n, ndmin=2)
            except ValueError as exc:
                raise ScanlightError(p, f"corrupt or truncated PLY vertex data ({exc})") from None
            if len(rows) < n:
                raise ScanlightError(p, f"truncated PLY: header declares {n} vertices but the file "
                                        f"holds {len(rows)}")
            if rows.shape[1] != len(props):
                raise ScanlightError(p, f"corrupt PLY: vertex lines have {rows.shape[1]} values, "
                                        f"the header declares {len(props)}")
            data = {name: rows[:, i] for i, (name, _) in enumerate(props)}
        else:
            offset = 0
            for name, count, eprops in elements[:vi]:
                if any(pr[0] == "list" for pr in eprops):
                    raise ScanlightError(p, f"binary PLY with list element {name!r} before the "
                                            "vertices is not supported")
                row = np.dtype([(q, endian + _PLY_TYPES[t]) for q, t in eprops])
                offset += count * row.itemsize
            blob = f.read()
            have = max(0, (len(blob) - offset) // dtype.itemsize) if dtype.itemsize else 0
            if have < n:
                raise ScanlightError(p, f"truncated PLY: header declares {n} vertices but the data "
                                        f"holds only {have}")
            rec = np.frombuffer(blob, dtype=dtype, count=n, offset=offset)
            data = {name: rec[name] for name in dtype.names}
    types = dict(props)
    if not all(k in data for k in "xyz"):
        raise ScanlightError(p, "PLY vertex element lacks x, y, z")
    out = {"positions": np.stack([data[k].astype(np.float64) for k in "xyz"], axis=1),
           "normals": None, "colors": None, "color_type": None, "warnings": []}
    far = float(np.abs(out["positions"]).max()) if len(out["positions"]) else 0.0
    if far > FLOAT32_FAR and any(np.dtype(_PLY_TYPES[types[k]]).itemsize < 8 for k in "xyz"):
        step = float(np.spacing(np.float32(far)))
        out["warnings"].append(f"positions up to {far:.3g} m stored as 32-bit floats are rounded "
                               f"to {step * 100:.2g} cm steps there; store x, y, z as double")
    for nn in _NORMAL_NAMES:
        if all(k in data for k in nn):
            out["normals"] = np.stack([data[k] for k in nn], axis=1).astype(np.float32)
            break
    for cn in _COLOR_NAMES:
        if all(k in data for k in cn):
            kinds = {np.dtype(_PLY_TYPES[types[k]]).kind for k in cn}
            if len(kinds) != 1:
                raise ScanlightError(p, "PLY colour channels mix integer and float types")
            t = np.dtype(_PLY_TYPES[types[cn[0]]])
            rgb = np.stack([data[k].astype(np.float64) for k in cn], axis=1)
            out["color_type"], out["hdr"] = types[cn[0]], t.kind == "f"
            if t.kind == "f":
                out["colors"] = rgb.astype(np.float32)
            else:
                out["colors"] = srgb_to_linear(np.clip(rgb / np.iinfo(t).max, 0.0, 1.0))
            break
    out["attributes"] = _ply_provenance(data, types, out["warnings"])
    return out


def _ply_provenance(data: dict, types: dict, warns: list) -> dict:
    """PROVENANCE_ATTR (and SCORE_ATTR) from the vertex properties, or {} with a warning in
    ``warns`` when they are not valid: provenance is a description, not part of the scan."""
    def kind(name):
        return np.dtype(_PLY_TYPES[types[name]]).kind

    if PROVENANCE_ATTR not in data:
        if SCORE_ATTR in data:
            warns.append(f"property {SCORE_ATTR!r} without {PROVENANCE_ATTR!r}: ignored")
        return {}
    labels = data[PROVENANCE_ATTR]
    if kind(PROVENANCE_ATTR) not in "iu":
        warns.append(f"property {PROVENANCE_ATTR!r} is {types[PROVENANCE_ATTR]}, not an integer "
                     "label: provenance ignored")
        return {}
    bad = ~np.isin(labels, list(PROVENANCE))
    if bad.any():
        seen = ", ".join(f"{v:g}" for v in np.unique(labels[bad])[:5])
        warns.append(f"{int(bad.sum())} points have provenance codes outside "
                     f"{min(PROVENANCE)}-{max(PROVENANCE)} ({seen}): provenance ignored")
        return {}
    attrs = {PROVENANCE_ATTR: labels.astype(np.uint8)}
    if SCORE_ATTR in data:
        if kind(SCORE_ATTR) == "f":
            attrs[SCORE_ATTR] = data[SCORE_ATTR].astype(np.float32)
        else:
            warns.append(f"property {SCORE_ATTR!r} is {types[SCORE_ATTR]}, not float: "
                         "provenance scores ignored")
    return attrs


# ---------------------------------------------------------------------------------------- PCD

def _pcd_header(p: Path) -> tuple[int, str, int, int]:
    """(POINTS, DATA kind, header byte length, bytes per point) from a PCD header."""
    fields: dict[str, list[str]] = {}
    with open(p, "rb") as f:
        while True:
            raw = f.readline(MAX_PCD_HEADER + 1)
            if not raw or f.tell() > MAX_PCD_HEADER:
                raise ScanlightError(p, "corrupt PCD: header has no DATA line")
            words = raw.decode("ascii", "replace").split()
            if not words or words[0].startswith("#"):
                continue
            fields[words[0].upper()] = words[1:]
            if words[0].upper() == "DATA":
                break
        header_len = f.tell()
    try:
        if "POINTS" in fields:
            n = int(fields["POINTS"][0])
        else:
            n = int(fields["WIDTH"][0]) * int(fields["HEIGHT"][0])
        sizes = [int(s) for s in fields["SIZE"]]
        counts = [int(c) for c in fields.get("COUNT", ["1"] * len(sizes))]
        kind = fields["DATA"][0].lower()
    except (KeyError, IndexError, ValueError) as exc:
        raise ScanlightError(p, f"corrupt PCD header ({exc!r})") from None
    # a field of 0 bytes would let any point count pass the size checks below
    if not sizes or any(s not in (1, 2, 4, 8) for s in sizes) or any(c < 1 for c in counts):
        raise ScanlightError(p, f"corrupt PCD header: SIZE must be 1, 2, 4 or 8 and COUNT at "
                                f"least 1 per field, got SIZE {' '.join(map(str, sizes))} "
                                f"COUNT {' '.join(map(str, counts))}")
    return n, kind, header_len, sum(s * c for s, c in zip(sizes, counts))


def _read_pcd(p: Path) -> dict:
    n, kind, header_len, stride = _pcd_header(p)
    size = p.stat().st_size
    if n < 0:
        raise ScanlightError(p, f"corrupt PCD: negative point count {n}")
    if kind not in ("ascii", "binary", "binary_compressed"):
        raise ScanlightError(p, f"corrupt PCD: DATA must be ascii, binary or binary_compressed, "
                                f"got {kind!r}")
    if kind == "binary_compressed":
        # two uint32 (compressed size, uncompressed size) then the LZF data: both must agree
        # with the header and the file, or the decoder turns random bytes into points
        with open(p, "rb") as f:
            f.seek(header_len)
            sizes = f.read(8)
        if len(sizes) < 8:
            raise ScanlightError(p, "truncated PCD: binary_compressed data has no size header")
        packed, unpacked = struct.unpack("<II", sizes)
        if unpacked != n * stride or packed > size - header_len - 8:
            raise ScanlightError(p, f"corrupt PCD: compressed block of {packed} bytes expanding "
                                    f"to {unpacked} does not hold {n} points of {stride} bytes")
    if kind == "ascii":
        with open(p, "rb") as f:
            f.seek(header_len)
            have = sum(1 for line in f if line.strip())
        if have < n:
            raise ScanlightError(p, f"truncated PCD: header declares {n} points but the file "
                                    f"holds {have}")
    elif kind == "binary" and size - header_len < n * stride:
        have = (size - header_len) // max(stride, 1)
        raise ScanlightError(p, f"truncated PCD: header declares {n} points but the data holds "
                                f"only {have}")
    import open3d as o3d

    pc = o3d.io.read_point_cloud(str(p), format="pcd", remove_nan_points=False,
                                 remove_infinite_points=False)
    if len(pc.points) != n:
        raise ScanlightError(p, f"corrupt PCD: header declares {n} points, open3d read "
                                f"{len(pc.points)}")
    out = {"positions": np.asarray(pc.points, dtype=np.float64), "normals": None, "colors": None,
           "color_type": None}
    if pc.has_normals():
        out["normals"] = np.asarray(pc.normals, dtype=np.float32)
    if pc.has_colors():  # PCD colours are packed 8-bit rgb; open3d hands them over as k/255
        enc = np.round(np.asarray(pc.colors) * 255.0) / 255.0
        out["colors"], out["color_type"] = srgb_to_linear(np.clip(enc, 0, 1)), "uchar"
        out["hdr"] = False
    return out


# ---------------------------------------------------------------------------------------- text

def _text_colors(rgb: np.ndarray) -> tuple[np.ndarray, str, bool, list[str]]:
    """Colours from a typeless text file: (linear rgb, kind, hdr, warnings).

    No types are stored, so the values decide: all in [0, 1] -> sRGB-encoded (the open3d
    convention); integers up to 255 -> 8-bit sRGB; anything else -> linear HDR, with a warning
    (use PLY with float colours to make HDR unambiguous).
    """
    finite = rgb[np.isfinite(rgb)]
    if finite.size == 0 or (finite.min() >= 0 and finite.max() <= 1.0):
        return srgb_to_linear(np.clip(rgb, 0, 1)), "text 0-1 (sRGB)", False, []
    if np.all(finite == np.round(finite)) and finite.min() >= 0 and finite.max() <= 255:
        return srgb_to_linear(np.clip(rgb, 0, 255) / 255.0), "text 0-255 (sRGB)", False, []
    return rgb.astype(np.float32), "text float (linear HDR)", True, [
        "text colours outside 0-1 and 0-255 integers were read as linear HDR radiance"]


def _read_text(p: Path) -> dict:
    ext = p.suffix.lower()
    with open(p, "rb") as f:
        text = io.TextIOWrapper(f, encoding="ascii", errors="replace")
        declared = None
        if ext == ".pts":
            first = text.readline()
            words = first.split()
            if len(words) == 1 and re.fullmatch(r"\d+", words[0]):
                declared = int(words[0])
            else:
                text.seek(0)
        try:
            with warnings.catch_warnings():  # an empty file is reported as "no points" later
                warnings.simplefilter("ignore", UserWarning)
                rows = np.loadtxt(text, dtype=np.float64, ndmin=2, comments=("#", "//"))
        except ValueError as exc:
            raise ScanlightError(p, f"corrupt {ext} file: rows must hold the same number of "
                                    f"numbers ({exc})") from None
    if declared is not None and len(rows) < declared:
        raise ScanlightError(p, f"truncated PTS: first line declares {declared} points but the "
                                f"file holds {len(rows)}")
    out = {"positions": np.zeros((0, 3)), "normals": None, "colors": None, "color_type": None,
           "warnings": []}
    if len(rows) == 0:
        return out
    ncol = rows.shape[1]
    if ncol < 3:
        raise ScanlightError(p, f"{ext} rows need at least x y z, found {ncol} numbers")
    out["positions"] = rows[:, :3]
    cols = None
    if ext == ".xyzn" and ncol >= 6:
        out["normals"] = rows[:, 3:6].astype(np.float32)
    elif ext == ".xyzrgb" and ncol >= 6:
        cols = rows[:, 3:6]
    elif ext == ".pts" and ncol >= 6:
        cols = rows[:, ncol - 3:]  # x y z [intensity] r g b
    needed = {".xyz": 3, ".xyzn": 6, ".xyzrgb": 6, ".pts": 3}[ext]
    if ncol < needed:
        raise ScanlightError(p, f"{ext} rows need {needed} numbers, found {ncol}")
    if cols is not None:
        out["colors"], out["color_type"], out["hdr"], out["warnings"] = _text_colors(cols)
    return out


# ------------------------------------------------------------------------------------- normals

def estimate_normals(positions: np.ndarray, k: int = NORMAL_NEIGHBOURS) -> np.ndarray:
    """Unit normals from k-nearest-neighbour plane fits, oriented towards the bounding-box centre.

    Positions are centred first so that clouds offset by 1e6 m keep their precision in open3d.
    Points whose fit fails (fewer than 3 neighbours) get the direction towards the centre.
    """
    import open3d as o3d

    lo, hi = positions.min(axis=0), positions.max(axis=0)
    local = positions - (lo + hi) / 2
    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(local))
    if len(local) >= 3:
        pc.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(knn=min(k, len(local))))
        pc.orient_normals_towards_camera_location(np.zeros(3))
        n = np.asarray(pc.normals, dtype=np.float64)
    else:
        n = np.zeros_like(local)
    return _fallback_normals(n, local).astype(np.float32)


def _fallback_normals(n: np.ndarray, local: np.ndarray) -> np.ndarray:
    """Normalise; rows with no usable direction point to the centre (or +y at the centre)."""
    length = np.linalg.norm(n, axis=1)
    bad = ~np.isfinite(length) | (length < 1e-12)
    out = np.where(bad[:, None], 0.0, n) / np.where(bad, 1.0, length)[:, None]
    if bad.any():
        towards = -local[bad]
        tl = np.linalg.norm(towards, axis=1)
        towards = np.where(tl[:, None] > 1e-12, towards / np.maximum(tl, 1e-300)[:, None],
                           np.array([0.0, 1.0, 0.0]))
        out[bad] = towards
    return out


# ---------------------------------------------------------------------------------------- load

def _warn(report: dict, p: Path, msg: str) -> None:
    report.setdefault("warnings", []).append(msg)
    log.warning("%s: %s", p, msg)


STRAY_FACTOR = 100.0


def _not_stray(pos: np.ndarray) -> np.ndarray:
    """False for the stray points of a scan: further from its median than STRAY_FACTOR times
    the extent of its central 98% (the largest of the 1st-99th percentile ranges of x, y, z).
    One stray point 1e8 m out in a 10 m room put every camera's near plane 10 km away and left
    float32 coordinates 4 m steps: a silently black render. Real far points (a scanner seeing
    a hill 2 km from a 50 m site) lie well within the factor."""
    if len(pos) < 100:
        return np.ones(len(pos), bool)
    lo, mid, hi = np.quantile(pos, [0.01, 0.5, 0.99], axis=0)
    extent = max(float((hi - lo).max()), 1e-3)
    return np.all(np.abs(pos - mid) <= STRAY_FACTOR * extent, axis=1)


def _rows(mask, pos, normals, colors, attributes):
    """The points where ``mask`` holds, with their normals, colours (either may be None) and
    per-point attributes."""
    return (pos[mask], None if normals is None else normals[mask],
            None if colors is None else colors[mask], {k: v[mask] for k, v in attributes.items()})


def load_cloud(path) -> PointCloud:
    """Read a point cloud; repairs are counted in ``cloud.report`` (see the module docstring)."""
    p = require_file(path, "point cloud", CLOUD_EXTENSIONS)
    ext = p.suffix.lower()
    raw = _read_ply(p) if ext == ".ply" else _read_pcd(p) if ext == ".pcd" else _read_text(p)
    pos, normals, colors = raw["positions"], raw["normals"], raw["colors"]
    attributes = raw.get("attributes", {})
    report: dict = {"points_in_file": int(len(pos)), "color_type": raw["color_type"]}
    for w in raw.get("warnings", []):
        _warn(report, p, w)
    if len(pos) == 0:
        raise ScanlightError(p, "point cloud has no points")

    with np.errstate(invalid="ignore"):
        finite = np.all(np.isfinite(pos), axis=1) & np.all(np.abs(pos) <= MAX_COORD, axis=1)
    report["dropped_nonfinite_positions"] = int((~finite).sum())
    if not finite.all():
        beyond = f"lie beyond {MAX_COORD:g} m"
        if not finite.any():
            raise ScanlightError(p, f"all {len(pos)} points have NaN or Inf positions or {beyond}")
        _warn(report, p, f"dropped {int((~finite).sum())} points with NaN/Inf positions or that "
                         f"{beyond}")
        pos, normals, colors, attributes = _rows(finite, pos, normals, colors, attributes)
    keep = _not_stray(pos)
    report["dropped_stray_points"] = int((~keep).sum())
    if not keep.all():
        _warn(report, p, f"dropped {int((~keep).sum())} stray points more than {STRAY_FACTOR:g} "
                         "times the scan's extent from its centre")
        pos, normals, colors, attributes = _rows(keep, pos, normals, colors, attributes)

    if colors is None:
        colors = np.full((len(pos), 3), DEFAULT_COLOR, dtype=np.float32)
        _warn(report, p, f"no colours in the file: using linear grey {DEFAULT_COLOR}")
        hdr = False
    else:
        hdr = raw["hdr"]
        colors, counts = clean_rgb(colors, "colors")
        report.update(counts)
        if any(counts.values()):
            _warn(report, p, describe_counts(counts))

    report["replaced_bad_normals"] = 0
    if normals is None:
        normals = estimate_normals(pos)
        report["normals"] = "estimated"
        _warn(report, p, "no normals in the file: estimated from "
                         f"{NORMAL_NEIGHBOURS} neighbours, oriented towards the cloud centre")
    else:
        length = np.linalg.norm(normals.astype(np.float64), axis=1)
        bad = ~np.isfinite(length) | (length < 1e-6)
        normals = normals / np.where(bad, 1.0, length)[:, None]
        report["normals"] = "file"
        if bad.any():
            normals[bad] = estimate_normals(pos)[bad]
            report["replaced_bad_normals"] = int(bad.sum())
            _warn(report, p, f"re-estimated {int(bad.sum())} zero-length or NaN normals")
    return PointCloud(pos, normals, colors, hdr=hdr, source=str(p), report=report,
                      attributes=attributes)


# ---------------------------------------------------------------------------------------- save

def save_cloud(cloud: PointCloud, path, color_type: str | None = None) -> None:
    """Write a binary little-endian PLY atomically.

    x, y, z are float32, or double when any |coordinate| exceeds FLOAT32_COORD_LIMIT (4096 m) so
    offset scans keep sub-millimetre precision; nx, ny, nz float32. Colours: ``color_type`` None
    picks float32 linear for HDR clouds and uchar sRGB for LDR ones, so that load_cloud gives back
    the same ``hdr`` flag (8-bit values survive uchar -> linear -> uchar exactly); pass "float32"
    to store an LDR cloud's linear colours as floats. ``cloud.attributes`` follow as extra
    properties of their names: uint8 -> uchar, int32 -> int, float -> float (NaN allowed); any
    other dtype, shape or name is a ValueError (see the module docstring).
    """
    p = Path(path)
    if p.suffix.lower() != ".ply":
        raise ScanlightError(p, "point clouds are saved as .ply only")
    if color_type is None:
        color_type = "float32" if cloud.hdr else "uchar"
    if color_type not in ("float32", "uchar"):
        raise ValueError(f"color_type must be 'float32' or 'uchar', got {color_type!r}")
    pos = cloud.positions
    if not (np.all(np.isfinite(pos)) and np.all(np.isfinite(cloud.normals))
            and np.all(np.isfinite(cloud.colors))):
        raise ValueError("save_cloud: the cloud holds NaN or Inf")
    big = len(pos) > 0 and float(np.abs(pos).max()) > FLOAT32_COORD_LIMIT
    ptype = ("double", "<f8") if big else ("float", "<f4")
    ctype = ("float", "<f4") if color_type == "float32" else ("uchar", "u1")
    cnames = ("red", "green", "blue")
    attrs = _attribute_types(cloud)
    dtype = np.dtype([(k, ptype[1]) for k in "xyz"] + [(k, "<f4") for k in ("nx", "ny", "nz")]
                     + [(k, ctype[1]) for k in cnames]
                     + [(k, t[1]) for k, t in attrs.items()])
    rec = np.empty(len(pos), dtype=dtype)
    for i, k in enumerate("xyz"):
        rec[k] = pos[:, i]
    for i, k in enumerate(("nx", "ny", "nz")):
        rec[k] = cloud.normals[:, i]
    cols = cloud.colors if color_type == "float32" else to_uint8_srgb(cloud.colors)
    for i, k in enumerate(cnames):
        rec[k] = cols[:, i]
    for k in attrs:
        rec[k] = cloud.attributes[k]
    header = ["ply", "format binary_little_endian 1.0",
              "comment scanlight: " + ("linear HDR float colours" if color_type == "float32"
                                       else "sRGB-encoded 8-bit colours")]
    if PROVENANCE_ATTR in attrs:
        header.append(f"comment {PROVENANCE_ATTR} codes: "
                      + ", ".join(f"{k} {v}" for k, v in sorted(LABEL_NAMES.items())))
    header.append(f"element vertex {len(pos)}")
    header += [f"property {ptype[0]} {k}" for k in "xyz"]
    header += [f"property float {k}" for k in ("nx", "ny", "nz")]
    header += [f"property {ctype[0]} {k}" for k in cnames]
    header += [f"property {t[0]} {k}" for k, t in attrs.items()]
    header.append("end_header")
    with atomic_output(p) as tmp:
        with open(tmp, "wb") as f:
            f.write(("\n".join(header) + "\n").encode("ascii"))
            f.write(rec.tobytes())


def _attribute_types(cloud: PointCloud) -> dict:
    """name -> (PLY type, stored dtype) of each of ``cloud.attributes``; the names the reader
    takes for positions, normals or colours are refused."""
    taken = ("x", "y", "z") + sum(_NORMAL_NAMES + _COLOR_NAMES, ())
    out = {}
    for name, values in cloud.attributes.items():
        if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", name) or name in taken:
            raise ValueError(f"save_cloud: point attribute name {name!r} cannot be a PLY property "
                             f"(letters, digits and _, not one of {', '.join(taken)})")
        dt = values.dtype
        if values.ndim != 1:
            raise ValueError(f"save_cloud: point attribute {name!r} has shape {values.shape}; "
                             "only one value per point is written")
        if dt == np.uint8:
            out[name] = _ATTR_UCHAR
        elif dt == np.int32:
            out[name] = _ATTR_INT
        elif dt.kind == "f":
            out[name] = _ATTR_FLOAT
        else:
            raise ValueError(f"save_cloud: point attribute {name!r} is {dt}; PLY properties are "
                             "written for uint8, int32 and float arrays")
    return out
