"""Every record and number the viewer's passes and the point splatter share between Python and
GLSL, declared once (the PBGI passes have theirs in app/pbgi/gpu_layout.py, same helper:
app/render/gpu_records.py).

The passes (app/ui/viewport.py drives them; app/render/splat.py draws the room):

* splat.glsl draws the room cloud (``SPLAT_VERTEX``) as oriented discs (a depth pass, then an
  accumulation pass), splat_resolve.glsl normalises, fills small holes (push-pull) and shades
  (eye-dome lighting) into an RGBA32F target of ``ROOM_TEXEL``;
* viewer_gbuffer.glsl rasterises the asset (``VIEWER_VERTEX``) into ``GUIDE_TEXEL``;
* viewer_composite.glsl reads those, the room's depth, the two GI images of app/ui/refine.py
  (``GI_TEXEL``) and a label, on the texture units ``VIEW_TEX``, and writes the linear composite
  (``COMPOSITE_TEXEL``) and the display image on the image units ``VIEW_IMG``, in work groups of
  ``COMPOSITE_TILE`` x ``COMPOSITE_TILE`` pixels.

Python binds, packs and reads through these names; the shaders get the same numbers, vertex
inputs, fragment outputs and texel codecs from the generated includes below (registered in
app/render/programs.py). tests/render/test_viewer_records.py decodes each record on the GPU.
The 8-bit images (display, label) are plain sRGB colour with alpha, not records of 32-bit words.
"""

from __future__ import annotations

from app.render.gpu_records import Field, Record, Units

# -- binding points and units ---------------------------------------------------------------------
VIEW_TEX = Units("texture units of viewer_composite.glsl: layout(binding = VIEW_TEX_X) uniform "
                 "sampler2D u_x, Texture.use(location)", "VIEW_TEX_", {
                     "ROOM": (0, "the room's splats (ROOM_TEXEL)"),
                     "ROOM_DEPTH": (1, "window depth of the room's splats (depth texture)"),
                     "GBUF": (2, "the asset's G-buffer (GUIDE_TEXEL)"),
                     "PREVIEW": (3, "reduced-resolution GI (GI_TEXEL)"),
                     "FULL": (4, "layer-resolution GI, tile by tile (GI_TEXEL)"),
                     "LABEL": (5, "RGBA8 text image shown over the asset"),
                 })
VIEW_IMG = Units("image units of viewer_composite.glsl: layout(format, binding = VIEW_IMG_X) "
                 "uniform image2D u_x, bind_to_image", "VIEW_IMG_", {
                     "LINEAR": (0, "the linear composite (COMPOSITE_TEXEL)"),
                     "DISPLAY": (1, "the display image (RGBA8 sRGB)"),
                 })
SPLAT_TEX = Units("texture units of splat.glsl: layout(binding = SPLAT_TEX_X) uniform sampler2D "
                  "u_x, Texture.use(location)", "SPLAT_TEX_", {
                      "FRONT": (0, "window depth of the depth pass (the accumulation pass "
                                   "reads it)"),
                  })
SPLAT_IMG = Units("image units of splat_resolve.glsl: layout(format, binding = SPLAT_IMG_X) "
                  "uniform image2D u_x, bind_to_image", "SPLAT_IMG_", {
                      "SRC": (0, "read: the sums (normalise), level l (pull), level l+1 (push), "
                                 "filled level 0 (finish)"),
                      "AUX": (1, "read: sum of weight x depth (normalise), level l (push)"),
                      "DST": (2, "written: a level, or the ROOM_TEXEL image (finish)"),
                  })
SPLAT_RESOLVE_TILE = 8        # splat_resolve.glsl's work group: TILE x TILE pixels
DEPTH_SUM_TARGET = 1          # splat.glsl's accumulation pass: second output, sum of w x depth
COMPOSITE_TILE = 8            # viewer_composite.glsl's work group: TILE x TILE pixels
DISPLAY_FORMAT = "rgba8"      # image format of the display image (and of the label texture)
COLOR_TARGET = 0              # fragment output location: each pass's only colour attachment

