"""The BSH node record, defined once for numpy and GLSL (40 bytes, as in the paper's Section 5.4).

One record = ten 32-bit words, read on the GPU from a ``uint`` SSBO (a GLSL struct with vec3
members would be padded to 48 bytes by std430, so the shader unpacks words itself):

====  =============  ==============================================================================
word  field          meaning
====  =============  ==============================================================================
0-2   center         bounding-sphere centre, float32, *relative to* ``Hierarchy.origin`` (float64)
3     radius         bounding-sphere radius, float32 (conservative: contains every point below)
4-6   color          mean linear HDR radiance of the points below, float32 (can exceed 65504)
7     cone           normal cone: axis octahedral-encoded 2 x 11 bits (bits 0-10 x, 11-21 y) and
                     half-aperture in 10 bits (bits 22-31, units of pi/1023, rounded *up*)
8     skip           escape index: the next node in depth-first order after this subtree
9     count_flags    bits 0-30 number of points below; bit 31 set on leaves (incl. cluster leaves)
====  =============  ==============================================================================

Traversal convention (stackless, depth-first, root = node 0)::

    uint i = 0u;
    while (i != BSH_END) {                 // BSH_END == node_count() == root's skip
        Node n = load_node(i);
        if (n.is_leaf || accept(n)) { use(n); i = n.skip; }   // leaf or good enough: skip subtree
        else if (cull(n))           {         i = n.skip; }   // reject subtree
        else                        {         i = i + 1u; }   // descend: first child is i + 1
    }

An internal node ``i`` always has exactly two children: ``i + 1`` and ``skip(i + 1)``
(``node_left`` / ``node_right``), so breadth-first PBGI variants can push children explicitly.
A node is a leaf iff ``skip == i + 1`` (the flag bit says the same, without a second read).

GLSL API of ``gen/node_layout.glsl`` (include it after defining ``NODE_BINDING`` if binding 3 is
taken)::

    #define NODE_BINDING 3          // default SSBO binding point, override with a define
    buffer BshNodes { uint bsh_words[]; }   // readonly, std430
    struct Node { vec3 center; float radius; vec3 color; vec3 cone_axis; float cone_cos;
                  float cone_angle; uint skip; uint count; bool is_leaf; };
    uint  node_count();             // number of records in the bound buffer (== BSH_END)
    Node  load_node(uint i);        // full decode (10 words)
    vec4  node_sphere(uint i);      // xyz centre, w radius (4 words: the cheap culling read)
    vec3  node_color(uint i);
    vec4  node_cone(uint i);        // xyz unit axis, w cos(half-aperture)
    float node_cone_angle(uint i);  // half-aperture in radians, in [0, pi]
    uint  node_skip(uint i);
    uint  node_point_count(uint i);
    bool  node_is_leaf(uint i);
    uint  node_left(uint i);        // == i + 1
    uint  node_right(uint i);       // == node_skip(i + 1)
    vec3  bsh_decode_oct(uint cone_word);

A unit normal v is inside node n's normal cone iff ``dot(v, cone_axis) >= cone_cos``;
``cone_angle == pi`` means "all directions" (cone_cos == -1). Cones are stored conservatively
(axis quantisation and angle rounding only ever widen them); spheres contain every point below.

Upload: ``ctx.buffer(hierarchy.nodes.tobytes())``, then ``bind_to_storage_buffer(NODE_BINDING)``.
Centres are relative to ``Hierarchy.origin`` (float64): shade in that frame (subtract the origin
from receiver positions on the CPU in float64) so a scan far from the world origin keeps float32
precision.
"""

from __future__ import annotations

import numpy as np

from app.render.gpu_records import Field, Record

NODE_BINDING_DEFAULT = 3      # app/pbgi/gpu_layout.py's SSBO.NODES
LAYOUT_VERSION = 1

# The single source of the record layout (app/render/gpu_records.py: fields in word order).
NODE = Record("BshNodeRecord", (
    Field("center", "vec3", "bounding-sphere centre, relative to the hierarchy origin"),
    Field("radius", "float", "bounding-sphere radius"),
    Field("color", "vec3", "mean linear HDR radiance of the points below"),
    Field("cone", "uint", "normal cone: octahedral axis 2 x 11 bits, half-angle 10 bits"),
    Field("skip", "uint", "escape index: the next node after this subtree"),
    Field("count_flags", "uint", "bits 0-30 points below, bit 31 leaf"),
), word="uint", slot_words=1)
NODE_WORDS = NODE.words
NODE_BYTES = NODE.nbytes

# (name, numpy base type, components, first word), derived from NODE.
FIELDS = tuple((f.name, NODE.dtype.fields[f.name][0].base.type, f.comps, NODE.index(f.name))
               for f in NODE.fields)

AXIS_BITS = 11
ANGLE_BITS = 10
AXIS_MAX = (1 << AXIS_BITS) - 1      # 2047
ANGLE_MAX = (1 << ANGLE_BITS) - 1    # 1023: pi
ANGLE_STEP = np.pi / ANGLE_MAX
LEAF_BIT = np.uint32(1 << 31)
COUNT_MASK = np.uint32((1 << 31) - 1)


