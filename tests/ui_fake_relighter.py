"""A stand-in for app.pbgi.renderer with the same interface, for the viewer's own tests.

It lets the viewer tests check the viewer (refinement, tiles, compositing, panels, sessions)
independently of PBGI: the asset is replaced by its bounding sphere and shaded analytically
(Lambert + a Phong-like lobe from the material, a directional key light and the cloud's mean
radiance as ambient), which is cheap, deterministic and depends on every input the real renderer
depends on (camera, tile, materials, mode, cloud colours). Selected with
SCANLIGHT_RELIGHTER=tests.ui_fake_relighter:Relighter.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

MODE_GAIN = {"classic": 1.0, "mipmapped": 0.96, "hybrid": 0.98, "envmap": 0.85}
KEY = np.array([0.3, 0.9, 0.3]) / np.linalg.norm([0.3, 0.9, 0.3])


@dataclass
class RenderParams:
    mode: str = "classic"
    microbuffer: int = 24
    omega_tr_factor: float = 32.0
    memory_budget_mb: float = 1024.0


@dataclass
class RenderResult:
    image: np.ndarray
    stats: dict = field(default_factory=dict)


class Relighter:
    calls: list = []  # (camera size, tile) of every render, for tests

    def __init__(self, ctx=None):
        self.ambient = np.zeros(3)
        self.centre = None
        self.radius = 0.0
        self.materials = None

    def set_cloud(self, cloud, hierarchy=None):
        self.ambient = np.asarray(cloud.colors, np.float64).mean(axis=0)

    def set_asset(self, mesh):
        lo, hi = mesh.bounds()
        self.centre = (np.asarray(lo, float) + np.asarray(hi, float)) / 2
        self.radius = float(np.max(np.asarray(hi, float) - np.asarray(lo, float))) / 2
        self.materials = mesh.materials

    def render(self, camera, materials, params, tile=None):
        x0, y0, w, h = tile if tile is not None else (0, 0, camera.width, camera.height)
        Relighter.calls.append(((camera.width, camera.height), (x0, y0, w, h)))
        origin, dirs = camera.pixel_rays()
        d = dirs[y0:y0 + h, x0:x0 + w].reshape(-1, 3)
        oc = origin - self.centre
        b = d @ oc
        disc = b * b - (oc @ oc - self.radius ** 2)
        hit = disc > 0
        t = -b - np.sqrt(np.maximum(disc, 0))
        hit &= t > 0
        p = origin + t[:, None] * d
        n = (p - self.centre) / self.radius
        mat = (materials or self.materials)[0]
        base = np.asarray(mat.base_color, float)
        ndl = np.clip(n @ KEY, 0, None)
        r = d - 2 * np.sum(d * n, axis=1, keepdims=True) * n
        shininess = 2.0 / max(mat.roughness, 0.02) ** 4
        spec = (1 - 0.9 * mat.roughness) * np.clip(r @ KEY, 0, None) ** min(shininess, 1e4)
        diffuse = (1 - mat.metallic) * base[None] * (0.4 * self.ambient + 1.5 * ndl[:, None])
        tint = base if mat.metallic > 0.5 else np.ones(3)
        rgb = (diffuse + 2.0 * spec[:, None] * tint[None]) * MODE_GAIN[params.mode]
        img = np.zeros((h * w, 4), np.float32)
        img[hit, :3] = rgb[hit]
        img[hit, 3] = 1.0
        stats = {"mode": params.mode, "ms": 0.0, "mb": 0.0, "nodes_visited": int(hit.sum()),
                 "microbuffer": params.microbuffer, "width": camera.width,
                 "height": camera.height, "completed": True}
        return RenderResult(img.reshape(h, w, 4), stats)
