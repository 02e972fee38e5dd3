"""Every CPU<->GPU record of app/pbgi/gpu_layout.py means the same on both sides: records packed
through the numpy dtypes are decoded on the GPU by the generated gen/*.glsl code the renderer
uses (tests/shaders/gpu_records_check.glsl) and come back bit for bit; records the GPU writes
are read back through the dtypes. Plus: binding points, units and widths come from one table,
and no production shader or PBGI module writes one as a literal."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from app.material import Material, SCALAR_NAMES
from app.pbgi import gpu_layout as G
from app.pbgi import layout
from app.pbgi.brdf import PARAM_NAMES, pack_params
from app.render.gpu_records import Field, Pad, Record
from app.render.programs import GENERATED_INCLUDES, build_source, load_compute, shaders_dir
from tests.support import TEST_SHADERS

ROOT = Path(__file__).resolve().parents[2]
OUT_BINDING = 10          # the test shader's output buffer
MODES = {"receiver": 0, "principled": 1, "classic_state": 2, "finish_state": 3, "counters": 4,
         "streams": 5, "streams_read": 6, "mip": 7, "microbuffer": 8, "share_rows": 9,
         "block_of": 10, "frames": 11, "gather_output": 12, "node_textures": 13,
         "gather_parts": 14}


def decoded_words(rec: Record, records: np.ndarray) -> np.ndarray:
    """What the test shader writes per record: the fields in order, every component one 32-bit
    word (a float-value field as its integer)."""
    cols = []
    for f in rec.fields:
        v = np.ascontiguousarray(records[f.name])
        if f.stored_as == "value":
            v = (v + np.float32(0.5)).astype(np.uint32)
        cols.append(v.view(np.uint32).reshape(len(records), -1))
    return np.concatenate(cols, axis=1)


def random_records(rec: Record, n: int, rng, value_max: int = 1) -> np.ndarray:
    """``n`` records with random fields: floats from a normal distribution (never NaN or
    subnormal), uints over the full 32 bits, float-value ids in [0, value_max)."""
    out = rec.zeros(n)
    for f in rec.fields:
        shape = out[f.name].shape
        if f.stored_as == "value":
            out[f.name] = rng.integers(0, value_max, shape).astype(np.float32)
        elif f.base == "float":
            out[f.name] = rng.normal(0.0, 10.0, shape).astype(np.float32)
        else:
            out[f.name] = rng.integers(0, 2**32, shape, dtype=np.uint64).astype(np.uint32)
    return out


@pytest.fixture(scope="module")
def progs(ctx):
    cache = {}

    def get(mode: str):
        if mode not in cache:
            cache[mode] = load_compute(ctx, TEST_SHADERS / "gpu_records_check.glsl",
                                       {"MODE": MODES[mode]})
        return cache[mode]
    yield get
    for p in cache.values():
        p.release()


def run(ctx, prog, count: int, words: int, **uniforms) -> np.ndarray:
    """Dispatch one invocation per record; (count, words) uint32 of what they wrote."""
    out = ctx.buffer(reserve=max(4 * count * words, 4))
    out.bind_to_storage_buffer(OUT_BINDING)
    prog["u_count"] = count
    if "u_words" in prog:
        prog["u_words"] = words
    for k, v in uniforms.items():
        prog[k] = v
    prog.run(G.dispatch_groups(count))
    ctx.memory_barrier()
    got = np.frombuffer(out.read(), np.uint32)[:count * words].reshape(count, words).copy()
    out.release()
    return got


def ssbo(ctx, records: np.ndarray, binding: int):
    buf = ctx.buffer(np.ascontiguousarray(records).tobytes())
    buf.bind_to_storage_buffer(binding)
    return buf


def image(ctx, rec: Record, records: np.ndarray, unit: int, width: int = G.MIP_WIDTH, rows=1):
    """A width x rows texture of ``rec`` texels holding ``records`` (row-major), bound as an
    image on ``unit``."""
    data = rec.zeros(width * rows)
    data[:len(records)] = records
    tex = ctx.texture((width, rows), rec.texel_components, data.tobytes(),
                      dtype=rec.texture_dtype)
    tex.bind_to_image(unit, read=True, write=True)
    return tex


def test_receiver_record_decodes_on_the_gpu(ctx, progs):
    rng = np.random.default_rng(1)
    rec = random_records(G.RECEIVER, 300, rng, value_max=7)
    rec["pixel"] = rng.integers(0, 4096 * 4096, 300)        # real pixels: subnormal bit patterns
    buf = ssbo(ctx, rec, G.SSBO.RECEIVERS)
    got = run(ctx, progs("receiver"), 300, 16)
    np.testing.assert_array_equal(got, decoded_words(G.RECEIVER, rec))
    buf.release()


def test_receiver_slots_are_the_gbuffer_targets():
    """Slot k of a receiver is render target k: the G-buffer compaction copies the targets whole,
    and gbuffer.glsl takes its output locations from the generated RECEIVER_SLOT_* defines."""
    from app.pbgi.gbuffer import RECEIVER_FLOATS, TARGETS
    assert (TARGETS, RECEIVER_FLOATS) == (G.RECEIVER.slots, G.RECEIVER.words)
    text = G.gbuffer_glsl()
    for f in G.RECEIVER.fields:
        assert f"#define RECEIVER_SLOT_{f.name.upper()} {G.RECEIVER.slot(f.name)}" in text
    src = (shaders_dir() / "gbuffer.glsl").read_text()
    assert len(re.findall(r"layout\(location = RECEIVER_SLOT_\w+\) out vec4", src)) == TARGETS


def test_material_rule_on_the_gpu_matches_numpy(ctx, progs):
    """receiver_principled: base colour, metallic and roughness from the receiver, every other
    parameter from its material's row - the same 13 numbers as gpu_layout.principled_params."""
    rng = np.random.default_rng(2)
    mats = [Material(**{n: float(rng.random()) for n in SCALAR_NAMES},
                     base_color=tuple(rng.random(3))) for _ in range(5)]
    table = G.material_rows(mats)
    rec = random_records(G.RECEIVER, 200, rng, value_max=len(mats))
    bufs = [ssbo(ctx, rec, G.SSBO.RECEIVERS), ssbo(ctx, table, G.SSBO.MATERIALS)]
    got = run(ctx, progs("principled"), 200, len(PARAM_NAMES))
    expect = G.principled_params(rec, table).astype(np.float32)
    np.testing.assert_array_equal(got, expect.view(np.uint32))
    # the rule in words: the receiver's textured values win, the table holds only the others
    mid = (rec["material"] + 0.5).astype(int)
    table_params = np.array([pack_params(m) for m in mats], np.float32)[mid]
    textured = np.zeros(len(PARAM_NAMES), bool)
    textured[[0, 1, 2, PARAM_NAMES.index("metallic"), PARAM_NAMES.index("roughness")]] = True
    np.testing.assert_array_equal(expect[:, ~textured], table_params[:, ~textured])
    np.testing.assert_array_equal(expect[:, 0:3], rec["base_color"])
    np.testing.assert_array_equal(expect[:, PARAM_NAMES.index("roughness")], rec["roughness"])
    assert not set(G.TEXTURED_PARAMS) & {f.name for f in G.MATERIAL.fields}
    for b in bufs:
        b.release()


