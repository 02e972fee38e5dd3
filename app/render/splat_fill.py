"""The splats' screen-space passes: normalisation, push-pull hole filling, eye-dome lighting.

app/render/splat.py accumulates the splats (sum of weight x colour, sum of weight, sum of weight x
eye depth) into this module's targets; shaders/splat_resolve.glsl then, as compute passes (a
per-pixel gather in a full-screen fragment pass gives wrong diagonal pixels on llvmpipe):

1. divides the sums (level 0 of a pyramid of vec4(radiance, eye depth), depth 0 = empty);
2. pulls: each coarser level averages the filled texels of the level below that lie on the front
   surface (within ``PULL_DEPTH_REL`` of the nearest);
3. pushes back down: an empty texel takes the bilinear mean of the coarser level; at full
   resolution only if it is enclosed (a filled pixel within ``MAX_HOLE_PX`` in both directions
   along at least 3 of the 4 axes), so holes up to MAX_HOLE_PX pixels across and cracks of any
   length close while the room's outline against empty space (a window, the edge of a partial
   scan) keeps its place; a filled pixel enclosed
   the same way by pixels nearer by ``SEE_THROUGH_REL`` (a farther surface seen through a gap of
   a slanted one) is replaced too;
4. writes ROOM_TEXEL(radiance x eye-dome shade, coverage 1 | 0), less a guard band: the splats
   are drawn GUARD_PX wider on each side than the image, so a hole at the image's border is
   enclosed like any other.

``push_pull`` runs 2 and 3 alone on an array (tests/render/test_backdrop.py compares it with a
numpy twin of the same rules).
"""

from __future__ import annotations

import numpy as np

from app.render.gpu_layout import SPLAT_IMG, SPLAT_RESOLVE_TILE
from app.render.programs import load_compute

MAX_HOLE_PX = 8          # enclosure reach: holes up to this many pixels across are filled
PUSH_PULL_LEVELS = 5     # coarsest level: 16 x 16 pixels a texel, twice MAX_HOLE_PX
PULL_DEPTH_REL = 0.1     # texels more than 10% behind the nearest of a 2x2 block are background
SEE_THROUGH_REL = 0.02   # a pixel 2% behind nearer ones in all 8 directions is seen through a gap
GUARD_PX = MAX_HOLE_PX   # extra pixels drawn on each side of the image (see 4.)
EDL_RADIUS_PX = 1.0      # eye-dome lighting: neighbour distance (Potree: 1.4 at full HD)
EDL_RESPONSE = 100.0     # shade = exp(-EDL_RESPONSE x mean log2 depth step behind neighbours)

_PASSES = {"normalise": 0, "pull": 1, "push": 2, "finish": 3}


