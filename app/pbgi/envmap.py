"""The environment-map baseline (paper Fig. 14): the cloud splatted into a cube map seen from the
object's centre, then used as *distant* light by the same gather and BRDF as PBGI.

This is the standard look-dev approach: it ignores parallax (every receiver sees the room from
the centre) and so misplaces near walls and lights, which is what PBGI fixes. ``EnvmapMode`` is
the render mode (app/pbgi/modebase.py): no micro-buffers, one gather of all receivers from the
cube map the Relighter keeps per cloud, asset and face size.
"""

from __future__ import annotations

import time

import numpy as np

from app.camera import cube_cameras
from app.pbgi.modebase import Frame, RenderMode, RenderParams
from app.pbgi.stats import RenderStats
from app.render.splat import SplatRenderer

DEFAULT_FACE = 128


def fill_holes(rgba: np.ndarray) -> np.ndarray:
    """Pull-push hole filling: pixels no splat covered (alpha 0) take the alpha-weighted mean of
    the nearest covered ones, from successively coarser levels. Splats of a random scan leave
    ~10% of a face uncovered, which would otherwise darken the environment by as much."""
    rgb, a = rgba[..., :3].astype(np.float64), np.clip(rgba[..., 3:4], 0, 1).astype(np.float64)
    if a.min() >= 1.0 or a.max() <= 0.0:
        return rgb.astype(np.float32)
    h, w = a.shape[:2]
    ph, pw = h + h % 2, w + w % 2
    c = np.pad(rgb * a, ((0, ph - h), (0, pw - w), (0, 0)))
    wa = np.pad(a, ((0, ph - h), (0, pw - w), (0, 0)))
    cs = c.reshape(ph // 2, 2, pw // 2, 2, 3).sum((1, 3))
    ws = wa.reshape(ph // 2, 2, pw // 2, 2, 1).sum((1, 3))
    coarse = np.concatenate([cs / np.maximum(ws, 1e-12), np.minimum(ws, 1.0)], axis=-1)
    filled = fill_holes(coarse)
    up = np.repeat(np.repeat(filled, 2, axis=0), 2, axis=1)[:h, :w]
    return (rgb * a + up * (1.0 - a)).astype(np.float32)


class EnvironmentMap:
    """A float32 RGB cube texture with mipmaps (textureLod by micro-pixel solid angle), from six
    (S, S, 3) faces in cube_cameras' order, each row 0 at the top: the cloud's splats seen from
    the asset's centre (``of_splats``), or an HDRI panorama (app/pbgi/hdri.py)."""

    def __init__(self, ctx, faces, centre):
        self.ctx = ctx
        self.centre = np.asarray(centre, dtype=np.float64)
        self.face_size = int(faces[0].shape[0])
        # faces have row 0 at the top; the cube face wants the framebuffer's own order
        # (bottom row first) for cube_cameras' orientation - verified per face by a test.
        data = np.concatenate([np.ascontiguousarray(f[::-1, :, :3], dtype="f4").ravel()
                               for f in faces])
        self.faces = faces
        self.texture = ctx.texture_cube((self.face_size, self.face_size), 3, data.tobytes(),
                                        dtype="f4")
        self.texture.build_mipmaps()
        self.texel_omega = (2.0 / self.face_size) ** 2
        self.nbytes = int(data.nbytes * 4 // 3)

    @classmethod
    def of_splats(cls, ctx, splat: SplatRenderer, centre, face_size: int = DEFAULT_FACE):
        """The room's splats seen from ``centre``, holes filled (app/render/splat.py)."""
        faces = [fill_holes(splat.render(cam)) for cam in cube_cameras(centre, int(face_size))]
        return cls(ctx, faces, centre)

    def release(self) -> None:
        self.texture.release()


class EnvmapMode(RenderMode):
    """The environment-map baseline as a render mode."""

    name = "envmap"

    def fits(self, params: RenderParams) -> bool:
        return True                   # the face size is per render (the Relighter's cube map)

    def render(self, frame: Frame, stats: RenderStats) -> int:
        env = frame.environment(frame.params.envmap_face)
        self.ctx.finish()
        tg = time.perf_counter()
        frame.gather.run(frame.receivers, frame.materials, frame.output, 0, frame.count, frame.m,
                         frame.camera_rel, env=env, lobe=frame.lobe,
                         absent=frame.absent_features, parts=frame.parts)
        self.ctx.finish()
        stats.ms_gather = (time.perf_counter() - tg) * 1e3
        stats.envmap_face = env.face_size
        return env.nbytes

    def release(self) -> None:
        pass                          # the cube map is the Relighter's
