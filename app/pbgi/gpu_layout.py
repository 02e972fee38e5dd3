"""Every record and number the PBGI passes share between Python and GLSL, declared once.

Python packs and reads these records through their numpy dtypes and binds buffers, textures and
images to the numbers below; the shaders get the same numbers and the record decoders from the
generated includes (``gen/*.glsl``, registered in app/render/programs.py). The record helper is
app/render/gpu_records.py; the BSH node record is app/pbgi/layout.py (same helper).
tests/pbgi/test_gpu_records.py decodes every record on the GPU through the generated code.

Receivers and materials - one rule for the Disney parameters
-------------------------------------------------------------
A receiver carries the parameters a material may texture: base colour, metallic and roughness,
each factor x texture as the G-buffer computed them (shaders/gbuffer.glsl). The material table
carries only the others (``MATERIAL``: subsurface, specular, ... - no texture can change them).
``TEXTURED_PARAMS`` is the split; ``receiver_principled(rid)`` (gen/materials.glsl) assembles a
receiver's parameters from the two and is the only place the gather gets them, so no parameter
reaches the gather twice (a roughness in the table too would be a second value, silently
ignored or silently winning). ``receiver_params`` is the same rule in numpy (the CPU reference's
G-buffer, tests/support/scenes.py).
"""

from __future__ import annotations

import numpy as np

from app.material import ALL_NAMES, SCALAR_PARAMS
from app.pbgi import layout
from app.pbgi.brdf import PARAM_NAMES
from app.render.gpu_records import Field, Pad, Record, Units

# -- binding points and units ---------------------------------------------------------------------
# Numbers shared by names never meet in one program (the comment says who binds what).
SSBO = Units("SSBO binding points: layout(std430, binding = SSBO_X), bind_to_storage_buffer",
             "SSBO_", {
                 "RECEIVERS": (0, "receiver records (RECEIVER): every per-receiver pass"),
                 "WALK_STATE": (1, "per-receiver resume state of a walk (CLASSIC_STATE, "
                                   "FINISH_STATE)"),
                 "COUNTERS": (2, "refinement counters (PAIR_COUNTERS), or a walk's count of "
                                 "receivers left (one uint)"),
                 "NODES": (layout.NODE_BINDING_DEFAULT, "BSH node records (gen/node_layout.glsl):"
                                                        " building the node textures"),
                 "SHARE": (3, "far-field sharing: per-row ball and frame (SHARE_ROW), "
                              "pbgi_classic.glsl with SHARE_SPLIT"),
                 "BLOCK_OF": (3, "far-field sharing: block of each batch receiver (BLOCK_OF), "
                                 "pbgi_share_merge.glsl"),
                 "MATERIALS": (6, "material table (MATERIAL): the gather"),
                 "OUTPUT": (7, "the gather's output (GATHER_OUTPUT), one per tile pixel"),
                 "FRAMES": (8, "the gather's micro-buffer frame per batch receiver (FRAME), "
                               "FRAME_NORMALS"),
                 "PARTS": (9, "the gather's radiance split by BRDF factor (GATHER_PARTS), one "
                              "per tile pixel, GATHER_PARTS"),
             })
TEXTURE = Units("texture units: layout(binding = TEX_X) uniform sampler, Texture.use(location)",
                "TEX_", {
                    "ENV": (0, "environment cube map (the gather with RADIANCE_CUBEMAP)"),
                    "BSH_SPHERE": (1, "node texture: sphere (BSH_SPHERE)"),
                    "BSH_CONE": (2, "node texture: normal cone (BSH_CONE)"),
                    "BSH_LINK": (3, "node texture: skip and count (BSH_LINK)"),
                    "BSH_COLOR": (4, "node texture: colour (BSH_COLOR)"),
                    "MB_TABLE": (5, "micro-buffer entry directions and weights (MB_DIRECTION)"),
                    "MB_INDEX": (6, "micro-buffer grid pixel -> bands (MB_BANDS)"),
                    "MB_FLUX": (7, "micro-buffer entry flux (MB_FLUX), the gather with "
                                   "FRAME_NORMALS"),
                    "ASSET_DIR": (8, "the asset's glossy bounce: how its nodes' radiance varies "
                                     "with direction (app/pbgi/nodetex.py: directional)"),
                    "ASSET_ENV": (9, "the asset's mirror bounce: the room seen from the asset's "
                                     "centre (a cube map), the gather with ASSET_MIRROR"),
                    "METAL_ALBEDO": (10, "the asset's mirror bounce: a metal's directional "
                                        "albedo (app/pbgi/brdf.py: metal_albedo_table)"),
                })
IMAGE = Units("image units: layout(format, binding = IMG_X) uniform image, bind_to_image",
              "IMG_", {
                  "MB": (0, "the micro-buffers of a batch (MB_ENTRY), one row per receiver"),
                  "PAIRS": (1, "pair stack (PAIR): pbgi_refine.glsl"),
                  "ITEMS": (2, "second stream (ITEM): refinement and finishing walk"),
                  "HEADS": (3, "per pyramid pixel, its first item (HEAD)"),
                  "MIP_SPHERE": (4, "G-buffer pyramid: position spheres (MIP_SPHERE)"),
                  "MIP_CONE": (5, "G-buffer pyramid: normal cones (MIP_CONE)"),
                  "MIP_LINK": (6, "G-buffer pyramid: topology (MIP_LINK)"),
                  "LOBE": (7, "the lobe micro-buffers of a batch (MB_ENTRY), one row per glossy "
                              "receiver: pbgi_lobe.glsl, the gather with LOBE_BUFFER"),
                  "SHARE_SOURCE": (1, "far-field sharing: the block micro-buffers being copied"),
                  "BSH_SPHERE": (1, "node texture being built: sphere (bsh_textures.glsl)"),
                  "BSH_CONE": (2, "node texture being built: normal cone"),
                  "BSH_LINK": (3, "node texture being built: skip and count"),
                  "BSH_COLOR": (4, "node texture being built: colour"),
              })