NODE_DTYPE = NODE.dtype


# -- cone packing (numpy side; the GLSL decode below mirrors decode_cone) -------------------------

def _oct_encode_xyz(x, y, z):
    s = np.abs(x) + np.abs(y) + np.abs(z)
    s = np.where(s > 0, s, 1.0)
    x, y = x / s, y / s
    neg = z < 0
    ox = np.where(neg, (1.0 - np.abs(y)) * np.where(x >= 0, 1.0, -1.0), x)
    oy = np.where(neg, (1.0 - np.abs(x)) * np.where(y >= 0, 1.0, -1.0), y)
    qx = np.clip(np.rint((ox * 0.5 + 0.5) * AXIS_MAX), 0, AXIS_MAX).astype(np.uint32)
    qy = np.clip(np.rint((oy * 0.5 + 0.5) * AXIS_MAX), 0, AXIS_MAX).astype(np.uint32)
    return qx, qy


def _oct_decode_xyz(qx, qy):
    x = qx.astype(np.float64) * (2.0 / AXIS_MAX) - 1.0
    y = qy.astype(np.float64) * (2.0 / AXIS_MAX) - 1.0
    z = 1.0 - np.abs(x) - np.abs(y)
    t = np.maximum(-z, 0.0)
    x = x + np.where(x >= 0, -t, t)
    y = y + np.where(y >= 0, -t, t)
    n = np.sqrt(x * x + y * y + z * z)
    return x / n, y / n, z / n


def oct_encode(v: np.ndarray) -> np.ndarray:
    """Unit vectors (M, 3) -> (M, 2) integer octahedral coordinates in [0, AXIS_MAX]."""
    v = np.asarray(v, dtype=np.float64)
    return np.stack(_oct_encode_xyz(v[:, 0], v[:, 1], v[:, 2]), axis=1)


def oct_decode(q: np.ndarray) -> np.ndarray:
    """(M, 2) octahedral integers -> (M, 3) unit float64 vectors (same formula as the GLSL)."""
    return np.stack(_oct_decode_xyz(q[:, 0], q[:, 1]), axis=1)


def pack_cone(axis: np.ndarray, half_angle: np.ndarray, margin: float = 1e-5) -> np.ndarray:
    """Pack cones conservatively: the decoded cone contains the given one.

    ``axis`` is (M, 3) (or a transposed (3, M) array). The quantised axis deviates from the
    true one by ``delta``; the stored half-angle is ``half_angle + delta + margin`` rounded *up*
    to the 10-bit grid (``margin`` covers the float32 decode on the GPU and the build's angle
    round-off), saturating at pi (= all directions).
    """
    a = np.asarray(axis, dtype=np.float64)
    x, y, z = a[:, 0], a[:, 1], a[:, 2]
    qx, qy = _oct_encode_xyz(x, y, z)
    dx, dy, dz = _oct_decode_xyz(qx, qy)
    n = np.maximum(np.sqrt(x * x + y * y + z * z), 1e-300)
    cos_d = (x * dx + y * dy + z * dz) / n
    delta = np.arccos(np.clip(cos_d, -1.0, 1.0))  # error ~1e-8 rad, inside the margin
    ang = np.asarray(half_angle, dtype=np.float64) + delta + margin
    qa = np.clip(np.ceil(ang / ANGLE_STEP), 0, ANGLE_MAX).astype(np.uint32)
    return qx | (qy << np.uint32(AXIS_BITS)) | (qa << np.uint32(2 * AXIS_BITS))


