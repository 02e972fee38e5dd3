"""Box-filtered silhouettes (app/pbgi/antialias.py, ``Relighter.render_passes(edge_samples=)``):
the pixels a silhouette crosses are found, get their extra samples there only, and their alpha
becomes the covered fraction - checked against the mesh's coverage computed here by ray casting."""

from __future__ import annotations

import numpy as np
import pytest

from tests.support import scenes as S
from app.pbgi.antialias import silhouette_pixels
from app.pbgi.renderer import RenderParams

CAM = S.look((0.0, 0.9, 1.1), (0.0, 0.8, 0.0), 48, 40)


def test_silhouette_pixels_are_the_outline_and_the_depth_jumps():
    """A covered square with a step in depth inside: the outline (both sides of it) and the
    step are marked, the flat inside and the empty outside are not."""
    alpha = np.zeros((12, 12))
    alpha[3:9, 3:9] = 1.0
    depth = np.full((12, 12), np.inf)
    depth[3:9, 3:9] = 2.0
    depth[3:9, 6:9] = 3.0                      # the right half further away: an inner edge
    edges = silhouette_pixels(alpha, depth)
    ring = np.zeros((12, 12), bool)
    ring[2:10, 2:10] = True
    ring[4:8, 4:8] = False
    assert (edges[ring]).all()
    assert edges[4:8, 5:7].all()               # both sides of the step
    assert not edges[4:8, 4].any() and not edges[4:8, 7].any()
    assert not edges[:1].any() and not edges[11:].any()
    smooth = depth.copy()
    smooth[3:9, 3:9] = 2.0 + 0.01 * np.arange(6)   # a gentle slope is no edge
    assert not silhouette_pixels(alpha, smooth)[4:8, 4:8].any()