@pytest.mark.parametrize("mode,rec", [("classic_state", G.CLASSIC_STATE),
                                      ("finish_state", G.FINISH_STATE)])
def test_walk_states_are_std430_structs(ctx, progs, mode, rec):
    rng = np.random.default_rng(3)
    states = random_records(rec, 150, rng)
    buf = ssbo(ctx, states, G.SSBO.WALK_STATE)
    got = run(ctx, progs(mode), 150, rec.words)
    np.testing.assert_array_equal(got, decoded_words(rec, states))
    back = rec.view(buf.read())                   # the shader wrote the fields reversed
    names = [f.name for f in rec.fields]
    for a, b in zip(names, reversed(names)):
        np.testing.assert_array_equal(back[a], states[b])
    buf.release()


def test_refinement_counters_by_word(ctx, progs):
    rng = np.random.default_rng(4)
    c = random_records(G.PAIR_COUNTERS, 1, rng)
    buf = ssbo(ctx, c, G.SSBO.COUNTERS)
    fields = decoded_words(G.PAIR_COUNTERS, c)
    got = run(ctx, progs("counters"), 1, fields.shape[1])
    np.testing.assert_array_equal(got, fields)
    from app.pbgi import mipmapped
    assert mipmapped.COUNTER_WORDS == G.PAIR_COUNTERS.words == 32
    assert (mipmapped.C_REFINE_ARGS, mipmapped.C_MOVE_ARGS) == (4, 7)   # indirect offsets
    buf.release()