WORKGROUP = 64                # local_size_x of the per-receiver / per-item compute passes
BSH_TEX_WIDTH = 4096          # texels per row of the node textures (node i: i % W, i / W)
MIP_WIDTH = 4096              # texels per row of the pyramid and pair-stream images
NIL = 0xFFFFFFFF              # "none" in the pyramid and the pair streams (parent, list end)
MB_EMPTY = 0xFFFFFFFF         # an empty micro-buffer entry (key and node)
MB_FAR_BIT = 0x80000000       # in an entry's node: copied from a far-field block (Hybrid's merge;
                              # the gather scales those by the block's level, block_levels.py)
SHARE_NONE = 0xFFFFFFFF       # a receiver without a far-field block
FRAME_SEED_BLOCK = 0x80000000  # in a frame seed (ShareRow.seed, Frame.seed): a far-field block's
                              # square follows, not an image pixel (farfield.square_seeds)
WALK_DONE = 1                 # walk state flags: the walk has finished
WALK_CUT_SHORT = 2            # ... a loop of it was cut short by the driver (llvmpipe)

for _w in (BSH_TEX_WIDTH, MIP_WIDTH):
    assert _w & (_w - 1) == 0, "image widths are powers of two (texel = (i & (W-1), i >> log2 W))"


LOOP_LIMIT = 65535   # llvmpipe: loop iterations per invocation, all loops together, past which
                     # it leaves the shader silently (every bounded walk stays below it)

# The walks compiled without their rasterisation and ray casts (lib/pbgi_cut.glsl: cut_raster,
# pbgi_lobe.glsl): a render that times its walks alone (Relighter.walks_only, bench profile).
WALK_ONLY = {"CUT_WALK_ONLY": 1}


def dispatch_groups(n: int, size: int = WORKGROUP) -> int:
    """Work groups for one invocation per item (``size`` invocations each)."""
    return (int(n) + int(size) - 1) // int(size)


# -- receivers and materials ----------------------------------------------------------------------
_TOOLTIP = {p.name: p.tooltip for p in SCALAR_PARAMS}

# The parameters a receiver carries (factor x texture from the G-buffer); the rest come from the
# material table. The one rule for where the gather takes each Disney parameter from.
TEXTURED_PARAMS = ("base_color", "metallic", "roughness")

# Slot k of a receiver is G-buffer render target k (shaders/gbuffer.glsl writes them with
# layout(location = RECEIVER_SLOT_...)); compaction replaces target 0's w (coverage) by the pixel.
RECEIVER = Record("Receiver", (
    Field("position", "vec3", "position relative to the hierarchy origin"),
    Field("pixel", "uint", "pixel index in the tile, row-major, row 0 at the top"),
    Field("normal", "vec3", "unit shading normal (normal map applied, bent towards the viewer)"),
    Field("material", "uint", "material id: row of the material table", stored_as="value"),
    Field("tangent", "vec3", "unit tangent, orthogonal to the shading normal"),
    Field("roughness", "float", "roughness, factor x texture, in [0, 1]"),
    Field("base_color", "vec3", "linear base colour, factor x texture, in [0, 1]"),
    Field("metallic", "float", "metallic, factor x texture, in [0, 1]"),
), word="float", doc="an object pixel of the G-buffer")

MATERIAL = Record("MaterialConstants", tuple(
    Field(n, "float", _TOOLTIP[n]) for n in ALL_NAMES if n not in TEXTURED_PARAMS
), word="float", doc="the Disney parameters no texture changes, one row per material")

assert set(TEXTURED_PARAMS) <= {f.name for f in RECEIVER.fields}


def material_rows(materials) -> np.ndarray:
    """The material table: one MATERIAL record per material (at least one row)."""
    out = MATERIAL.zeros(max(len(materials), 1))
    for i, m in enumerate(materials):
        for f in MATERIAL.fields:
            out[f.name][i] = getattr(m, f.name)
    return out


def _param_columns(name: str) -> slice:
    """Columns of a Disney parameter in brdf.PARAM_NAMES order (base colour: three)."""
    i = PARAM_NAMES.index("base_r") if name == "base_color" else PARAM_NAMES.index(name)
    return slice(i, i + (3 if name == "base_color" else 1))


def receiver_params(params: np.ndarray, receivers) -> np.ndarray:
    """The rule in numpy: (n, 13) Disney parameters (brdf.PARAM_NAMES order) with
    TEXTURED_PARAMS replaced by the RECEIVER records' values, in place (returned)."""
    rec = RECEIVER.view(receivers)
    for name in TEXTURED_PARAMS:
        params[:, _param_columns(name)] = rec[name].reshape(len(rec), -1)
    return params


def principled_params(receivers, table) -> np.ndarray:
    """numpy twin of ``receiver_principled``: (n, 13) float64 parameters in brdf.PARAM_NAMES
    order for RECEIVER records ``receivers`` and the MATERIAL table ``table``."""
    rec = RECEIVER.view(receivers)
    rows = MATERIAL.view(table)[(rec["material"] + np.float32(0.5)).astype(np.int64)]
    params = np.zeros((len(rec), len(PARAM_NAMES)))
    for f in MATERIAL.fields:
        params[:, _param_columns(f.name)] = rows[f.name][:, None]
    return receiver_params(params, rec)


