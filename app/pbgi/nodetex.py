"""The texture view of the BSH that the per-pixel walks read (see shaders/lib/bsh_textures.glsl
for why textures: llvmpipe fetches texels ~16x faster than it loads SSBO words).

Built on the GPU from the uploaded 40-byte records by shaders/bsh_textures.glsl, which decodes
them through the generated layout header, so the record format is still defined only in
app/pbgi/layout.py. Costs 64 bytes per node on top of the records' 40.
"""

from __future__ import annotations

from app.render.programs import load_compute

WIDTH = 4096                 # BSH_TEX_WIDTH in the GLSL
UNITS = {"sphere": 1, "cone": 2, "link": 3, "color": 4}   # texture and image units


class NodeTextures:
    def __init__(self, ctx, records, count: int):
        """``records``: the SSBO holding ``count`` node records."""
        import moderngl
        self.ctx = ctx
        self.count = int(count)
        h = max(1, (self.count + WIDTH - 1) // WIDTH)
        self.textures = {
            "sphere": ctx.texture((WIDTH, h), 4, dtype="f4"),
            "cone": ctx.texture((WIDTH, h), 4, dtype="f4"),
            "link": ctx.texture((WIDTH, h), 4, dtype="u4"),
            "color": ctx.texture((WIDTH, h), 4, dtype="f4"),
        }
        for t in self.textures.values():
            t.filter = (moderngl.NEAREST, moderngl.NEAREST)
        prog = load_compute(ctx, "bsh_textures.glsl")
        records.bind_to_storage_buffer(3)
        for name, unit in UNITS.items():
            self.textures[name].bind_to_image(unit, read=False, write=True)
        prog.run((self.count + 63) // 64)
        ctx.memory_barrier()
        prog.release()
        self.nbytes = sum(4 * 4 * WIDTH * h for _ in self.textures)

    def use(self) -> None:
        for name, unit in UNITS.items():
            self.textures[name].use(location=unit)

    def release(self) -> None:
        for t in self.textures.values():
            t.release()
        self.textures = {}