def test_pair_streams_round_trip(ctx, progs):
    rng = np.random.default_rng(5)
    n = 500
    pairs = random_records(G.PAIR, n, rng)
    items = random_records(G.ITEM, n, rng)
    heads = random_records(G.HEAD, n, rng)
    texs = [image(ctx, G.PAIR, pairs, G.IMAGE.PAIRS), image(ctx, G.ITEM, items, G.IMAGE.ITEMS),
            image(ctx, G.HEAD, heads, G.IMAGE.HEADS)]
    got = run(ctx, progs("streams"), n, 2)
    np.testing.assert_array_equal(got, decoded_words(G.PAIR, pairs))
    back = G.PAIR.view(texs[0].read())[n:2 * n]        # pair_store(n + i, pixel, node)
    np.testing.assert_array_equal(back["node"], pairs["pixel"])
    np.testing.assert_array_equal(back["pixel"], pairs["node"])
    written = G.ITEM.view(texs[1].read())[:n]          # item_store(i, Item(pixel, node, i, ~i))
    np.testing.assert_array_equal(written["node"], pairs["pixel"])
    np.testing.assert_array_equal(written["next"], pairs["node"])
    np.testing.assert_array_equal(written["pixel"], np.arange(n))
    np.testing.assert_array_equal(written["skip"], ~np.arange(n, dtype=np.uint32))
    # the finishing walk's read-only view: item_load, head_load
    texs[1].write(G.ITEM.zeros(G.MIP_WIDTH).tobytes())
    texs[1].write(items.tobytes(), viewport=(0, 0, n, 1))
    got = run(ctx, progs("streams_read"), n, 5)
    np.testing.assert_array_equal(got[:, :4], decoded_words(G.ITEM, items))
    np.testing.assert_array_equal(got[:, 4], heads["item"])
    for t in texs:
        t.release()


def test_pyramid_records_round_trip(ctx, progs):
    rng = np.random.default_rng(6)
    n = 400
    link, sph, cone = (random_records(r, n, rng) for r in (G.MIP_LINK, G.MIP_SPHERE, G.MIP_CONE))
    texs = [image(ctx, G.MIP_SPHERE, sph, G.IMAGE.MIP_SPHERE),
            image(ctx, G.MIP_CONE, cone, G.IMAGE.MIP_CONE),
            image(ctx, G.MIP_LINK, link, G.IMAGE.MIP_LINK)]
    got = run(ctx, progs("mip"), n, 12)
    expect = np.concatenate([decoded_words(r, a) for r, a in
                             ((G.MIP_LINK, link), (G.MIP_SPHERE, sph), (G.MIP_CONE, cone))], 1)
    np.testing.assert_array_equal(got, expect)
    s2 = G.MIP_SPHERE.view(texs[0].read())[:n]         # mip_store: the two swapped
    c2 = G.MIP_CONE.view(texs[1].read())[:n]
    np.testing.assert_array_equal(s2["center"], cone["axis"])
    np.testing.assert_array_equal(s2["radius"], cone["angle"])
    np.testing.assert_array_equal(c2["axis"], sph["center"])
    np.testing.assert_array_equal(c2["angle"], sph["radius"])
    from app.pbgi import gmip
    topo = gmip.build_topology(gmip.z_order(np.arange(50), 7))
    for col, name in ((gmip.L_FIRST, "first"), (gmip.L_COUNT, "count"),
                      (gmip.L_PARENT, "parent"), (gmip.L_LEVEL, "level")):
        np.testing.assert_array_equal(topo.link[:, col], G.MIP_LINK.view(topo.link)[name])
    for t in texs:
        t.release()