# The G-buffer's vertex buffer (shaders/gbuffer.glsl's inputs, app/pbgi/gbuffer.py's upload).
GBUFFER_VERTEX = Record("GBufferVertex", (
    Field("position", "vec3", "relative to the hierarchy origin"),
    Field("normal", "vec3", "vertex normal"),
    Field("uv", "vec2", "texture coordinates (0 without UVs)"),
    Field("tangent", "vec4", "xyz: direction of increasing u, w: handedness"),
), word="float", slot_words=1, doc="a vertex of the asset")


# -- walks and the pair refinement ---------------------------------------------------------------
CLASSIC_STATE = Record("ClassicState", (
    Field("next", "uint", "node to resume from; >= the node count: done"),
    Field("visited", "uint", "nodes visited so far"),
    Field("flags", "uint", "WALK_DONE | WALK_CUT_SHORT"),
    Field("tests", "uint", "micro-buffer entry tests so far"),
), word="uint", doc="Classic's per-receiver resume state (pbgi_classic.glsl)")

FINISH_STATE = Record("FinishState", (
    Field("node", "uint", "next node of the current sub-tree"),
    Field("end", "uint", "end of the current sub-tree: skip(its root)"),
    Field("next_item", "uint", "next item on the current list, or NIL"),
    Field("pixel", "uint", "pyramid pixel whose list is walked; NIL: every list is done"),
    Field("visited", "uint", "nodes visited so far"),
    Field("flags", "uint", "WALK_DONE | WALK_CUT_SHORT"),
    Field("tests", "uint", "micro-buffer entry tests so far"),
    Field("pixel0", "uint", "the receiver's level-0 pyramid pixel"),
), word="uint", doc="the finishing walk's per-receiver resume state (pbgi_finish.glsl)")

PAIR_COUNTERS = Record("PairCounters", (
    Field("stack", "uint", "pairs on the stack"),
    Field("s2", "uint", "items appended to the second stream (may exceed s2_cap)"),
    Field("base", "uint", "first popped pair of this pass"),
    Field("k", "uint", "pairs popped by this pass"),
    Field("refine_args", "uvec3", "indirect dispatch of REFINE"),
    Field("move_args", "uvec3", "indirect dispatch of MOVE"),
    Field("move_src", "uint", "first pair MOVE copies into the popped hole"),
    Field("move_n", "uint", "pairs MOVE copies"),
    Field("allowed", "uint", "1: refinement may push children this pass"),
    Field("pushed_back", "uint", "stat: items pushed back onto a full stack"),
    Field("processed", "uint", "stat: pairs popped"),
    Field("node_refines", "uint", "stat: pairs replaced by their node's children"),
    Field("pixel_splits", "uint", "stat: pairs replaced by their pixel's children"),
    Field("culled", "uint", "stat: pairs culled for every receiver below"),
    Field("to_s2", "uint", "stat: items appended"),
    Field("peak_stack", "uint", "stat: largest stack"),
    Field("passes", "uint", "stat: passes that popped pairs"),
    Field("accepted", "uint", "stat: pairs every receiver below decides in one step"),
    Field("kmax", "uint", "most pairs one pass pops (set by the host)"),
    Field("cap", "uint", "stack capacity in pairs (set by the host)"),
    Field("s2_cap", "uint", "second-stream capacity in items (set by the host)"),
    Field("disabled_passes", "uint", "stat: passes run with children disabled"),
), word="uint", slot_words=1, words=32, doc="pbgi_refine.glsl's counters[] (atomics)")

PAIR = Record("Pair", (
    Field("node", "uint", "BSH node A"),
    Field("pixel", "uint", "G-buffer pyramid pixel P"),
), word="uint", slot_words=2, doc="a pending (node, pixel) pair on the stack")

ITEM = Record("Item", (
    Field("node", "uint", "sub-tree root"),
    Field("next", "uint", "next item on the same pixel's list, or NIL"),
    Field("pixel", "uint", "the pyramid pixel whose list holds it"),
    Field("skip", "uint", "skip(node): the end of the sub-tree"),
), word="uint", doc="a second-stream item: a sub-tree for the finishing walk")

HEAD = Record("Head", (
    Field("item", "uint", "first item of the pixel's list, or NIL"),
), word="uint", slot_words=1, doc="per pyramid pixel, the head of its item list")

# -- the G-buffer pyramid -------------------------------------------------------------------------
MIP_SPHERE = Record("MipSphere", (
    Field("center", "vec3", "centre of a sphere containing its receivers' positions"),
    Field("radius", "float", "its radius (0 at level 0)"),
), word="float", doc="pyramid pixel: bound of the positions below")

MIP_CONE = Record("MipCone", (
    Field("axis", "vec3", "unit axis of a cone containing its receivers' normals"),
    Field("angle", "float", "its half-angle in radians (0 at level 0)"),
), word="float", doc="pyramid pixel: bound of the normals below")

MIP_LINK = Record("MipLink", (
    Field("first", "uint", "first child pixel; at level 0: the receiver's slot in the batch"),
    Field("count", "uint", "number of child pixels (1-4); 0 at level 0"),
    Field("parent", "uint", "parent pixel, or NIL at the top"),
    Field("level", "uint", "pyramid level, 0 = one receiver"),
), word="uint", doc="pyramid pixel: topology")

# -- node textures --------------------------------------------------------------------------------
BSH_SPHERE = Record("BshSphere", (
    Field("center", "vec3", "bounding-sphere centre, relative to the hierarchy origin"),
    Field("radius", "float", "bounding-sphere radius"),
), word="float", doc="node texture: sphere")

