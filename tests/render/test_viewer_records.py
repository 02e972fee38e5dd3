"""Every CPU<->GPU record of app/render/gpu_layout.py (the viewer's passes and the point
splatter) means the same on both sides: records packed through the numpy dtypes come back bit
for bit through the generated gen/*.glsl code (tests/shaders/viewer_records_check.glsl), and the
real passes write texels that read back through the dtypes. Plus: the units come from one table,
no two active samplers or images of a viewer program share one, and neither the viewer's shaders
nor its Python modules write a binding, location or vertex format as a literal."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from app.render import gpu_layout as G
from app.render.gpu_records import Record
from app.render.programs import (GENERATED_INCLUDES, build_source, load_compute, load_program,
                                 shaders_dir)
from tests.support import TEST_SHADERS

ROOT = Path(__file__).resolve().parents[2]
CHECK = TEST_SHADERS / "viewer_records_check.glsl"


def fields_as_words(rec: Record, records: np.ndarray) -> np.ndarray:
    """(n, words) uint32: the fields in declaration order, each component one word."""
    return np.concatenate([np.ascontiguousarray(records[f.name]).view(np.uint32)
                           .reshape(len(records), -1) for f in rec.fields], axis=1)


def random_records(rec: Record, n: int, rng) -> np.ndarray:
    """``n`` records, every (float) field from a normal distribution: no NaN, no subnormal."""
    out = rec.zeros(n)
    for f in rec.fields:
        out[f.name] = rng.normal(0.0, 10.0, out[f.name].shape).astype(np.float32)
    return out


def texture(ctx, rec: Record, records: np.ndarray, size):
    return ctx.texture(size, rec.texel_components, records.tobytes(), dtype=rec.texture_dtype)


# -- round trips through the generated code -------------------------------------------------------

def test_texel_records_decode_through_the_composite_include(ctx):
    """room_at, guide_at and gi_at read the viewer's texel records on the viewer's own units
    (VIEW_TEX) and composite_store writes COMPOSITE_TEXEL on VIEW_IMG.LINEAR."""
    rng = np.random.default_rng(11)
    w, h = 37, 23
    n = w * h
    recs = {name: random_records(rec, n, rng) for name, rec in
            (("room", G.ROOM_TEXEL), ("guide", G.GUIDE_TEXEL), ("preview", G.GI_TEXEL),
             ("full", G.GI_TEXEL))}
    texs = [texture(ctx, G.ROOM_TEXEL, recs["room"], (w, h)),
            texture(ctx, G.GUIDE_TEXEL, recs["guide"], (w, h)),
            texture(ctx, G.GI_TEXEL, recs["preview"], (w, h)),
            texture(ctx, G.GI_TEXEL, recs["full"], (w, h))]
    for tex, unit in zip(texs, (G.VIEW_TEX.ROOM, G.VIEW_TEX.GBUF, G.VIEW_TEX.PREVIEW,
                                G.VIEW_TEX.FULL)):
        tex.use(location=unit)
    linear = ctx.texture((w, h), G.COMPOSITE_TEXEL.texel_components,
                         dtype=G.COMPOSITE_TEXEL.texture_dtype)
    linear.bind_to_image(G.VIEW_IMG.LINEAR, read=False, write=True)
    out = ctx.buffer(reserve=16 * 4 * n)
    out.bind_to_storage_buffer(0)
    prog = load_compute(ctx, CHECK, {"MODE": 0})
    prog["u_count"], prog["u_width"] = n, w
    prog.run((n + 63) // 64)
    ctx.memory_barrier()
    got = np.frombuffer(out.read(), np.uint32).reshape(n, 16)
    expect = np.concatenate([fields_as_words(G.ROOM_TEXEL, recs["room"]),
                             fields_as_words(G.GUIDE_TEXEL, recs["guide"]),
                             fields_as_words(G.GI_TEXEL, recs["preview"]),
                             fields_as_words(G.GI_TEXEL, recs["full"])], axis=1)
    np.testing.assert_array_equal(got, expect)
    back = G.COMPOSITE_TEXEL.view(linear.read())
    np.testing.assert_array_equal(back["radiance"], recs["guide"]["normal"])
    np.testing.assert_array_equal(back["asset"], recs["room"]["coverage"])
    for obj in texs + [linear, out, prog]:
        obj.release()


@pytest.mark.parametrize("mode,rec", [(1, G.SPLAT_VERTEX), (2, G.VIEWER_VERTEX)])
def test_vertex_records_reach_the_vertex_stage(ctx, mode, rec):
    """One buffer per field, bound by Record.vertex_content as the viewer binds them: the vertex
    stage sees every field at its generated location (transform feedback copies them out)."""
    import moderngl
    rng = np.random.default_rng(12 + mode)
    n = 500
    recs = random_records(rec, n, rng)
    names = [f.name for f in rec.fields]
    prog = load_program(ctx, CHECK, {"MODE": mode}, stages=("VERTEX_SHADER",),
                        varyings=[f"o_{f}" for f in names])
    for k, f in enumerate(names):
        assert prog[f"in_{f}"].location == k
    bufs = {f: ctx.buffer(rec.field_array(f, recs[f]).tobytes()) for f in names}
    vao = ctx.vertex_array(prog, rec.vertex_content(bufs))
    out = ctx.buffer(reserve=rec.nbytes * n)
    vao.transform(out, mode=moderngl.POINTS, vertices=n)
    got = np.frombuffer(out.read(), np.uint32).reshape(n, rec.words)
    np.testing.assert_array_equal(got, fields_as_words(rec, recs))
    for obj in [vao, out, prog, *bufs.values()]:
        obj.release()


def test_splat_pass_writes_room_texels(ctx):
    """The real splat pass: covered pixels read back as ROOM_TEXEL(colour x scale, 1), the
    others stay cleared (coverage 0)."""
    from app.camera import Camera
    from app.cloud import PointCloud
    from app.render.splat import SplatRenderer
    pos = np.array([[-0.5, 0.0, 0.0], [0.5, 0.0, 0.0], [0.0, 0.5, 0.0]])
    colors = np.array([[0.25, 0.5, 1.0], [2.0, 0.125, 0.0], [0.75, 0.75, 4.0]], np.float32)
    cloud = PointCloud(pos, np.tile([0.0, 0.0, 1.0], (3, 1)), colors)
    cam = Camera((0.0, 0.0, 3.0), (0.0, 0.0, 0.0), fov_y_deg=40.0, width=64, height=48)
    splat = SplatRenderer(cloud, radius=0.08, ctx=ctx)
    img = G.ROOM_TEXEL.view(splat.render(cam, scale=2.0))
    splat.release()
    covered = img["coverage"] > 0
    assert covered.sum() > 20
    np.testing.assert_array_equal(img["coverage"][covered], 1.0)
    # the splats are blended (sum w c / sum w): each covered pixel is one point's colour to
    # float rounding (the points' discs do not overlap), and every point shows
    want = colors * np.float32(2.0)
    err = np.abs(img["radiance"][covered][:, None, :] - want[None]).max(axis=2)
    assert err.min(axis=1).max() <= 1e-6 * want.max()
    assert set(err.argmin(axis=1)) == {0, 1, 2}
    np.testing.assert_array_equal(img["radiance"][~covered], 0.0)


def test_gbuffer_pass_writes_guide_texels(ctx):
    """The real G-buffer pass: a quad facing the camera reads back as GUIDE_TEXEL(its normal,
    its eye depth); pixels off the asset stay at depth 0."""
    from app.camera import Camera
    from app.io.mesh import Mesh
    from app.material import Material
    from app.ui.viewport import ViewportRenderer
    quad = Mesh(positions=[[-0.5, -0.5, 0.0], [0.5, -0.5, 0.0], [0.5, 0.5, 0.0], [-0.5, 0.5, 0.0]],
                normals=np.tile([0.0, 0.0, 1.0], (4, 1)), uvs=None,
                tangents=np.tile([1.0, 0.0, 0.0, 1.0], (4, 1)), indices=[[0, 1, 2], [0, 2, 3]],
                material_ids=[0, 0], materials=[Material()])
    view = ViewportRenderer(ctx)
    view.resize(40, 30)
    view.set_asset(quad)
    view.draw_gbuffer(Camera((0.0, 0.0, 3.0), (0.0, 0.0, 0.0), fov_y_deg=40.0, width=40,
                             height=30))
    from app.render.context import bind_anchor
    bind_anchor()
    gbuf = G.GUIDE_TEXEL.view(view.read_inputs()["gbuf"])
    view.release()
    on = gbuf["depth"] > 0
    assert 50 < on.sum() < 40 * 30
    np.testing.assert_array_equal(gbuf["normal"][on], np.tile([0.0, 0.0, 1.0], (on.sum(), 1)))
    np.testing.assert_allclose(gbuf["depth"][on], 3.0, rtol=1e-5)
    np.testing.assert_array_equal(gbuf["normal"][~on], 0.0)


# -- one table for the numbers ---------------------------------------------------------------------

def test_generated_defines_carry_every_number():
    text = G.composite_glsl()
    for units in (G.VIEW_TEX, G.VIEW_IMG):
        for name, value in units.items():
            assert re.search(rf"^#define {units.prefix}{name}\s+{value}\b", text, re.M), name
            kind = "sampler2D" if units is G.VIEW_TEX else "image2D"
            assert re.search(rf"binding = {units.prefix}{name}\).*uniform {kind} "
                             rf"u_{name.lower()};", text), name
    assert f"#define VIEW_TILE {G.COMPOSITE_TILE}" in text
    for fn, rec in ((G.splat_glsl, G.SPLAT_VERTEX), (G.gbuffer_glsl, G.VIEWER_VERTEX)):
        src = fn()
        for k, f in enumerate(rec.fields):
            assert f"layout(location = {k}) in {f.type} in_{f.name};" in src
        assert f"layout(location = {G.COLOR_TARGET}) out vec4" in src


COMPOSITE_PROGRAMS = [{}, {"ASSET_PASS": 1}, {"LABEL_PASS": 1}]
_UNIFORM_DECL = re.compile(r"layout\([^)]*binding\s*=\s*(\w+)\)\s*(?:writeonly\s+|readonly\s+)*"
                           r"uniform\s+(?:writeonly\s+|readonly\s+)*(\w+)\s+(\w+)\s*;")


@pytest.mark.parametrize("defines", COMPOSITE_PROGRAMS)
def test_active_units_are_distinct_and_from_the_table(ctx, defines):
    """In each compiled composite program every active sampler and image takes its binding
    from VIEW_TEX / VIEW_IMG (by name, and GL reports that unit), and no two share one."""
    values = {u.define(n): (kind, v) for kind, u in (("sampler", G.VIEW_TEX),
                                                      ("image", G.VIEW_IMG)) for n, v in u.items()}
    text, _ = build_source("viewer_composite.glsl", "COMPUTE_SHADER", defines)
    decl = {m.group(3): (m.group(1), m.group(2)) for m in _UNIFORM_DECL.finditer(text)}
    prog = load_compute(ctx, "viewer_composite.glsl", defines or None)
    seen: dict[tuple[str, int], str] = {}
    for member in prog:
        if member not in decl:
            continue
        binding, gl_type = decl[member]
        key = values[binding]                      # KeyError: a binding not from the table
        assert key[0] == ("image" if "image" in gl_type else "sampler"), member
        assert prog[member].value == key[1], member
        assert key not in seen, (defines, member, seen[key])
        seen[key] = member
    assert seen                                     # the passes do read textures
    prog.release()


def test_no_number_is_written_by_hand():
    """The viewer's shaders take every binding, location and work-group size from the generated
    includes; its Python modules bind units and build vertex formats from gpu_layout."""
    for name in ("splat.glsl", "splat_resolve.glsl", "viewer_composite.glsl",
                 "viewer_gbuffer.glsl"):
        text = (shaders_dir() / name).read_text()
        assert not re.search(r"(binding|location)\s*=\s*\d", text), name
        assert not re.search(r"local_size_\w\s*=\s*\d", text), name
    paths = [ROOT / "app" / "ui" / n for n in ("viewport.py", "composite.py", "refine.py")]
    paths += [p for p in sorted((ROOT / "app" / "render").glob("*.py"))
              if p.name not in ("gpu_records.py", "gpu_layout.py")]     # where numbers live
    for path in paths:
        text = path.read_text()
        assert not re.search(r"\.use\((location=)?\d|bind_to_image\(\d|bind_to_storage_buffer\(\d",
                             text), path
        assert not re.search(r"""["']\d[fiu]\d?["']""", text), path      # "3f" vertex formats


def test_every_generated_include_is_registered_and_self_contained(ctx, tmp_path):
    """Registered in programs.GENERATED_INCLUDES, marked as generated, and each compiles alone,
    in a compute shader and in a vertex + fragment program (it includes what it needs)."""
    for name, fn in G.GENERATED.items():
        assert GENERATED_INCLUDES[name] == f"app.render.gpu_layout:{fn.__name__}"
        assert fn().startswith("// GENERATED by app/render/gpu_layout.py"), name
        cs = tmp_path / f"cs_{name.replace('/', '_')}"
        cs.write_text(f'#include "{name}"\nlayout(local_size_x = 1) in;\nvoid main() {{}}\n')
        load_compute(ctx, cs).release()
        vf = tmp_path / f"vf_{name.replace('/', '_')}"
        vf.write_text(f'#include "{name}"\n#ifdef VERTEX_SHADER\n'
                      "void main() { gl_Position = vec4(0.0); }\n#endif\n"
                      "#ifdef FRAGMENT_SHADER\nvoid main() {}\n#endif\n")
        load_program(ctx, vf).release()


def test_every_record_is_checked_here():
    """Each record of gpu_layout.RECORDS goes through one of the GPU round trips above."""
    checked = {G.ROOM_TEXEL, G.GUIDE_TEXEL, G.GI_TEXEL, G.COMPOSITE_TEXEL, G.SPLAT_VERTEX,
               G.VIEWER_VERTEX}
    assert set(G.RECORDS.values()) == checked
    assert set(G.TEXELS.values()) <= checked


def test_field_array_and_vertex_content():
    rec = G.SPLAT_VERTEX
    a = rec.field_array("color", np.ones((5, 3), np.float64))
    assert a.dtype == np.float32 and a.shape == (5, 3) and a.flags.c_contiguous
    with pytest.raises(ValueError):
        rec.field_array("color", np.ones((5, 4)))
    assert [(fmt, attr) for _, fmt, attr in rec.vertex_content(
        {"position": 1, "color": 2, "normal": 3, "radius": 4})] \
        == [("3f", "in_position"), ("3f", "in_color"), ("3f", "in_normal"), ("1f", "in_radius")]
    with pytest.raises(ValueError):
        rec.vertex_content({"position": 1})