@pytest.mark.parametrize("m", [8, 24])
def test_microbuffer_tables_and_entries(ctx, progs, m):
    """The tables app/pbgi/microbuffer.py builds, decoded by gen/microbuffer.glsl, are
    micro_pixel_table's numbers; the entry image round-trips MbEntry."""
    from app.pbgi import microbuffer as MB
    t = MB.micro_pixel_table(m)
    e = t["entries"]
    rng = np.random.default_rng(m)
    entries = random_records(G.MB_ENTRY, e, rng)
    mb_img = image(ctx, G.MB_ENTRY, entries, G.IMAGE.MB, width=e, rows=2)
    MB.table_texture(ctx, m).use(location=G.TEXTURE.MB_TABLE)
    MB.flux_texture(ctx, m).use(location=G.TEXTURE.MB_FLUX)
    MB.index_texture(ctx, m).use(location=G.TEXTURE.MB_INDEX)
    side = m + 1
    n = max(e, side * side)
    got = run(ctx, progs("microbuffer"), n, 13, u_side=side)
    f32 = lambda a: np.asarray(a, np.float32).view(np.uint32).reshape(len(a), -1)  # noqa: E731
    np.testing.assert_array_equal(got[:e, 0:3], f32(t["dir"]))
    np.testing.assert_array_equal(got[:e, 3], f32(t["weight"])[:, 0])
    np.testing.assert_array_equal(got[:e, 4:7], f32(t["flux"]))
    np.testing.assert_array_equal(got[:e, 7], f32(t["solid_angle"])[:, 0])
    np.testing.assert_array_equal(got[:e, 8:10], decoded_words(G.MB_ENTRY, entries))
    bands = got[:side * side, 10:13].reshape(side, side, 3)
    np.testing.assert_array_equal(bands[:m, :m, 0].ravel(), t["extra_first"])
    np.testing.assert_array_equal(bands[:m, :m, 1].ravel(), t["extra_count"])
    np.testing.assert_array_equal(bands[..., 2], t["prefix"])
    row1 = G.MB_ENTRY.view(mb_img.read())[e:2 * e]     # mb_entry_store: key and node swapped
    np.testing.assert_array_equal(row1["key"], entries["node"])
    np.testing.assert_array_equal(row1["node"], entries["key"])
    assert MB.ENTRY_BYTES == G.MB_ENTRY.nbytes and MB.EMPTY == G.MB_EMPTY
    mb_img.release()


@pytest.mark.parametrize("mode,rec,binding", [
    ("share_rows", G.SHARE_ROW, G.SSBO.SHARE),
    ("block_of", G.BLOCK_OF, G.SSBO.BLOCK_OF),
    ("frames", G.FRAME, G.SSBO.FRAMES)])
def test_far_field_records_decode(ctx, progs, mode, rec, binding):
    rng = np.random.default_rng(7)
    recs = random_records(rec, 260, rng)
    buf = ssbo(ctx, recs, binding)
    expect = decoded_words(rec, recs)
    got = run(ctx, progs(mode), 260, expect.shape[1])
    np.testing.assert_array_equal(got, expect)
    buf.release()