BSH_CONE = Record("BshCone", (
    Field("axis", "vec3", "unit axis of the normal cone"),
    Field("cos_angle", "float", "cos(half-aperture); -1 = all directions"),
), word="float", doc="node texture: normal cone")

BSH_LINK = Record("BshLink", (
    Field("skip", "uint", "escape index: the next node after this sub-tree"),
    Field("count_flags", "uint", "points below | leaf bit (the node record's word)"),
    Pad(2),
), word="uint", doc="node texture: skip and count")

BSH_COLOR = Record("BshColor", (
    Field("color", "vec3", "mean linear HDR radiance of the points below"),
    Pad(1),
), word="float", doc="node texture: colour")

# -- the micro-buffers ----------------------------------------------------------------------------
MB_ENTRY = Record("MbEntry", (
    Field("key", "uint", "depth key: the depth's float bits, tie-break in the low bits"),
    Field("node", "uint", "the node seen through the entry; | MB_FAR_BIT: a far-field "
                          "block's, copied by Hybrid's merge"),
), word="uint", slot_words=2, doc="micro-buffer texel (MB_EMPTY in both: empty)")

MB_DIRECTION = Record("MbDirection", (
    Field("dir", "vec3", "unit centroid direction of the entry, receiver frame"),
    Field("weight", "float", "cosine-weighted solid angle of the entry (0: outside the disc)"),
), word="float", doc="micro-buffer entry table")

MB_FLUX = Record("MbFlux", (
    Field("flux", "vec3", "integral of the direction over the entry, receiver frame"),
    Field("solid_angle", "float", "the entry's solid angle"),
), word="float", doc="micro-buffer entry flux")

MB_BANDS = Record("MbBands", (
    Field("first", "uint", "first further elevation band of grid pixel (x, y)"),
    Field("count", "uint", "number of further bands"),
    Field("prefix", "uint", "summed-area prefix of count over [0, x) x [0, y)"),
    Field("elevation", "uint", "lower elevation of the pixel's bands (low 16 bits) and the "
                               "elevation one band spans (high 16 bits), in 1/65535 of pi / 2"),
), word="uint", doc="micro-buffer grid pixel index, (M + 1) x (M + 1) texels")

# -- far-field sharing and the gather -------------------------------------------------------------
SHARE_ROW = Record("ShareRow", (
    Field("center", "vec3", "centre of the ball that splits the tree for this row"),
    Field("ball", "float", "its radius D: a node outside is far; +inf: nothing is far"),
    Field("frame", "vec3", "unit normal whose frame and horizon the row's micro-buffer uses"),
    Field("seed", "uint", "that frame's turn (lib/microbuffer.glsl: mb_frame_shared): "
                          "FRAME_SEED_BLOCK | the row's block's square (farfield.square_seeds), "
                          "or SHARE_NONE: the row's receiver's own pixel"),
), word="float", doc="far-field sharing: per micro-buffer row of a SHARE_SPLIT walk")

BLOCK_OF = Record("BlockOf", (
    Field("block", "uint", "far-field block of the batch receiver, or SHARE_NONE"),
), word="uint", slot_words=1, doc="far-field sharing: block of each batch receiver")

FRAME = Record("Frame", (
    Field("normal", "vec3", "unit normal whose frame the receiver's micro-buffer is in"),
    Field("seed", "uint", "that frame's turn, as its walks drew it (ShareRow.seed)"),
    Field("level", "vec3", "factor on the entries copied from its block (MB_FAR_BIT): the "
                           "block's level (app/pbgi/block_levels.py); 1 without a block"),
    Pad(1),
), word="float", doc="the gather's micro-buffer frame per batch receiver")

GATHER_OUTPUT = Record("GatherOutput", (
    Field("radiance", "vec3", "outgoing linear radiance towards the camera"),
    Field("status", "float", "1: gathered; -1: the driver cut the gather loop short"),
), word="float", doc="the gather's output per tile pixel")

GATHER_PARTS = Record("GatherParts", (
    Field("diffuse", "vec3", "sum of L w x Burley's diffuse / pi; times (1 - metallic) base"),
    Field("material", "uint", "the receiver's material id (row of the material table)",
          stored_as="value"),
    Field("sheen", "vec3", "sum of L w x F_H; times (1 - metallic) sheen colour"),
    Pad(1),
    Field("spec_f0", "vec3", "sum of L w x GGX D G (1 - F_H); times the specular F0"),
    Pad(1),
    Field("spec_one", "vec3", "sum of L w x GGX D G F_H; times 1"),
    Pad(1),
    Field("coat", "vec3", "sum of L w x the clearcoat lobe at clearcoat 1; times clearcoat"),
    Pad(1),
), word="float", doc="the gather's radiance before the factors a material edit may change "
                     "(app/pbgi/gather_parts.py recombines it)")

RECORDS = {r.name: r for r in (
    RECEIVER, MATERIAL, GBUFFER_VERTEX, CLASSIC_STATE, FINISH_STATE, PAIR_COUNTERS, PAIR, ITEM, HEAD, MIP_SPHERE,
    MIP_CONE, MIP_LINK, BSH_SPHERE, BSH_CONE, BSH_LINK, BSH_COLOR, MB_ENTRY, MB_DIRECTION,
    MB_FLUX, MB_BANDS, SHARE_ROW, BLOCK_OF, FRAME, GATHER_OUTPUT, GATHER_PARTS)}


# -- generated GLSL -------------------------------------------------------------------------------
def _banner(fn: str, what: str) -> str:
    return (f"// GENERATED by app/pbgi/gpu_layout.py:{fn}() - do not edit; change {what} there.")