def _groups(size) -> tuple[int, int]:
    return -(-size[0] // SPLAT_RESOLVE_TILE), -(-size[1] // SPLAT_RESOLVE_TILE)


def level_sizes(size, levels: int = PUSH_PULL_LEVELS) -> list[tuple[int, int]]:
    """(w, h) of each pyramid level, level 0 = ``size``; each halves, rounding up."""
    out = [tuple(size)]
    for _ in range(levels - 1):
        w, h = out[-1]
        out.append((max(1, -(-w // 2)), max(1, -(-h // 2))))
    return out


class SplatFill:
    """The accumulation targets and the resolve passes for one context (targets per size)."""

    def __init__(self, ctx):
        self.ctx = ctx
        defines = {"PULL_DEPTH_REL": repr(PULL_DEPTH_REL), "MAX_HOLE_PX": str(MAX_HOLE_PX),
                   "SEE_THROUGH_REL": repr(SEE_THROUGH_REL),
                   "EDL_RESPONSE": repr(EDL_RESPONSE)}
        self.cs = {name: load_compute(ctx, "splat_resolve.glsl", dict(defines, RESOLVE_PASS=k))
                   for name, k in _PASSES.items()}
        self.size = None
        self._objs = []

    def _tex(self, size, components=4):
        import moderngl
        tex = self.ctx.texture(size, components, dtype="f4")
        tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self._objs.append(tex)
        return tex

    def targets(self, size) -> None:
        """(Re)make the accumulation targets and the pyramid for ``size`` = (w, h)."""
        size = (int(size[0]), int(size[1]))
        if size == self.size:
            return
        self.release_targets()
        self.size = size
        self.accum = self._tex(size)                 # (sum w c, sum w)
        self.depth_sum = self._tex(size, 1)          # sum w z
        self.accum_fbo = self.ctx.framebuffer([self.accum, self.depth_sum])
        self.depth = self.ctx.depth_texture(size)    # the depth pass's front surface
        self.depth.compare_func = ""
        self.depth_fbo = self.ctx.framebuffer(depth_attachment=self.depth)
        # labels: one opaque, depth-tested pass straight into the sums (weight 1)
        self.opaque_fbo = self.ctx.framebuffer([self.accum, self.depth_sum], self.depth)
        self._objs += [self.accum_fbo, self.depth, self.depth_fbo, self.opaque_fbo]
        self.levels = [self._tex(s) for s in level_sizes(size)]
        self.filled = self._tex(size)                # level 0 after the push

    def _run(self, name, out_size, **uniforms) -> None:
        cs = self.cs[name]
        cs["u_size"].value = tuple(out_size)
        for key, val in uniforms.items():
            if key in cs:
                cs[key].value = val
        cs.run(*_groups(out_size))
        self.ctx.memory_barrier()

    def _pyramid(self, hole_px: int, pick: bool = False) -> None:
        """Pull up from level 0, push back down; the result is in ``self.filled``. Level 0 is
        filled where enclosed within ``hole_px`` pixels (0: everywhere the pyramid reaches);
        ``pick``: one texel's value instead of means (labels)."""
        lv = self.levels
        for k in range(len(lv) - 1):
            lv[k].bind_to_image(SPLAT_IMG.SRC, read=True, write=False)
            lv[k + 1].bind_to_image(SPLAT_IMG.DST, read=False, write=True)
            self._run("pull", lv[k + 1].size, u_pick=int(pick))
        for k in range(len(lv) - 2, -1, -1):
            out = self.filled if k == 0 else lv[k]
            lv[k + 1].bind_to_image(SPLAT_IMG.SRC, read=True, write=False)
            lv[k].bind_to_image(SPLAT_IMG.AUX, read=True, write=False)
            out.bind_to_image(SPLAT_IMG.DST, read=False, write=True)
            self._run("push", lv[k].size, u_hole=max(int(hole_px), 0) if k == 0 else 0,
                      u_pick=int(pick))

    def resolve(self, out_tex, eye_dome: bool = False, hole_px: int = MAX_HOLE_PX,
                guard: int = 0, pick: bool = False) -> None:
        """Accumulation targets -> ``out_tex`` (RGBA32F, ROOM_TEXEL, this size less ``guard``
        pixels on each side); ``hole_px``: the enclosure reach of the hole filling, 0 = none."""
        self.accum.bind_to_image(SPLAT_IMG.SRC, read=True, write=False)
        self.depth_sum.bind_to_image(SPLAT_IMG.AUX, read=True, write=False)
        self.levels[0].bind_to_image(SPLAT_IMG.DST, read=False, write=True)
        self._run("normalise", self.size)
        if hole_px > 0:
            self._pyramid(hole_px, pick)
        (self.filled if hole_px > 0 else self.levels[0]).bind_to_image(
            SPLAT_IMG.SRC, read=True, write=False)
        out_tex.bind_to_image(SPLAT_IMG.DST, read=False, write=True)
        self._run("finish", out_tex.size, u_edl=int(bool(eye_dome)), u_edl_radius=EDL_RADIUS_PX,
                  u_offset=(int(guard), int(guard)))

    def push_pull(self, level0: np.ndarray, hole_px: int = MAX_HOLE_PX,
                  pick: bool = False) -> np.ndarray:
        """Fill an (h, w, 4) array of (radiance, eye depth; 0 = empty), GL orientation, as the
        renderer does (``hole_px`` 0: wherever the pyramid reaches); returns the filled array."""
        h, w = level0.shape[:2]
        self.targets((w, h))
        self.levels[0].write(np.ascontiguousarray(level0, "f4").tobytes())
        self._pyramid(hole_px, pick)
        return np.frombuffer(self.filled.read(), "f4").reshape(h, w, 4).copy()

    def release_targets(self) -> None:
        for obj in self._objs:
            obj.release()
        self._objs, self.size = [], None

    def release(self) -> None:
        self.release_targets()
        for cs in self.cs.values():
            cs.release()


__all__ = ["SplatFill", "level_sizes", "MAX_HOLE_PX", "GUARD_PX", "PUSH_PULL_LEVELS",
           "PULL_DEPTH_REL", "SEE_THROUGH_REL",
           "EDL_RADIUS_PX", "EDL_RESPONSE"]