def test_gather_output_is_read_through_its_record(ctx, progs):
    n = 333
    out = ctx.buffer(reserve=G.GATHER_OUTPUT.nbytes * n)
    out.bind_to_storage_buffer(G.SSBO.OUTPUT)
    run(ctx, progs("gather_output"), n, 0)
    got = G.GATHER_OUTPUT.view(out.read())
    i = np.arange(n, dtype=np.float32)
    np.testing.assert_array_equal(got["radiance"], np.stack([i, i + 0.5, -i], 1))
    np.testing.assert_array_equal(got["status"], np.where(np.arange(n) % 2 == 0, 1.0, -1.0))
    out.release()


def test_gather_parts_are_read_through_their_record(ctx, progs):
    n = 99
    out = ctx.buffer(reserve=G.GATHER_PARTS.nbytes * n)
    out.write(np.full(G.GATHER_PARTS.words * n, 7.0, np.float32).tobytes())   # padding -> 0
    out.bind_to_storage_buffer(G.SSBO.PARTS)
    run(ctx, progs("gather_parts"), n, 0)
    got = G.GATHER_PARTS.view(out.read())
    i = np.arange(n, dtype=np.float32)
    np.testing.assert_array_equal(got["diffuse"], np.stack([i, i + 0.25, -i], 1))
    np.testing.assert_array_equal(got["material"], np.arange(n) % 7)
    np.testing.assert_array_equal(got["sheen"], np.repeat(2 * i[:, None], 3, 1))
    np.testing.assert_array_equal(got["spec_f0"], np.full((n, 3), 3.0))
    np.testing.assert_array_equal(got["spec_one"], np.stack([-np.ones(n), i, np.full(n, 0.5)],
                                                            1))
    np.testing.assert_array_equal(got["coat"], np.repeat((i * i)[:, None], 3, 1))
    flat = G.GATHER_PARTS.flat(got)
    assert not flat[:, [7, 11, 15, 19]].any()
    out.release()


def test_node_textures_hold_the_node_records(ctx, progs):
    """bsh_textures.glsl packs the node records into the BSH_* texels (read back here through
    their dtypes) and tnode_* decodes the same texels."""
    from app.bench.bsh import local_room
    from app.pbgi.hierarchy import build_bsh
    from app.pbgi.nodetex import NodeTextures
    cloud = local_room(3000, seed=8)
    h = build_bsh(cloud.positions, cloud.normals, cloud.colors)
    n = len(h.nodes)
    records = ctx.buffer(h.nodes.tobytes())
    tex = NodeTextures(ctx, records, n)
    sph = G.BSH_SPHERE.view(tex.textures["sphere"].read())[:n]
    cone = G.BSH_CONE.view(tex.textures["cone"].read())[:n]
    link = G.BSH_LINK.view(tex.textures["link"].read())[:n]
    color = G.BSH_COLOR.view(tex.textures["color"].read())[:n]
    np.testing.assert_array_equal(sph["center"], h.nodes["center"])
    np.testing.assert_array_equal(sph["radius"], h.nodes["radius"])
    np.testing.assert_array_equal(color["color"], h.nodes["color"])
    np.testing.assert_array_equal(link["skip"], h.nodes["skip"])
    np.testing.assert_array_equal(link["count_flags"], h.nodes["count_flags"])
    d = layout.decode(h.nodes)
    np.testing.assert_allclose(cone["axis"], d["cone_axis"], atol=2e-6)
    np.testing.assert_allclose(cone["cos_angle"], d["cone_cos"], atol=2e-6)
    tex.use()
    got = run(ctx, progs("node_textures"), n, 13)
    expect = np.concatenate([decoded_words(G.BSH_SPHERE, sph), decoded_words(G.BSH_CONE, cone),
                             decoded_words(G.BSH_LINK, link), decoded_words(G.BSH_COLOR, color)],
                            1)
    np.testing.assert_array_equal(got, expect)
    tex.release()
    records.release()