def _log2(w: int) -> int:
    return int(w).bit_length() - 1


def _u(v: int) -> str:
    return f"0x{v:08x}u" if v > 0xFFFF else f"{v}u"


def bindings_glsl() -> str:
    """``gen/bindings.glsl``: binding points, units, image widths, the work-group size and the
    sentinels every pass shares."""
    return f"""{_banner("bindings_glsl", "SSBO, TEXTURE, IMAGE or the constants")}
#ifndef SCANLIGHT_GEN_BINDINGS_GLSL
#define SCANLIGHT_GEN_BINDINGS_GLSL
{SSBO.glsl()}

{TEXTURE.glsl()}

{IMAGE.glsl()}

#define WORKGROUP_SIZE {WORKGROUP}    // local_size_x of the per-item passes
#define BSH_TEX_WIDTH {BSH_TEX_WIDTH}u    // node i at texel (i % W, i / W) of the node textures
#define BSH_TEX_WIDTH_LOG2 {_log2(BSH_TEX_WIDTH)}u
#define MIP_WIDTH {MIP_WIDTH}u        // pyramid / pair-stream element g at (g % W, g / W)
#define MIP_WIDTH_LOG2 {_log2(MIP_WIDTH)}u
#define NIL {_u(NIL)}        // no pixel / no item (pyramid, pair streams)
#define MB_EMPTY {_u(MB_EMPTY)}   // empty micro-buffer entry (key and node)
#define MB_FAR_BIT {_u(MB_FAR_BIT)}  // entry node: copied from a far-field block (Hybrid)
#define SHARE_NONE {_u(SHARE_NONE)} // receiver without a far-field block
#define FRAME_SEED_BLOCK {_u(FRAME_SEED_BLOCK)} // frame seed: a far-field block's square follows
#define WALK_DONE {_u(WALK_DONE)}           // walk state flags
#define WALK_CUT_SHORT {_u(WALK_CUT_SHORT)}
#define BSH_TEX_LEAF_BIT {_u(int(layout.LEAF_BIT))}  // in BshLink.count_flags, as in the node record
#define BSH_TEX_COUNT_MASK {_u(int(layout.COUNT_MASK))}
#endif
"""


def _ssbo_getters(rec: Record, array: str, prefix: str) -> str:
    """Getters of record i from an SSBO array of its slots: ``array[n * i + k]``."""
    n = rec.slots

    def slot(k):
        first = "i" if n == 1 else f"{n}u * i"
        return f"{array}[{first} + {k}u]" if k else f"{array}[{first}]"
    return rec.glsl_getters(prefix, slot)


def receivers_glsl() -> str:
    """``gen/receivers.glsl``: the receiver record, its SSBO and one getter per field."""
    return f"""{_banner("receivers_glsl", "RECEIVER")}
// Receivers: the object pixels of the G-buffer in image order (app/pbgi/gbuffer.py), {RECEIVER.slots} vec4 each;
// slot k is G-buffer render target k (target 0's w, the coverage, holds the pixel index):
{RECEIVER.glsl_comment()}
#ifndef SCANLIGHT_GEN_RECEIVERS_GLSL
#define SCANLIGHT_GEN_RECEIVERS_GLSL
#include "gen/bindings.glsl"
layout(std430, binding = SSBO_RECEIVERS) readonly buffer Receivers {{ vec4 receivers[]; }};
{_ssbo_getters(RECEIVER, "receivers", "receiver_")}
#endif
"""


def gbuffer_glsl() -> str:
    """``gen/gbuffer.glsl``: shaders/gbuffer.glsl's vertex inputs (GBUFFER_VERTEX, in the
    vertex stage) and its render targets' locations (RECEIVER_SLOT_*: target k = receiver slot
    k)."""
    slots = "\n".join(f"#define RECEIVER_SLOT_{f.name.upper()} {RECEIVER.slot(f.name)}"
                       for f in RECEIVER.fields)
    return f"""{_banner("gbuffer_glsl", "GBUFFER_VERTEX or RECEIVER")}
#ifndef SCANLIGHT_GEN_GBUFFER_GLSL
#define SCANLIGHT_GEN_GBUFFER_GLSL
// Render target k of the G-buffer is slot k of the receiver record (gen/receivers.glsl):
{slots}
#ifdef VERTEX_SHADER
// The asset's vertices (GBUFFER_VERTEX), one attribute per field:
{GBUFFER_VERTEX.glsl_vertex_inputs()}
#endif
#endif
"""


def materials_glsl() -> str:
    """``gen/materials.glsl``: the material table and ``receiver_principled``, the rule that
    assembles a receiver's Disney parameters (TEXTURED_PARAMS from the receiver, the rest from
    its material's row)."""
    args = ",\n        ".join(
        f"receiver_{n}(rid)" if n in TEXTURED_PARAMS else f"material_{n}(m)" for n in ALL_NAMES)
    return f"""{_banner("materials_glsl", "MATERIAL or TEXTURED_PARAMS")}
// The material table: {MATERIAL.slots} vec4 per material, the Disney parameters no texture changes:
{MATERIAL.glsl_comment()}
#ifndef SCANLIGHT_GEN_MATERIALS_GLSL
#define SCANLIGHT_GEN_MATERIALS_GLSL
#include "gen/bindings.glsl"
#include "gen/receivers.glsl"
#include "lib/principled.glsl"
layout(std430, binding = SSBO_MATERIALS) readonly buffer Materials {{ vec4 materials[]; }};
{_ssbo_getters(MATERIAL, "materials", "material_")}

// The Disney parameters of receiver rid - the one rule: {", ".join(TEXTURED_PARAMS)} from the
// receiver (factor x texture, computed by the G-buffer), every other from its material's row.
PrincipledParams receiver_principled(uint rid) {{
    uint m = receiver_material(rid);
    return PrincipledParams(
        {args});
}}
#endif
"""