# -- vertices -------------------------------------------------------------------------------------
# One buffer per field: the viewer swaps the room's colours (LDR, HDR, difference) without
# uploading its positions again.
SPLAT_VERTEX = Record("SplatVertex", (
    Field("position", "vec3", "relative to the cloud's origin (float64 shift on the CPU)"),
    Field("color", "vec3", "linear radiance of the point"),
    Field("normal", "vec3", "unit normal: the splat is a disc in the plane it spans"),
    Field("radius", "float", "disc radius relative to the renderer's global radius (local "
          "point spacing / median spacing, clamped)"),
), word="float", slot_words=1, doc="a point of the room cloud (splat.glsl)")

VIEWER_VERTEX = Record("ViewerVertex", (
    Field("position", "vec3", "relative to the asset's origin (float64 shift on the CPU)"),
    Field("normal", "vec3", "vertex normal, world space"),
), word="float", slot_words=1, doc="a vertex of the placed asset (viewer_gbuffer.glsl)")

# -- texels (RGBA32F, GL orientation: row 0 at the bottom) ----------------------------------------
ROOM_TEXEL = Record("RoomTexel", (
    Field("radiance", "vec3", "linear radiance x the splat scale"),
    Field("coverage", "float", "1 where a splat covers the pixel, 0 where none landed"),
), word="float", doc="splat.glsl's output: the room")

GUIDE_TEXEL = Record("GuideTexel", (
    Field("normal", "vec3", "unit normal of the asset, world space"),
    Field("depth", "float", "eye depth along -z in metres; 0: no asset (the cleared value)"),
), word="float", doc="viewer_gbuffer.glsl's output: the guide of the bilateral upsampling")

GI_PENDING = -1.0             # GI_TEXEL.status of a pixel no tile has rendered yet
GI_TEXEL = Record("GiTexel", (
    Field("radiance", "vec3", "outgoing linear radiance of the relit asset"),
    Field("status", "float", "1: asset, 0: background, < 0 (GI_PENDING): not rendered yet"),
), word="float", doc="a pixel of the preview or full GI image (app/ui/refine.py)")

COMPOSITE_TEXEL = Record("CompositeTexel", (
    Field("radiance", "vec3", "linear radiance shown (room, background or asset)"),
    Field("asset", "float", "1 where the asset is shown, else 0"),
), word="float", doc="viewer_composite.glsl's linear output (EXR screenshots, the twin's tests)")

RECORDS = {r.name: r for r in (SPLAT_VERTEX, VIEWER_VERTEX, ROOM_TEXEL, GUIDE_TEXEL, GI_TEXEL,
                               COMPOSITE_TEXEL)}
TEXELS = {"room_texel": ROOM_TEXEL, "guide_texel": GUIDE_TEXEL, "gi_texel": GI_TEXEL,
          "composite_texel": COMPOSITE_TEXEL}     # GLSL function prefix -> record


# -- generated GLSL -------------------------------------------------------------------------------
def _head(fn: str, what: str, guard: str) -> str:
    return (f"// GENERATED by app/render/gpu_layout.py:{fn}() - do not edit; change {what} "
            f"there.\n#ifndef {guard}\n#define {guard}")


def texels_glsl() -> str:
    """``gen/viewer_texels.glsl``: the texel records as structs, ``*_unpack(vec4)`` and
    ``*_pack(struct)``."""
    parts = []
    for fn, rec in TEXELS.items():
        parts.append(f"// {rec.doc} ({rec.image_format}):\n{rec.glsl_comment()}\n"
                     f"{rec.glsl_struct()}\n{rec.glsl_unpack(fn + '_unpack')}\n"
                     f"{rec.glsl_pack(fn + '_pack')}")
    body = "\n".join(parts)
    return f"""{_head("texels_glsl", "the *_TEXEL records", "SCANLIGHT_GEN_VIEWER_TEXELS_GLSL")}
{body}
#endif
"""


def _vertex_pass(fn: str, what: str, guard: str, vertex: Record, texel: Record, fn_prefix: str,
                 output: str) -> str:
    """A raster pass's vertex inputs (vertex stage) and its one colour output (fragment stage)."""
    return f"""{_head(fn, what, guard)}
#include "gen/viewer_texels.glsl"
#ifdef VERTEX_SHADER
// {vertex.doc}, one buffer per field:
{vertex.glsl_vertex_inputs()}
#endif
#ifdef FRAGMENT_SHADER
// the colour attachment: {fn_prefix}_pack({texel.name}(...))
layout(location = {COLOR_TARGET}) out vec4 {output};
#endif
#endif
"""