# -- one table for the numbers ------------------------------------------------------------------

def test_generated_defines_carry_every_number():
    text = G.bindings_glsl()
    for units in (G.SSBO, G.TEXTURE, G.IMAGE):
        for name, value in units.items():
            assert re.search(rf"^#define {units.prefix}{name}\s+{value}\b", text, re.M), name
    for line in (f"#define WORKGROUP_SIZE {G.WORKGROUP}", f"#define BSH_TEX_WIDTH {G.BSH_TEX_WIDTH}u",
                 f"#define MIP_WIDTH {G.MIP_WIDTH}u", f"#define NIL 0x{G.NIL:08x}u",
                 f"#define MB_EMPTY 0x{G.MB_EMPTY:08x}u", f"#define SHARE_NONE 0x{G.SHARE_NONE:08x}u"):
        assert line in text
    assert f"#define NODE_BINDING {G.SSBO.NODES}" in layout.glsl_header()
    assert G.SSBO.NODES == layout.NODE_BINDING_DEFAULT


PROGRAMS = ([("gbuffer_mip.glsl", {}), ("bsh_textures.glsl", {}), ("mb_clear.glsl", {}),
             ("pbgi_share_merge.glsl", {}), ("pbgi_finish.glsl", {}),
             ("pbgi_finish.glsl", {"STAGE_INIT": 1})]
            + [("pbgi_classic.glsl", {"SHARE_SPLIT": s}) for s in (0, 1, 2)]
            + [("pbgi_refine.glsl", {f"STAGE_{s}": 1}) for s in ("PREPARE", "REFINE", "FIXUP",
                                                                   "MOVE")]
            + [("pbgi_gather.glsl", d) for d in ({}, {"RADIANCE_CUBEMAP": 1},
                                                  {"FRAME_NORMALS": 1})])
_UNIFORM_DECL = re.compile(r"layout\([^)]*binding\s*=\s*(\w+)\)\s*(?:writeonly\s+|readonly\s+)*"
                           r"uniform\s+(?:writeonly\s+|readonly\s+)*(\w+)\s+(\w+)\s*;")


def test_shared_numbers_never_meet_in_one_program(ctx):
    """Names that share a number (gpu_layout's comments say who uses which) never meet: in every
    compiled production program the active SSBOs, samplers and images each have distinct
    bindings, all declared in the table. (SSBO bindings from GL; a sampler's or image's binding
    from its declaration, as moderngl misreads uimage2D uniforms.)"""
    values = {u.define(n): (kind, v) for kind, u in (("sampler", G.TEXTURE), ("image", G.IMAGE))
              for n, v in u.items()}
    ssbos = set(dict(G.SSBO.items()).values())
    for name, defines in PROGRAMS:
        defines = {k: v for k, v in defines.items() if v}
        text, _ = build_source(name, "COMPUTE_SHADER", defines)
        decl = {m.group(3): m.group(1) for m in _UNIFORM_DECL.finditer(text)}
        prog = load_compute(ctx, name, defines or None)
        seen: dict[tuple[str, int], str] = {}
        for member in prog:
            m = prog[member]
            if type(m).__name__ == "StorageBlock":
                key = ("ssbo", m.binding)
                assert m.binding in ssbos, (name, member, m.binding)
            elif member in decl:
                key = values[decl[member]]          # KeyError: a binding not from the table
                assert ("image" if "image" in decl_type(text, member) else "sampler") == key[0]
            else:
                continue
            assert key not in seen, (name, defines, member, seen[key])
            seen[key] = member
        prog.release()


def decl_type(text: str, member: str) -> str:
    return next(m.group(2) for m in _UNIFORM_DECL.finditer(text) if m.group(3) == member)