def walk_state_glsl() -> str:
    """``gen/walk_state.glsl``: the walks' per-receiver resume states, as std430 structs (the
    struct is the SSBO element: its layout is the record's)."""
    for r in (CLASSIC_STATE, FINISH_STATE):
        assert r.std430_struct_ok(), r.name
    return f"""{_banner("walk_state_glsl", "CLASSIC_STATE or FINISH_STATE")}
#ifndef SCANLIGHT_GEN_WALK_STATE_GLSL
#define SCANLIGHT_GEN_WALK_STATE_GLSL
#include "gen/bindings.glsl"
// {CLASSIC_STATE.doc}
{CLASSIC_STATE.glsl_struct()}
// {FINISH_STATE.doc}
{FINISH_STATE.glsl_struct()}
#endif
"""


def _texel_codec(rec: Record, fn: str) -> str:
    return f"{rec.glsl_struct()}\n{rec.glsl_unpack(fn + '_unpack')}\n{rec.glsl_pack(fn + '_pack')}"


def pair_streams_glsl() -> str:
    """``gen/pair_streams.glsl``: the refinement counters and the two streams of Mipmapped /
    Hybrid PBGI (images, MIP_WIDTH texels per row). Define PAIR_STREAMS_READONLY in the
    finishing walk; the refinement declares ``counters[]`` itself (PAIR_COUNTERS)."""
    return f"""{_banner("pair_streams_glsl", "PAIR_COUNTERS, PAIR, ITEM or HEAD")}
// The two streams of Mipmapped/Hybrid PBGI (app/pbgi/mipmapped.py), in images (llvmpipe loads
// image texels as vector gathers, SSBO words with a scalar loop per lane), element g at texel mip_texel(g):
//   pairs ({PAIR.image_format}): the pending (node, pyramid pixel) pairs, a stack;
//   items ({ITEM.image_format}): the second stream, sub-tree roots for the finishing walk;
//   heads ({HEAD.image_format}): per pyramid pixel, the first item of its list or NIL.
#ifndef SCANLIGHT_GEN_PAIR_STREAMS_GLSL
#define SCANLIGHT_GEN_PAIR_STREAMS_GLSL
#include "gen/bindings.glsl"
#include "gen/mip.glsl"
// counters[] of the refinement ({PAIR_COUNTERS.words} uints), word indexes:
{PAIR_COUNTERS.glsl_word_defines("C_")}
#define PAIR_COUNTER_WORDS {PAIR_COUNTERS.words}

{_texel_codec(PAIR, "pair")}
{_texel_codec(ITEM, "item")}
#ifdef PAIR_STREAMS_READONLY
layout({ITEM.image_format}, binding = IMG_ITEMS) uniform readonly uimage2D items_img;
layout({HEAD.image_format}, binding = IMG_HEADS) uniform readonly uimage2D heads_img;
Item item_load(uint i) {{ return item_unpack(imageLoad(items_img, mip_texel(i))); }}
uint head_load(uint pixel) {{ return imageLoad(heads_img, mip_texel(pixel)).x; }}
#else
layout({PAIR.image_format}, binding = IMG_PAIRS) uniform uimage2D pairs_img;
layout({ITEM.image_format}, binding = IMG_ITEMS) uniform writeonly uimage2D items_img;
layout({HEAD.image_format}, binding = IMG_HEADS) uniform uimage2D heads_img;
Pair pair_load(uint i) {{ return pair_unpack(imageLoad(pairs_img, mip_texel(i)).xy); }}
void pair_store(uint i, uint node, uint pixel) {{
    imageStore(pairs_img, mip_texel(i), uvec4(pair_pack(Pair(node, pixel)), 0u, 0u));
}}
void item_store(uint i, Item v) {{ imageStore(items_img, mip_texel(i), item_pack(v)); }}
#endif
#endif
"""


def mip_glsl() -> str:
    """``gen/mip.glsl``: the G-buffer pyramid's images (app/pbgi/gmip.py). Define MIP_WRITABLE
    where the geometry is written (the pyramid build)."""
    return f"""{_banner("mip_glsl", "MIP_SPHERE, MIP_CONE or MIP_LINK")}
// The G-buffer pyramid (app/pbgi/gmip.py), in images (llvmpipe loads image texels as vector
// gathers, SSBO words with a scalar loop per lane). Pixel g lives at texel mip_texel(g) of three images:
//   mip_sphere ({MIP_SPHERE.image_format}):
{MIP_SPHERE.glsl_comment("//     ")}
//   mip_cone ({MIP_CONE.image_format}):
{MIP_CONE.glsl_comment("//     ")}
//   mip_link ({MIP_LINK.image_format}):
{MIP_LINK.glsl_comment("//     ")}
#ifndef SCANLIGHT_GEN_MIP_GLSL
#define SCANLIGHT_GEN_MIP_GLSL
#include "gen/bindings.glsl"
ivec2 mip_texel(uint g) {{ return ivec2(int(g & (MIP_WIDTH - 1u)), int(g >> MIP_WIDTH_LOG2)); }}
#ifdef MIP_WRITABLE
layout({MIP_SPHERE.image_format}, binding = IMG_MIP_SPHERE) uniform image2D mip_sphere_img;
layout({MIP_CONE.image_format}, binding = IMG_MIP_CONE) uniform image2D mip_cone_img;
#else
layout({MIP_SPHERE.image_format}, binding = IMG_MIP_SPHERE) uniform readonly image2D mip_sphere_img;
layout({MIP_CONE.image_format}, binding = IMG_MIP_CONE) uniform readonly image2D mip_cone_img;
#endif
layout({MIP_LINK.image_format}, binding = IMG_MIP_LINK) uniform readonly uimage2D mip_link_img;
{_texel_codec(MIP_SPHERE, "mip_sphere")}
{_texel_codec(MIP_CONE, "mip_cone")}
{_texel_codec(MIP_LINK, "mip_link")}
MipSphere mip_sphere(uint g) {{ return mip_sphere_unpack(imageLoad(mip_sphere_img, mip_texel(g))); }}
MipCone mip_cone(uint g) {{ return mip_cone_unpack(imageLoad(mip_cone_img, mip_texel(g))); }}
MipLink mip_link(uint g) {{ return mip_link_unpack(imageLoad(mip_link_img, mip_texel(g))); }}
#ifdef MIP_WRITABLE
void mip_store(uint g, MipSphere s, MipCone c) {{
    imageStore(mip_sphere_img, mip_texel(g), mip_sphere_pack(s));
    imageStore(mip_cone_img, mip_texel(g), mip_cone_pack(c));
}}
#endif
#endif
"""