def splat_glsl() -> str:
    """``gen/splat.glsl``: splat.glsl's vertex inputs (SPLAT_VERTEX), outputs (ROOM_TEXEL; the
    accumulation pass's sum of weight x depth) and texture units (SPLAT_TEX)."""
    body = _vertex_pass("splat_glsl", "SPLAT_VERTEX, ROOM_TEXEL, SPLAT_TEX or DEPTH_SUM_TARGET",
                        "SCANLIGHT_GEN_SPLAT_GLSL", SPLAT_VERTEX, ROOM_TEXEL, "room_texel",
                        "out_room")
    extra = (f"{SPLAT_TEX.glsl()}\n#ifdef FRAGMENT_SHADER\n// the accumulation pass's sum of "
             f"weight x eye depth\nlayout(location = {DEPTH_SUM_TARGET}) out float "
             f"out_depth_sum;\n#endif\n#endif\n")
    return body[:body.rindex("#endif")] + extra


def splat_resolve_glsl() -> str:
    """``gen/splat_resolve.glsl``: splat_resolve.glsl's image units (SPLAT_IMG), work group and
    the ROOM_TEXEL codec."""
    return f"""{_head("splat_resolve_glsl", "SPLAT_IMG or SPLAT_RESOLVE_TILE",
                      "SCANLIGHT_GEN_SPLAT_RESOLVE_GLSL")}
{SPLAT_IMG.glsl()}
#define SPLAT_TILE {SPLAT_RESOLVE_TILE}   // work group: SPLAT_TILE x SPLAT_TILE pixels
#include "gen/viewer_texels.glsl"
#endif
"""


def gbuffer_glsl() -> str:
    """``gen/viewer_gbuffer.glsl``: viewer_gbuffer.glsl's vertex inputs (VIEWER_VERTEX) and
    output (GUIDE_TEXEL)."""
    return _vertex_pass("gbuffer_glsl", "VIEWER_VERTEX or GUIDE_TEXEL",
                        "SCANLIGHT_GEN_VIEWER_GBUFFER_GLSL", VIEWER_VERTEX, GUIDE_TEXEL,
                        "guide_texel", "out_guide")


def composite_glsl() -> str:
    """``gen/viewer_composite.glsl``: viewer_composite.glsl's units, samplers, images, work-group
    size and texel accessors. Define VIEW_DISPLAY_READABLE where the display image is read (the
    label pass blends over it)."""
    samplers = "\n".join(f"layout(binding = {VIEW_TEX.define(n)}) uniform sampler2D "
                         f"u_{n.lower()};" for n, _ in VIEW_TEX.items())
    linear = (f"layout({COMPOSITE_TEXEL.image_format}, binding = {VIEW_IMG.define('LINEAR')}) "
              f"writeonly uniform image2D u_linear;")
    display = f"layout({DISPLAY_FORMAT}, binding = {VIEW_IMG.define('DISPLAY')})"
    return f"""{_head("composite_glsl", "VIEW_TEX, VIEW_IMG, COMPOSITE_TILE or the texels",
                      "SCANLIGHT_GEN_VIEWER_COMPOSITE_GLSL")}
{VIEW_TEX.glsl()}

{VIEW_IMG.glsl()}

#define VIEW_TILE {COMPOSITE_TILE}   // work group: VIEW_TILE x VIEW_TILE pixels
#include "gen/viewer_texels.glsl"
// u_x: the texture on unit VIEW_TEX_X (see above)
{samplers}
{linear}
#ifdef VIEW_DISPLAY_READABLE
{display} uniform image2D u_display;
#else
{display} writeonly uniform image2D u_display;
#endif
RoomTexel room_at(ivec2 p) {{ return room_texel_unpack(texelFetch(u_room, p, 0)); }}
GuideTexel guide_at(ivec2 p) {{ return guide_texel_unpack(texelFetch(u_gbuf, p, 0)); }}
GiTexel gi_at(sampler2D tex, ivec2 p) {{ return gi_texel_unpack(texelFetch(tex, p, 0)); }}
void composite_store(ivec2 p, CompositeTexel v) {{ imageStore(u_linear, p, composite_texel_pack(v)); }}
#endif
"""


GENERATED = {
    "gen/viewer_texels.glsl": texels_glsl,
    "gen/splat.glsl": splat_glsl,
    "gen/splat_resolve.glsl": splat_resolve_glsl,
    "gen/viewer_gbuffer.glsl": gbuffer_glsl,
    "gen/viewer_composite.glsl": composite_glsl,
}