def test_no_binding_number_is_written_by_hand():
    """Production PBGI shaders take every binding, unit and work-group size from gen/*.glsl, the
    PBGI modules from gpu_layout (the viewer's composite pass has its own, app/ui)."""
    for path in shaders_dir().rglob("*.glsl"):
        if path.name.startswith("viewer_"):
            continue
        text = path.read_text()
        assert not re.search(r"binding\s*=\s*\d", text), path
        assert not re.search(r"local_size_x\s*=\s*\d{2,}", text), path
    for path in (ROOT / "app" / "pbgi").glob("*.py"):
        text = path.read_text()
        assert not re.search(r"bind_to_storage_buffer\(\d|bind_to_image\(\d|\.use\((location=)?\d",
                             text), path


def test_every_generated_include_is_registered_and_self_contained(ctx, tmp_path):
    """Registered in programs.GENERATED_INCLUDES, marked as generated, and each compiles alone
    (it includes what it needs)."""
    for name, fn in G.GENERATED.items():
        assert GENERATED_INCLUDES[name] == f"app.pbgi.gpu_layout:{fn.__name__}"
        assert fn().startswith("// GENERATED by app/pbgi/gpu_layout.py"), name
        path = tmp_path / (name.replace("/", "_"))
        path.write_text(f'#include "{name}"\nlayout(local_size_x = 1) in;\nvoid main() {{}}\n')
        load_compute(ctx, path).release()


def test_every_record_is_checked_here():
    """Each record of gpu_layout.RECORDS goes through one of the GPU round trips above
    (GBUFFER_VERTEX through the G-buffer's: tests/pbgi/test_pbgi_gbuffer.py checks positions,
    normals, UV-mapped textures and tangents against the mesh)."""
    checked = {G.RECEIVER, G.MATERIAL, G.GBUFFER_VERTEX, G.CLASSIC_STATE, G.FINISH_STATE, G.PAIR_COUNTERS, G.PAIR,
               G.ITEM, G.HEAD, G.MIP_LINK, G.MIP_SPHERE, G.MIP_CONE, G.MB_ENTRY, G.MB_DIRECTION,
               G.MB_FLUX, G.MB_BANDS, G.SHARE_ROW, G.BLOCK_OF, G.FRAME, G.GATHER_OUTPUT,
               G.GATHER_PARTS,
               G.BSH_SPHERE, G.BSH_CONE, G.BSH_LINK, G.BSH_COLOR}
    assert set(G.RECORDS.values()) == checked


# -- the record helper --------------------------------------------------------------------------

def test_record_layout_rules():
    r = Record("T", (Field("a", "vec3"), Field("id", "uint", stored_as="value"),
                     Field("b", "vec2"), Pad(2)), word="float")
    assert (r.words, r.slots, r.nbytes) == (8, 2, 32)
    assert [r.index(n) for n in ("a", "id", "b")] == [0, 3, 4]
    assert r.dtype.fields["id"][0] == np.float32
    with pytest.raises(ValueError, match="straddles"):
        Record("U", (Field("a", "float"), Field("b", "vec4")))
    with pytest.raises(ValueError):
        Record("V", (Field("id", "uint", stored_as="value"),), word="uint")
    u = Record("W", (Field("x", "uint"), Field("y", "uint")), word="uint")
    assert u.std430_struct_ok() is False                    # padded to a whole slot
    assert G.CLASSIC_STATE.std430_struct_ok() and G.FINISH_STATE.std430_struct_ok()
    text = r.glsl_getters("t_", lambda k: f"buf[2u * i + {k}u]")
    assert "uint t_id(uint i) { return uint(buf[2u * i + 0u].w + 0.5); }" in text
    assert "vec2 t_b(uint i) { return buf[2u * i + 1u].xy; }" in text
    assert layout.NODE_DTYPE == layout.NODE.dtype and layout.NODE_BYTES == 40