def microbuffer_glsl() -> str:
    """``gen/microbuffer.glsl``: the micro-buffer image and its tables (app/pbgi/microbuffer.py
    builds the tables; lib/microbuffer.glsl holds what is done with them)."""
    return f"""{_banner("microbuffer_glsl", "MB_ENTRY, MB_DIRECTION, MB_FLUX or MB_BANDS")}
// The micro-buffers of a batch: image mb_image ({MB_ENTRY.image_format}), row = receiver, texel k = entry k:
{MB_ENTRY.glsl_comment()}
// The entry table mb_table_tex ({MB_DIRECTION.image_format}, E x 1), texel k:
{MB_DIRECTION.glsl_comment()}
// The entry flux mb_flux_tex ({MB_FLUX.image_format}, E x 1; the gather with FRAME_NORMALS), texel k:
{MB_FLUX.glsl_comment()}
// The grid pixel index mb_index_tex ({MB_BANDS.image_format}, (M + 1) x (M + 1)), texel (x, y):
{MB_BANDS.glsl_comment()}
#ifndef SCANLIGHT_GEN_MICROBUFFER_GLSL
#define SCANLIGHT_GEN_MICROBUFFER_GLSL
#include "gen/bindings.glsl"
layout({MB_ENTRY.image_format}, binding = IMG_MB) uniform uimage2D mb_image;
layout(binding = TEX_MB_TABLE) uniform sampler2D mb_table_tex;
layout(binding = TEX_MB_INDEX) uniform usampler2D mb_index_tex;
layout(binding = TEX_MB_FLUX) uniform sampler2D mb_flux_tex;
{_texel_codec(MB_ENTRY, "mb_entry")}
{MB_DIRECTION.glsl_struct()}
{MB_DIRECTION.glsl_unpack("mb_direction_unpack")}
{MB_FLUX.glsl_struct()}
{MB_FLUX.glsl_unpack("mb_flux_unpack")}
{MB_BANDS.glsl_struct()}
{MB_BANDS.glsl_unpack("mb_bands_unpack")}
MbEntry mb_entry_at(ivec2 c) {{ return mb_entry_unpack(imageLoad(mb_image, c).xy); }}
void mb_entry_store(ivec2 c, MbEntry e) {{ imageStore(mb_image, c, uvec4(mb_entry_pack(e), 0u, 0u)); }}
#ifdef LOBE_BUFFER
// The lobe micro-buffers (lib/lobe.glsl): the same texels, micro-pixel k = ring * sectors + sector.
layout({MB_ENTRY.image_format}, binding = IMG_LOBE) uniform uimage2D lobe_image;
MbEntry lobe_entry_at(ivec2 c) {{ return mb_entry_unpack(imageLoad(lobe_image, c).xy); }}
void lobe_entry_store(ivec2 c, MbEntry e) {{ imageStore(lobe_image, c, uvec4(mb_entry_pack(e), 0u, 0u)); }}
#endif
MbDirection mb_table(uint k) {{ return mb_direction_unpack(texelFetch(mb_table_tex, ivec2(int(k), 0), 0)); }}
MbFlux mb_flux(uint k) {{ return mb_flux_unpack(texelFetch(mb_flux_tex, ivec2(int(k), 0), 0)); }}
MbBands mb_bands(uint x, uint y) {{ return mb_bands_unpack(texelFetch(mb_index_tex, ivec2(x, y), 0)); }}
uint mb_entries() {{ return uint(textureSize(mb_table_tex, 0).x); }}   // E: texels per receiver
#endif
"""