def decode_cone(words: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cone words -> (unit axis (M, 3) float64, half-angle (M,) float64 radians)."""
    w = np.asarray(words, dtype=np.uint32)
    mask = np.uint32(AXIS_MAX)
    axis = np.stack(_oct_decode_xyz(w & mask, (w >> np.uint32(AXIS_BITS)) & mask), axis=1)
    angle = (w >> np.uint32(2 * AXIS_BITS)).astype(np.float64) * ANGLE_STEP
    return axis, angle


def decode(nodes: np.ndarray) -> dict:
    """All fields of a record array as plain arrays (what load_node returns in GLSL)."""
    axis, angle = decode_cone(nodes["cone"])
    cf = nodes["count_flags"]
    return {
        "center": nodes["center"].astype(np.float32),
        "radius": nodes["radius"].astype(np.float32),
        "color": nodes["color"].astype(np.float32),
        "cone_axis": axis,
        "cone_angle": angle,
        "cone_cos": np.cos(angle),
        "skip": nodes["skip"].astype(np.int64),
        "count": (cf & COUNT_MASK).astype(np.int64),
        "is_leaf": (cf & LEAF_BIT) != 0,
    }


# -- GLSL ------------------------------------------------------------------------------------------

def _word_expr(word: int) -> str:
    return f"bsh_words[base + {word}u]" if word else "bsh_words[base]"


def glsl_header() -> str:
    """The GLSL text of ``gen/node_layout.glsl``, generated from FIELDS and the cone constants."""
    off = {name: word for name, _, _, word in FIELDS}

    def f(name, k=0):
        return f"uintBitsToFloat({_word_expr(off[name] + k)})"

    def u(name):
        return _word_expr(off[name])

    return f"""// GENERATED by app/pbgi/layout.py:glsl_header() - do not edit; change FIELDS there.
// BSH node records: {NODE_WORDS} x 32-bit words ({NODE_BYTES} bytes) per node, depth-first order.
// Traversal: start at i = 0; descend -> i + 1; skip subtree -> node_skip(i); stop at BSH_END.
#ifndef SCANLIGHT_NODE_LAYOUT_GLSL
#define SCANLIGHT_NODE_LAYOUT_GLSL
#ifndef NODE_BINDING
#define NODE_BINDING {NODE_BINDING_DEFAULT}
#endif
#define BSH_NODE_WORDS {NODE_WORDS}u
#define BSH_LAYOUT_VERSION {LAYOUT_VERSION}
#define BSH_AXIS_BITS {AXIS_BITS}u
#define BSH_AXIS_MAX {AXIS_MAX}u
#define BSH_ANGLE_STEP {ANGLE_STEP!r}
#define BSH_LEAF_BIT 0x80000000u
#define BSH_COUNT_MASK 0x7fffffffu

layout(std430, binding = NODE_BINDING) readonly buffer BshNodes {{
    uint bsh_words[];
}};

struct Node {{
    vec3 center;      // bounding-sphere centre, relative to the hierarchy origin
    float radius;     // bounding-sphere radius
    vec3 color;       // mean linear HDR radiance of the points below
    vec3 cone_axis;   // unit axis of the normal cone
    float cone_cos;   // cos(half-aperture); -1 = all directions
    float cone_angle; // half-aperture in radians [0, pi]
    uint skip;        // escape index: next node after this subtree
    uint count;       // number of points below
    bool is_leaf;     // leaf or cluster leaf (also: skip == i + 1)
}};

uint node_count() {{ return uint(bsh_words.length()) / BSH_NODE_WORDS; }}
#define BSH_END node_count()

vec3 bsh_decode_oct(uint w) {{
    vec2 p = vec2(float(w & BSH_AXIS_MAX), float((w >> BSH_AXIS_BITS) & BSH_AXIS_MAX))
             / float(BSH_AXIS_MAX) * 2.0 - 1.0;
    vec3 v = vec3(p, 1.0 - abs(p.x) - abs(p.y));
    float t = max(-v.z, 0.0);
    v.x += (v.x >= 0.0) ? -t : t;
    v.y += (v.y >= 0.0) ? -t : t;
    return normalize(v);
}}

float bsh_cone_angle(uint w) {{ return float(w >> (2u * BSH_AXIS_BITS)) * BSH_ANGLE_STEP; }}

vec4 node_sphere(uint i) {{
    uint base = i * BSH_NODE_WORDS;
    return vec4({f("center", 0)}, {f("center", 1)},
                {f("center", 2)}, {f("radius")});
}}

vec3 node_color(uint i) {{
    uint base = i * BSH_NODE_WORDS;
    return vec3({f("color", 0)}, {f("color", 1)}, {f("color", 2)});
}}

float node_cone_angle(uint i) {{
    uint base = i * BSH_NODE_WORDS;
    return bsh_cone_angle({u("cone")});
}}

vec4 node_cone(uint i) {{
    uint base = i * BSH_NODE_WORDS;
    uint w = {u("cone")};
    return vec4(bsh_decode_oct(w), cos(bsh_cone_angle(w)));
}}

uint node_skip(uint i) {{ uint base = i * BSH_NODE_WORDS; return {u("skip")}; }}
uint node_point_count(uint i) {{
    uint base = i * BSH_NODE_WORDS;
    return {u("count_flags")} & BSH_COUNT_MASK;
}}
bool node_is_leaf(uint i) {{
    uint base = i * BSH_NODE_WORDS;
    return ({u("count_flags")} & BSH_LEAF_BIT) != 0u;
}}
uint node_left(uint i) {{ return i + 1u; }}
uint node_right(uint i) {{ return node_skip(i + 1u); }}

Node load_node(uint i) {{
    uint base = i * BSH_NODE_WORDS;
    Node n;
    n.center = vec3({f("center", 0)}, {f("center", 1)}, {f("center", 2)});
    n.radius = {f("radius")};
    n.color = vec3({f("color", 0)}, {f("color", 1)}, {f("color", 2)});
    uint w = {u("cone")};
    n.cone_axis = bsh_decode_oct(w);
    n.cone_angle = bsh_cone_angle(w);
    n.cone_cos = cos(n.cone_angle);
    n.skip = {u("skip")};
    uint cf = {u("count_flags")};
    n.count = cf & BSH_COUNT_MASK;
    n.is_leaf = (cf & BSH_LEAF_BIT) != 0u;
    return n;
}}
#endif
"""
