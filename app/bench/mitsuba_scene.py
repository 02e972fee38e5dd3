"""The reference protocol: the same cloud and asset path traced by Mitsuba 3, an independent
renderer (a dev dependency: ``pip install -e .[reference]``; variant ``scalar_rgb``, the only one
that runs here - the ``llvm_*`` variants crash on this machine). Nothing in CI runs it: the
references it renders are committed (tests/pbgi/references/, made by
tests/pbgi/make_references.py) and the tests compare against those.

The scene is what PBGI assumes, rendered without any of PBGI's approximations:
* the cloud is one emissive mesh: a square per point, centred on it, facing its normal, with the
  side of a disc of the leaves' size (``square_side``: the area of a disc of radius
  ``estimate_disc_radius``, the median spacing of the scan), emitting the point's colour as
  radiance from its front only (Mitsuba's ``area`` emitter is one-sided, as a scan's point is: it
  saw the front of the surface). The squares reflect nothing (black ``diffuse``): a scan's colour
  already is the light leaving the room;
* the asset carries Mitsuba's ``principled`` BSDF with our material's parameters. The two models
  differ where Mitsuba follows Burley 2015 rather than the 2012 BRDF explorer we transcribe
  (see ``CONVENTIONS``): metals agree term by term, dielectrics differ at grazing angles;
* the ``path`` integrator, depth ``max_depth`` (2: camera -> asset -> room, all a convex asset
  needs; 3 for the asset in the room, app/bench/asset_scenes.py: one inter-reflection of the
  asset, and the asset's bounce onto a shadow catcher), box pixel filter (a pixel's value is the mean over its
  footprint), ``spp`` samples per pixel split into two independent halves whose difference gives
  the reference's own noise floor.

Scene loading is kept out of the timings (``Reference.seconds`` is the render alone).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from app.camera import Camera
from app.cloud import PointCloud

VARIANT = "scalar_rgb"
CONVENTIONS = (
    "Mitsuba's principled BSDF vs the Disney 2012 BRDF explorer (app/pbgi/brdf.py): "
    "metal lobe identical (GGX D, Smith G with the same alpha = roughness^2, Schlick Fresnel "
    "tinted by the base colour); dielectric specular uses the exact dielectric Fresnel for "
    "eta = 2 / (1 - sqrt(0.08 specular)) - 1 instead of Schlick; the diffuse lobe is Burley 2015's "
    "(retro-reflection split out) instead of 2012's; clearcoat omits the 1 / (4 cos cos) factor.")


def _mitsuba():
    try:
        import mitsuba as mi
    except ImportError as exc:       # a dev dependency only
        raise RuntimeError("the Mitsuba reference needs `pip install -e .[reference]`") from exc
    mi.set_variant(VARIANT)
    return mi


def square_side(cloud: PointCloud, disc_radius: float | None = None) -> float:
    """Side of the square standing for one point: the area of a disc of ``disc_radius``
    (default: app/pbgi/lobe.py's surface_radius, the disc a PBGI leaf is ray cast as)."""
    from app.pbgi.lobe import surface_radius
    r = float(disc_radius if disc_radius is not None else surface_radius(cloud.positions))
    return float(np.sqrt(np.pi) * r)


ATLAS_WIDTH = 1024


def cloud_squares(positions, normals, colors, side: float):
    """(vertices (4P, 3), faces (2P, 3), texcoords (4P, 2), atlas (H, ATLAS_WIDTH, 3)) of one
    square per point, wound so that Mitsuba's face normal is the point's normal. Each square's
    four corners carry the UV of the centre of its own texel of the radiance atlas, read with
    nearest filtering: the square emits exactly its point's colour. (Per-face colours through a
    ``mesh_attribute`` texture would be simpler, but crash Mitsuba 3.7's scalar variant on an
    emitter.)"""
    p = np.asarray(positions, np.float64)
    n = np.asarray(normals, np.float64)
    n = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    a = np.where(np.abs(n[:, :1]) < 0.9, np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]]))
    t = np.cross(n, a)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    b = np.cross(n, t)                      # (t, b, n) right-handed
    h = 0.5 * side
    corners = np.stack([p - h * t - h * b, p + h * t - h * b, p + h * t + h * b,
                        p - h * t + h * b], axis=1).reshape(-1, 3)
    base = 4 * np.arange(len(p))[:, None]
    faces = np.concatenate([base + [0, 1, 2], base + [0, 2, 3]], axis=1).reshape(-1, 3)
    n_pts = len(p)
    rows = max(2, -(-n_pts // ATLAS_WIDTH))
    atlas = np.zeros((rows * ATLAS_WIDTH, 3), np.float32)
    atlas[:n_pts] = np.maximum(np.asarray(colors, np.float32), 0.0)
    i = np.arange(n_pts)
    uv = np.stack([(i % ATLAS_WIDTH + 0.5) / ATLAS_WIDTH, (i // ATLAS_WIDTH + 0.5) / rows], 1)
    return (corners, faces.astype(np.uint32), np.repeat(uv, 4, axis=0),
            atlas.reshape(rows, ATLAS_WIDTH, 3))


def principled_dict(material) -> dict:
    """Mitsuba's ``principled`` BSDF with our material's parameters (see CONVENTIONS)."""
    m = material
    return {"type": "principled",
            "base_color": {"type": "rgb", "value": [float(c) for c in m.base_color]},
            "metallic": float(m.metallic), "specular": float(m.specular),
            "spec_tint": float(m.specular_tint), "roughness": float(m.roughness),
            "anisotropic": float(m.anisotropic), "sheen": float(m.sheen),
            "sheen_tint": float(m.sheen_tint), "clearcoat": float(m.clearcoat),
            "clearcoat_gloss": float(m.clearcoat_gloss), "spec_trans": 0.0}


def _mesh(mi, name, vertices, faces, normals=None, uvs=None, bsdf=None, emitter=None):
    mesh = mi.Mesh(name, vertex_count=len(vertices), face_count=len(faces),
                   has_vertex_normals=normals is not None, has_vertex_texcoords=uvs is not None,
                   props=_props(mi, bsdf, emitter))
    params = mi.traverse(mesh)
    params["vertex_positions"] = np.ascontiguousarray(vertices, np.float32).ravel()
    params["faces"] = np.ascontiguousarray(faces, np.uint32).ravel()
    if uvs is not None:
        params["vertex_texcoords"] = np.ascontiguousarray(uvs, np.float32).ravel()
    params.update()
    if normals is not None:             # after the positions: their update recomputes normals
        params = mi.traverse(mesh)
        params["vertex_normals"] = np.ascontiguousarray(normals, np.float32).ravel()
        params.update()
    return mesh


def _props(mi, bsdf, emitter):
    props = mi.Properties()
    if bsdf is not None:
        props["bsdf"] = mi.load_dict(bsdf)
    if emitter is not None:
        props["emitter"] = mi.load_dict(emitter)
    return props


@dataclass
class Reference:
    image: np.ndarray          # (h, w, 3) linear radiance, the mean of the two halves
    halves: tuple              # the two independent half-spp images
    spp: int
    seconds: float             # render time, scene loading excluded

    def noise_floor(self, mask=None, pool: int = 1) -> float:
        """Relative RMSE of this reference against the truth, estimated from its halves
        (RMSE(a - b) / 2 is the RMSE of their mean, for independent noise)."""
        from app.bench.image_metrics import relative_rmse
        a, b = self.halves
        return 0.5 * relative_rmse(a, b, mask, pool, reference_image=self.image)


def build_scene(cloud: PointCloud, mesh, material, camera: Camera, side: float,
                max_depth: int = 2, emitter_scale: float = 1.0, catcher=None):
    """The Mitsuba scene object (loading it is the slow part: keep it out of timings).
    ``mesh`` None: no asset (the catcher's unshadowed image). ``catcher``: (x0, x1, z0, z1, y,
    albedo), a diffuse rectangle facing up at height y - a shadow catcher over the scan's
    floor (it hides the floor's emitting squares just below it)."""
    mi = _mitsuba()
    v, f, uv, atlas = cloud_squares(cloud.positions, cloud.normals, cloud.colors, side)
    radiance = {"type": "bitmap", "bitmap": mi.Bitmap(np.ascontiguousarray(atlas * emitter_scale)),
                "filter_type": "nearest", "raw": True, "wrap_mode": "clamp"}
    room = _mesh(mi, "room", v, f, uvs=uv,
                 bsdf={"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0] * 3}},
                 emitter={"type": "area", "radiance": radiance})
    shapes = {"room": room}
    if mesh is not None:
        shapes["asset"] = _mesh(mi, "asset", mesh.positions, mesh.indices, normals=mesh.normals,
                                bsdf=principled_dict(material))
    if catcher is not None:
        x0, x1, z0, z1, y, albedo = catcher
        quad = np.array([[x0, y, z0], [x0, y, z1], [x1, y, z1], [x1, y, z0]], np.float64)
        shapes["catcher"] = _mesh(mi, "catcher", quad, np.array([[0, 1, 2], [0, 2, 3]]),
                                  normals=np.tile([0.0, 1.0, 0.0], (4, 1)),
                                  bsdf={"type": "diffuse", "reflectance":
                                        {"type": "rgb", "value": [float(albedo)] * 3}})
    up = camera.up
    sensor = {"type": "perspective", "fov": float(camera.fov_y_deg), "fov_axis": "y",
              "near_clip": 1e-3, "far_clip": 1e4,
              "to_world": mi.ScalarTransform4f().look_at(
                  origin=[float(x) for x in camera.position],
                  target=[float(x) for x in camera.look_at], up=[float(x) for x in up]),
              "film": {"type": "hdrfilm", "width": int(camera.width),
                       "height": int(camera.height), "rfilter": {"type": "box"},
                       "pixel_format": "rgb"},
              "sampler": {"type": "independent", "sample_count": 1}}
    return mi.load_dict({"type": "scene", "integrator": {"type": "path", "max_depth": max_depth,
                                                         "hide_emitters": False},
                         "sensor": sensor, **shapes})


def render_reference(scene, spp: int, seed: int = 0) -> Reference:
    """Two independent halves of ``spp`` samples per pixel; their mean is the reference."""
    mi = _mitsuba()
    halves = []
    t0 = time.perf_counter()
    for k in range(2):
        img = mi.render(scene, spp=max(spp // 2, 1), seed=seed * 2 + k)
        halves.append(np.array(img, dtype=np.float32)[..., :3])
    seconds = time.perf_counter() - t0
    return Reference(0.5 * (halves[0] + halves[1]), tuple(halves), spp, seconds)


def read_index(directory, maker: str) -> dict:
    """A references folder's index (references.json); missing: one line naming ``maker``, the
    script that renders them."""
    import json
    from pathlib import Path

    from app.errors import ScanlightError
    path = Path(directory) / "references.json"
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        raise ScanlightError(path, f"no reference index: run {maker}") from None


def read_reference(path) -> np.ndarray:
    """A committed reference image as float32 (h, w, 3) linear radiance."""
    from app.io.exr import read_exr
    return np.asarray(read_exr(path).rgb, dtype=np.float32)