def bsh_textures_glsl() -> str:
    """``gen/bsh_textures.glsl``: the node textures (app/pbgi/nodetex.py), built on the GPU by
    shaders/bsh_textures.glsl (which defines BSH_TEX_WRITABLE) from the node records."""
    texs = ((BSH_SPHERE, "sphere", "sampler2D"), (BSH_CONE, "cone", "sampler2D"),
            (BSH_LINK, "link", "usampler2D"), (BSH_COLOR, "color", "sampler2D"))
    doc = "\n".join(f"//   bsh_{n}_tex ({r.image_format}):\n{r.glsl_comment('//     ')}"
                     for r, n, _ in texs)
    samplers = "\n".join(f"layout(binding = TEX_BSH_{n.upper()}) uniform {t} bsh_{n}_tex;"
                          for r, n, t in texs)
    images = "\n".join(f"layout({r.image_format}, binding = IMG_BSH_{n.upper()}) uniform writeonly "
                        f"{'u' if r.word == 'uint' else ''}image2D bsh_{n}_img;" for r, n, _ in texs)
    codecs = "\n".join(_texel_codec(r, f"bsh_{n}") for r, n, _ in texs)
    return f"""{_banner("bsh_textures_glsl", "BSH_SPHERE, BSH_CONE, BSH_LINK or BSH_COLOR")}
// Node i lives at texel bsh_texel(i) = (i % BSH_TEX_WIDTH, i / BSH_TEX_WIDTH) of four textures:
{doc}
#ifndef SCANLIGHT_GEN_BSH_TEXTURES_GLSL
#define SCANLIGHT_GEN_BSH_TEXTURES_GLSL
#include "gen/bindings.glsl"
ivec2 bsh_texel(uint i) {{ return ivec2(i & (BSH_TEX_WIDTH - 1u), i >> BSH_TEX_WIDTH_LOG2); }}
{codecs}
#ifdef BSH_TEX_WRITABLE
{images}
#else
{samplers}
#endif
#endif
"""


def _ssbo_include(fn: str, what: str, rec: Record, block: str, array: str, binding: str,
                  prefix: str) -> str:
    """A readonly SSBO of ``rec`` records and one getter per field."""
    guard = f"SCANLIGHT_GEN_{array.upper()}_GLSL"
    elem = rec.slot_type()
    return f"""{_banner(fn, what)}
// {rec.doc}: {rec.slots} {elem} per record in {array}[]:
{rec.glsl_comment()}
#ifndef {guard}
#define {guard}
#include "gen/bindings.glsl"
layout(std430, binding = {binding}) readonly buffer {block} {{ {elem} {array}[]; }};
{_ssbo_getters(rec, array, prefix)}
#endif
"""


def share_rows_glsl() -> str:
    """``gen/share_rows.glsl``: far-field sharing's per-row ball and frame (SHARE_SPLIT walks)."""
    return _ssbo_include("share_rows_glsl", "SHARE_ROW", SHARE_ROW, "ShareRows", "share_rows", "SSBO_SHARE",
                         "share_")


def block_of_glsl() -> str:
    """``gen/block_of.glsl``: far-field sharing's block per batch receiver (the merge)."""
    return _ssbo_include("block_of_glsl", "BLOCK_OF", BLOCK_OF, "BlockOf", "block_of", "SSBO_BLOCK_OF",
                         "share_")


def frames_glsl() -> str:
    """``gen/frames.glsl``: the gather's micro-buffer frame per batch receiver (FRAME_NORMALS)."""
    return _ssbo_include("frames_glsl", "FRAME", FRAME, "Frames", "frames", "SSBO_FRAMES", "frame_")


def gather_output_glsl() -> str:
    """``gen/gather_output.glsl``: the gather's output, one record per tile pixel; with
    GATHER_PARTS defined also its radiance in parts (GATHER_PARTS)."""
    return f"""{_banner("gather_output_glsl", "GATHER_OUTPUT")}
// {GATHER_OUTPUT.doc}, one vec4 per tile pixel (row-major, row 0 at the top):
{GATHER_OUTPUT.glsl_comment()}
#ifndef SCANLIGHT_GEN_GATHER_OUTPUT_GLSL
#define SCANLIGHT_GEN_GATHER_OUTPUT_GLSL
#include "gen/bindings.glsl"
layout(std430, binding = SSBO_OUTPUT) buffer Output {{ vec4 out_rgba[]; }};
{GATHER_OUTPUT.glsl_struct()}
{GATHER_OUTPUT.glsl_pack("gather_output_pack")}
void gather_output_store(uint pixel, GatherOutput v) {{ out_rgba[pixel] = gather_output_pack(v); }}
#ifdef GATHER_PARTS
// {GATHER_PARTS.doc}, {GATHER_PARTS.slots} vec4s per tile pixel:
{GATHER_PARTS.glsl_comment()}
layout(std430, binding = SSBO_PARTS) buffer Parts {{ vec4 parts_rgba[]; }};
{GATHER_PARTS.glsl_struct()}
{GATHER_PARTS.glsl_pack("gather_parts_pack")}
void gather_parts_store(uint pixel, GatherParts v) {{
    vec4 {", ".join(f"s{k}" for k in range(GATHER_PARTS.slots))};
    gather_parts_pack(v, {", ".join(f"s{k}" for k in range(GATHER_PARTS.slots))});
    uint b = {GATHER_PARTS.slots}u * pixel;
{chr(10).join(f"    parts_rgba[b + {k}u] = s{k};" for k in range(GATHER_PARTS.slots))}
}}
#endif
#endif
"""


GENERATED = {
    "gen/bindings.glsl": bindings_glsl,
    "gen/receivers.glsl": receivers_glsl,
    "gen/gbuffer.glsl": gbuffer_glsl,
    "gen/materials.glsl": materials_glsl,
    "gen/walk_state.glsl": walk_state_glsl,
    "gen/pair_streams.glsl": pair_streams_glsl,
    "gen/mip.glsl": mip_glsl,
    "gen/microbuffer.glsl": microbuffer_glsl,
    "gen/bsh_textures.glsl": bsh_textures_glsl,
    "gen/share_rows.glsl": share_rows_glsl,
    "gen/block_of.glsl": block_of_glsl,
    "gen/frames.glsl": frames_glsl,
    "gen/gather_output.glsl": gather_output_glsl,
}
