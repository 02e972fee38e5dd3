"""The final gather (paper eq. 9) shared by every mode: micro-buffer (or cube map) x Disney BRDF.

See shaders/pbgi_gather.glsl. The PBGI modes read the radiance of the node each micro-pixel
stores; the environment-map baseline reads the cube map in the same micro-pixel directions, so
the two differ only in where incoming light comes from.
"""

from __future__ import annotations

import numpy as np

from app.pbgi.gpu_layout import SSBO, TEXTURE, dispatch_groups
from app.pbgi.microbuffer import flux_texture, set_frame_uniforms, table_texture
from app.render.programs import load_compute


# Material parameters whose BRDF terms a gather variant can leave out (shaders/lib/principled.glsl:
# PRINCIPLED_NO_<NAME>) when every material it shades has them at 0.
FEATURES = {"subsurface": "SUBSURFACE", "anisotropic": "ANISOTROPY", "sheen": "SHEEN",
            "clearcoat": "CLEARCOAT"}


def absent_features(materials) -> tuple[str, ...]:
    """The FEATURES no material of ``materials`` uses (their parameter is 0 in every one): the
    BRDF code the gather may compile out. These parameters are plain factors (no textures,
    app/pbgi/gpu_layout.py: TEXTURED_PARAMS), so the material list decides exactly."""
    return tuple(sorted(tag for name, tag in FEATURES.items()
                        if all(float(getattr(m, name)) == 0.0 for m in materials)))


class Gather:
    def __init__(self, ctx):
        self.ctx = ctx
        self._progs = {}

    def _prog(self, cubemap: bool, frames: bool = False, lobe: bool = False,
              irradiance: bool = False, absent: tuple = (), directional: bool = False,
              parts: bool = False, mirror: bool = False, coverage: bool = False):
        key = (cubemap, frames, lobe, irradiance, tuple(absent), directional, parts, mirror,
               coverage)
        if key not in self._progs:
            defines = {"RADIANCE_CUBEMAP": 1} if cubemap else {}
            if coverage:
                defines["COVERAGE"] = 1
            if parts:
                defines["GATHER_PARTS"] = 1
            if directional:
                defines["ASSET_DIRECTIONAL"] = 1
            if mirror:
                defines["ASSET_MIRROR"] = 1
            if frames:
                defines["FRAME_NORMALS"] = 1
            if lobe:
                defines["LOBE_BUFFER"] = 1
            if irradiance:
                defines["IRRADIANCE"] = 1
            for tag in absent:
                defines[f"PRINCIPLED_NO_{tag}"] = 1
            self._progs[key] = load_compute(self.ctx, "pbgi_gather.glsl", defines=defines or None)
        return self._progs[key]

    def run(self, receivers, materials, output, first: int, count: int, m: int,
            camera_rel: np.ndarray, mb=None, nodes=None, env=None, frames=None,
            lobe=None, lobe_buffers=None, irradiance: bool = False,
            absent: tuple = (), parts=None, seed_tile: tuple = (0, 0, 1, 1),
            pass_index: int = 0, turned: bool = True, coverage: bool = False) -> None:
        """Gather receivers [first, first + count) into ``output`` (a gpu_layout.GATHER_OUTPUT
        record per tile pixel); ``materials``: the material table (gbuffer.material_table).
        Either ``mb`` + ``nodes`` (MicroBuffers + NodeTextures: PBGI) or ``env`` (an
        EnvironmentMap) gives the radiance. ``frames``: per batch receiver, the normal whose
        frame its micro-buffer is in (FRAME; default its own normal - Hybrid's far-field sharing
        gives every receiver of a block the block's frame). ``lobe``: the LobeSettings of the
        glossy receivers' lobe micro-buffers (``lobe_buffers``, filled for this batch; with
        ``env`` the lobe directions read the cube map instead; app/pbgi/lobe.py).
        ``irradiance``: a white Lambertian BRDF for every receiver (E / pi; no lobes).
        ``absent``: BRDF features no material of the table uses (``absent_features``): a
        variant without their code, compiled once per feature set. ``parts``: a buffer of
        gpu_layout.GATHER_PARTS records per tile pixel, filled too (the GATHER_PARTS variant:
        the sums kept apart per BRDF factor, app/pbgi/gather_parts.py). ``seed_tile`` (tile x0,
        y0, tile width, image width), ``pass_index`` and ``turned``: the receivers' micro-buffer
        frames, as their cut drew them (microbuffer.set_frame_uniforms). ``coverage`` (with
        ``irradiance`` and ``mb``): every entry the micro-buffers hold counts as radiance 1, so
        each output is the cosine-weighted share of the hemisphere they hold."""
        if irradiance and lobe is not None:
            raise ValueError("an irradiance gather has no lobe micro-buffers")
        if irradiance and parts is not None:
            raise ValueError("an irradiance gather has no BRDF to split into parts")
        if coverage and (not irradiance or env is not None):
            raise ValueError("a coverage gather is an irradiance gather of micro-buffers")
        directional = (env is None and not coverage
                       and bool(getattr(nodes, "has_directional", False)))
        mirror = directional and bool(getattr(nodes, "has_mirror", False))
        prog = self._prog(env is not None, frames is not None, lobe is not None, irradiance,
                          () if irradiance else tuple(absent), directional, parts is not None,
                          mirror, coverage)
        set_frame_uniforms(prog, seed_tile, pass_index, turned)
        if mirror:
            prog["u_asset_env_texel_omega"] = nodes.mirror_environment.texel_omega
        if parts is not None:
            parts.bind_to_storage_buffer(SSBO.PARTS)
        if lobe is not None:
            if env is None:
                lobe_buffers.bind()
            for name, value in (("u_rings", lobe.rings), ("u_sectors", lobe.sectors),
                                ("u_pass", lobe.pass_index),
                                ("u_lobe_tile", tuple(int(v) for v in lobe.seed_tile)),
                                ("u_lobe_cosine_m", int(lobe.cosine_m)),
                                ("u_glossy_below", lobe.glossy_below)):
                prog[name] = value
        if frames is not None:
            frames.bind_to_storage_buffer(SSBO.FRAMES)
            flux_texture(self.ctx, m).use(location=TEXTURE.MB_FLUX)
        receivers.bind_to_storage_buffer(SSBO.RECEIVERS)
        materials.bind_to_storage_buffer(SSBO.MATERIALS)
        output.bind_to_storage_buffer(SSBO.OUTPUT)
        if env is None:
            nodes.use()
            mb.bind()
        else:
            table_texture(self.ctx, m).use(location=TEXTURE.MB_TABLE)
            env.texture.use(location=TEXTURE.ENV)
            prog["u_env_texel_omega"] = env.texel_omega
        prog["u_first"] = first
        prog["u_count"] = count
        if "u_m" in prog:
            prog["u_m"] = m
        if "u_camera" in prog:          # the IRRADIANCE variant does not look at the camera
            prog["u_camera"] = tuple(float(c) for c in camera_rel)
        prog.run(dispatch_groups(count))
        self.ctx.memory_barrier()