def _sub_rays(cam, px, n):
    """n x n ray directions inside each pixel (row, col) of ``px``, (len(px), n*n, 3)."""
    r, u, f = cam.basis()
    t = np.tan(np.radians(cam.fov_y_deg) / 2)
    sub = (np.arange(n) + 0.5) / n
    sx, sy = np.meshgrid(sub, sub)
    x = ((px[:, 1:2] + sx.ravel()) / cam.width * 2 - 1) * t * cam.aspect
    y = (1 - (px[:, 0:1] + sy.ravel()) / cam.height * 2) * t
    d = f + x[..., None] * r + y[..., None] * u
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def _exact_coverage(cam, mesh, n=16) -> np.ndarray:
    """The mesh's covered fraction of each pixel, n x n rays per pixel intersected with its
    triangles (Moller-Trumbore, numpy), on the pixels the bounding sphere's outline crosses
    (elsewhere the pixel is all in or all out, decided by its centre)."""
    tri = mesh.positions[mesh.indices.astype(np.int64)]
    c = tri.reshape(-1, 3).mean(axis=0)
    rad = np.linalg.norm(tri.reshape(-1, 3) - c, axis=1).max()
    cov = np.zeros((cam.height, cam.width))
    rows, cols = np.mgrid[0:cam.height, 0:cam.width]
    px = np.stack([rows.ravel(), cols.ravel()], axis=1)
    centre = _sub_rays(cam, px, 1)[:, 0]
    oc = cam.position - c
    b = centre @ oc
    dist = np.sqrt(np.maximum(oc @ oc - b * b, 0))         # ray to sphere-centre distance
    pix_angle = 2 * np.tan(np.radians(cam.fov_y_deg) / 2) / cam.height * np.linalg.norm(oc)
    near = np.abs(dist - rad) < 2.5 * pix_angle
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    for (i, j), rays in zip(px[near], _sub_rays(cam, px[near], n)):
        p = np.cross(rays[:, None], e2[None])                # (rays, tris, 3)
        det = np.einsum("rtk,tk->rt", p, e1)
        tv = cam.position - tri[:, 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            uu = np.einsum("rtk,tk->rt", p, tv) / det
            q = np.cross(tv, e1)
            vv = np.einsum("rk,tk->rt", rays, q) / det
            hit = (uu >= 0) & (vv >= 0) & (uu + vv <= 1) & (np.abs(det) > 1e-12)
        cov[i, j] = hit.any(axis=1).mean()
    inside = ~near.reshape(cam.height, cam.width) & (dist < rad).reshape(cam.height, cam.width)
    cov[inside] = 1.0
    return cov


@pytest.fixture(scope="module")
def scene():
    r = S.sphere_in_box_room(0.1)
    yield r
    r.release()


@pytest.mark.parametrize("mode", ["classic", "hybrid"])
def test_edge_samples_give_true_coverage_and_box_filtered_edges(scene, mode):
    """16 samples on the silhouette: alpha within 0.07 (mean; 1/16 steps) of the mesh's coverage where one
    sample per pixel is 0 or 1 (mean error several times larger); the inside is the one-pass
    image unchanged; the silhouette pixels' radiance equals 16 full passes' (Classic: each
    receiver's walk is its own, so exactly; Hybrid shares far fields between the receivers
    present, so within 2% of the pixel)."""
    mat = S.diffuse(0.6)
    p = RenderParams(mode=mode, microbuffer=16)
    one = scene.render_passes(CAM, [mat], p, 1).image
    aa = scene.render_passes(CAM, [mat], p, 1, edge_samples=16)
    full = scene.render_passes(CAM, [mat], p, 16).image
    exact = _exact_coverage(CAM, scene.mesh)
    edges = (exact > 0) & (exact < 1)
    assert aa.stats.edge_samples == 16 and edges.sum() <= aa.stats.edge_pixels < 0.3 * 48 * 48
    err_aa = np.abs(aa.image[..., 3] - exact)[edges].mean()
    err_one = np.abs(one[..., 3] - exact)[edges].mean()
    assert err_aa < 0.07 and err_one > 3 * err_aa, (err_aa, err_one)
    np.testing.assert_array_equal(aa.image[..., 3], full[..., 3])
    from scipy.ndimage import binary_erosion
    deep = binary_erosion(exact == 1, iterations=5)      # 5 px inside the outline
    assert (aa.image[deep] == one[deep]).all()           # not resampled: the same pixels
    assert (np.abs(aa.image - one).max(axis=-1) > 0).sum() <= aa.stats.edge_pixels
    tol = 1e-4 if mode == "classic" else 0.02
    scale = full[..., :3].max()
    assert np.abs(aa.image[edges, :3] - full[edges, :3]).max() <= tol * scale


def test_edge_samples_under_the_passes_change_nothing(scene):
    """edge_samples <= passes: the plain passes (no silhouette pass)."""
    mat = S.diffuse(0.6)
    p = RenderParams(mode="classic", microbuffer=8)
    a = scene.render_passes(CAM, [mat], p, 2)
    b = scene.render_passes(CAM, [mat], p, 2, edge_samples=2)
    np.testing.assert_array_equal(a.image, b.image)
    assert b.stats.edge_pixels == 0


def test_pass_samples_are_centred_on_the_pixel():
    """Each count of passes samples points whose mean is the pixel's centre (one pass: the
    centre itself), spread over the pixel, all different; a pass outside its count is a bug."""
    from app.pbgi.gbuffer import pass_jitter
    assert pass_jitter(0, 1) == (0.0, 0.0)
    for n in range(2, 65):
        pts = np.array([pass_jitter(k, n) for k in range(n)])
        np.testing.assert_allclose(pts.mean(axis=0), 0.0, atol=1e-12)
        assert np.abs(pts).max() < 0.75 and len({tuple(p) for p in pts}) == n
        assert n < 4 or (pts.std(axis=0) > 0.2).all()     # over the pixel (uniform: 0.29)
    with pytest.raises(ValueError):
        pass_jitter(4, 4)


def _centroid(alpha: np.ndarray) -> np.ndarray:
    ys, xs = np.mgrid[0:alpha.shape[0], 0:alpha.shape[1]]
    return np.array([(alpha * xs).sum(), (alpha * ys).sum()]) / alpha.sum()


@pytest.mark.parametrize("passes, edge_samples", [(2, 1), (4, 1), (8, 1), (1, 8)])
def test_the_mean_of_passes_is_not_a_shifted_image(scene, passes, edge_samples):
    """The asset's coverage after N passes (or N silhouette samples) has its centroid where the
    exactly computed coverage has it, within 0.03 px: the samples' mean is the pixel centre.
    The first N points of the R2 sequence from the centre, unmoved, shifted the whole mean image
    by their mean offset: 0.25 px at 2 passes, 0.19 at 4, 0.11 at 8 - on a glossy sphere the
    mean of 2-8 passes was further from the box-filtered image than one pass (README,
    "Passes")."""
    p = RenderParams(mode="envmap")
    img = scene.render_passes(CAM, [S.diffuse(0.6)], p, passes, edge_samples=edge_samples).image
    exact = _exact_coverage(CAM, scene.mesh)
    shift = _centroid(img[..., 3]) - _centroid(exact)
    assert np.abs(shift).max() < 0.03, shift
