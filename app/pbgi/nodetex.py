"""The texture view of the BSH that the per-pixel walks read (see shaders/lib/bsh_textures.glsl
for why textures: llvmpipe fetches texels as vector gathers, SSBO words one lane at a time).

Built on the GPU from the uploaded 40-byte records by shaders/bsh_textures.glsl, which decodes
them through the generated layout header, so the record format is still defined only in
app/pbgi/layout.py. Costs 64 bytes per node on top of the records' 40. Texels, width and units:
app/pbgi/gpu_layout.py (BSH_SPHERE, BSH_CONE, BSH_LINK, BSH_COLOR; gen/bsh_textures.glsl).
"""

from __future__ import annotations

import numpy as np

from app.pbgi.gpu_layout import (BSH_COLOR, BSH_CONE, BSH_LINK, BSH_SPHERE, BSH_TEX_WIDTH, IMAGE,
                                 SSBO, TEXTURE, dispatch_groups)
from app.render.programs import load_compute

WIDTH = BSH_TEX_WIDTH
# name -> (texel record, texture unit the walks read it from, image unit the build writes it to)
TEXTURES = {
    "sphere": (BSH_SPHERE, TEXTURE.BSH_SPHERE, IMAGE.BSH_SPHERE),
    "cone": (BSH_CONE, TEXTURE.BSH_CONE, IMAGE.BSH_CONE),
    "link": (BSH_LINK, TEXTURE.BSH_LINK, IMAGE.BSH_LINK),
    "color": (BSH_COLOR, TEXTURE.BSH_COLOR, IMAGE.BSH_COLOR),
}


class NodeTextures:
    def __init__(self, ctx, records, count: int):
        """``records``: the SSBO holding ``count`` node records."""
        import moderngl
        self.ctx = ctx
        self.count = int(count)
        h = max(1, (self.count + WIDTH - 1) // WIDTH)
        self.textures = {name: ctx.texture((WIDTH, h), rec.texel_components,
                                           dtype=rec.texture_dtype)
                         for name, (rec, _, _) in TEXTURES.items()}
        for t in self.textures.values():
            t.filter = (moderngl.NEAREST, moderngl.NEAREST)
        prog = load_compute(ctx, "bsh_textures.glsl")
        records.bind_to_storage_buffer(SSBO.NODES)
        for name, (_, _, image_unit) in TEXTURES.items():
            self.textures[name].bind_to_image(image_unit, read=False, write=True)
        prog.run(dispatch_groups(self.count))
        ctx.memory_barrier()
        prog.release()
        self.nbytes = sum(rec.nbytes * WIDTH * h for rec, _, _ in TEXTURES.values())
        # the asset's surfels in a joined tree (app/pbgi/scene_tree.py): nodes from
        # ``asset_first`` on, each surfel of area ``surfel_area``; none by default
        self.asset_first = self.count
        self.surfel_area = 0.0
        self.directional = None
        self.metal_albedo = None
        self.set_directional(None)

    def set_directional(self, gradients, first: int = 0, mirror=None, environment=None) -> None:
        """The asset's glossy bounce (app/pbgi/asset_scene.py): its nodes from ``first`` on
        send L(d) = colour + G d towards unit direction d, ``gradients`` (k, 3, 3): per node
        G's columns dL/dx, dL/dy, dL/dz (RGB each). ``mirror`` (k, 5) per node (F0 RGB,
        roughness, weight) and ``environment`` (an EnvironmentMap of the room seen from the
        asset's centre, not owned): the mirror bounce, mixed in by its weight (asset_scene.py:
        mirror_params). The gather (shaders/pbgi_gather.glsl: node_radiance) reads texel 0 =
        (first / 65536, first % 65536, k) - two halves, exact in a float whatever the node
        count - and node first + j's texels 1 + 4 j + c, rows of WIDTH: c = 0, 1, 2 G's column
        c (the first's alpha: the roughness), c = 3 (F0, weight). None: every node's radiance
        is its colour (texel 0 holds a first no node reaches, 2^32 - 1), and the gather runs
        its variant without the look-up."""
        import moderngl
        if self.directional is not None:
            self.directional.release()
        g = np.zeros((0, 3, 3), np.float32) if gradients is None else \
            np.asarray(gradients, np.float32).reshape(-1, 3, 3)
        texels = np.zeros((1 + 4 * len(g), 4), np.float32)
        self.has_directional = bool(len(g))     # the gather's ASSET_DIRECTIONAL variant
        self.has_mirror = bool(len(g)) and mirror is not None and environment is not None
        self.mirror_environment = environment if self.has_mirror else None
        first = int(first) if len(g) else (1 << 32) - 1
        texels[0, :3] = (float(first >> 16), float(first & 0xFFFF), float(len(g)))
        node = texels[1:].reshape(-1, 4, 4)                      # (k, texel c, RGBA)
        node[:, :3, :3] = g.transpose(0, 2, 1)                   # texel c: column c
        if self.has_mirror:
            mp = np.asarray(mirror, np.float32).reshape(-1, 5)
            node[:, 0, 3] = mp[:, 3]
            node[:, 3, :3], node[:, 3, 3] = mp[:, :3], mp[:, 4]
            if self.metal_albedo is None:
                from app.pbgi.brdf import metal_albedo_table
                table = metal_albedo_table()
                self.metal_albedo = self.ctx.texture(table.shape[1::-1], 2,
                                                     np.ascontiguousarray(table).tobytes(),
                                                     dtype="f4")
                self.metal_albedo.filter = (moderngl.LINEAR, moderngl.LINEAR)
                self.metal_albedo.repeat_x = self.metal_albedo.repeat_y = False
        h = (len(texels) + WIDTH - 1) // WIDTH
        data = np.zeros((h * WIDTH, 4), np.float32)
        data[:len(texels)] = texels
        w = WIDTH if h > 1 or len(g) else 1
        self.directional = self.ctx.texture((w, h), 4, data[:w * h].tobytes(), dtype="f4")
        self.directional.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.directional_nbytes = w * h * 16

    def set_uniforms(self, prog) -> None:
        """The tree's uniforms of lib/pbgi_cut.glsl a walk shader kept: where the asset's
        nodes start and their surfels' area (0: no asset in the tree)."""
        for name, value in (("u_asset_first", int(self.asset_first)),
                            ("u_surfel_area", float(self.surfel_area))):
            if name in prog:
                prog[name] = value

    def use(self) -> None:
        for name, (_, unit, _) in TEXTURES.items():
            self.textures[name].use(location=unit)
        self.directional.use(location=TEXTURE.ASSET_DIR)
        if self.has_mirror:
            self.mirror_environment.texture.use(location=TEXTURE.ASSET_ENV)
            self.metal_albedo.use(location=TEXTURE.METAL_ALBEDO)

    def release(self) -> None:
        for t in self.textures.values():
            t.release()
        self.textures = {}
        if self.directional is not None:
            self.directional.release()
        self.directional = None
        if self.metal_albedo is not None:
            self.metal_albedo.release()
        self.metal_albedo = None
