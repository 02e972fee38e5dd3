"""CPU reference for small cases: Monte Carlo final gather against the cloud as emitting discs,
with exact nearest-hit visibility. Independent of every shader (numpy/scipy only); speed is not
its job - cost is O(pixels x samples x discs).

Scene model
- Each cloud point is a flat disc: centre = position, normal = point normal, radius
  ``disc_radius`` (scalar or per point; default: ``estimate_disc_radius``).
- Discs are ONE-SIDED emitters by default (``backface="black"``): a scan only observed the
  side facing the scanner, so the colour is the radiance leaving the front (normal side); the
  back of a disc is an opaque surface that emits nothing (the back of a wall is not the room).
  ``"emit"`` makes them two-sided; ``"cull"`` makes back-facing discs transparent, as the
  Classic PBGI's normal-cone back-face culling does (for like-for-like comparisons).
- Rays that hit nothing return ``background`` (radiance, default 0).
- Only the cloud occludes: the receiving object does not shadow itself (as in a gather over
  the cloud's BSH).

G-buffer (dict of arrays with a common leading shape, (H, W) or (P,)):
  "position" (..., 3) world; "normal" (..., 3) unit shading normal; "view" (..., 3) unit
  direction FROM the surface TO the eye (w_o); optional "tangent" (..., 3) (anisotropy axis;
  Gram-Schmidt-ed against the normal, Duff basis when missing); "params" (..., 13) or (13,)
  Disney parameters packed as app.pbgi.brdf.PARAM_NAMES, or "material" (a Material);
  optional "mask" (...) bool, False pixels return 0.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from app.pbgi.brdf import (PARAM_COUNT, pack_params, principled_brdf, sample_cosine,
                           sample_mixture, tangent_frame)

BACKFACE_MODES = ("black", "emit", "cull")
_PIXELS_PER_RNG_BLOCK = 64  # random numbers are drawn per fixed block: results do not depend
                            # on the memory chunking below
_CHUNK_ELEMS = 1 << 21      # rays x discs per brute-force batch (~16 MB per float64 array)


def estimate_disc_radius(positions, k: int = 4) -> float:
    """A disc radius that closes the gaps between points: the median distance to the k-th
    nearest neighbour. On a square or hexagonal grid of spacing h this is h (covering needs
    0.71 h and 0.58 h); jittered scans have larger holes, hence the margin. Overlap is harmless
    to a nearest-hit reference."""
    pts = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    if len(pts) < 2:
        raise ValueError("need at least two points to estimate a disc radius")
    k = min(k, len(pts) - 1)
    dist, _ = cKDTree(pts).query(pts, k=k + 1)
    return float(np.median(dist[:, k]))


def nearest_disc_hit(origins, dirs, centres, normals, radius, t_min: float = 0.0,
                     front_only: bool = False, chunk_elems: int = _CHUNK_ELEMS):
    """Exact nearest intersection of rays with discs, brute force in batches.

    Returns (index (R,) int64, -1 where nothing is hit; t (R,), inf on a miss; front (R,) bool:
    the ray arrives on the disc's normal side). Discs seen exactly edge-on are missed;
    ``front_only`` ignores discs seen from behind (back-face culling).
    """
    o = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
    d = np.asarray(dirs, dtype=np.float64).reshape(-1, 3)
    c = np.asarray(centres, dtype=np.float64).reshape(-1, 3)
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    r2 = np.broadcast_to(np.asarray(radius, dtype=np.float64) ** 2, (len(c),))
    idx = np.full(len(o), -1, dtype=np.int64)
    t_hit = np.full(len(o), np.inf)
    if len(c) == 0 or len(o) == 0:
        return idx, t_hit, np.zeros(len(o), dtype=bool)
    cn = np.sum(c * n, axis=1)
    cc = np.sum(c * c, axis=1)
    step = max(1, chunk_elems // len(c))
    for s in range(0, len(o), step):
        oo, dd = o[s:s + step], d[s:s + step]
        denom = dd @ n.T                                    # d . n
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (cn[None, :] - oo @ n.T) / denom            # plane hit
        # |o + t d - c|^2 = |o - c|^2 + 2 t d.(o - c) + t^2 (d unit)
        oc2 = np.sum(oo * oo, axis=1)[:, None] - 2.0 * (oo @ c.T) + cc[None, :]
        doc = np.sum(dd * oo, axis=1)[:, None] - dd @ c.T
        dist2 = oc2 + 2.0 * t * doc + t * t
        ok = (np.abs(denom) > 1e-12) & (t > t_min) & (dist2 <= r2[None, :])
        if front_only:
            ok &= denom < 0.0
        t = np.where(ok, t, np.inf)
        j = np.argmin(t, axis=1)
        tj = t[np.arange(len(t)), j]
        hit = np.isfinite(tj)
        idx[s:s + step] = np.where(hit, j, -1)
        t_hit[s:s + step] = tj
    front = np.zeros(len(o), dtype=bool)
    h = idx >= 0
    front[h] = np.sum(d[h] * n[idx[h]], axis=1) < 0.0
    return idx, t_hit, front


def lambert_brdf(params, L, V, N, X, Y):
    """base_color / pi above the surface: a Lambertian stand-in for analytic tests."""
    p = np.asarray(params, dtype=np.float64)
    up = (np.sum(N * L, -1) > 0) & (np.sum(N * V, -1) > 0)
    return np.where(up[..., None], np.clip(p[..., 0:3], 0.0, 1.0) / np.pi, 0.0)


def _gbuffer_arrays(gbuffer: dict):
    pos = np.asarray(gbuffer["position"], dtype=np.float64)
    if pos.shape[-1] != 3:
        raise ValueError(f"gbuffer['position'] must be (..., 3), got {pos.shape}")
    lead = pos.shape[:-1]
    P = int(np.prod(lead)) if lead else 1

    def field3(name):
        a = np.asarray(gbuffer[name], dtype=np.float64)
        return np.broadcast_to(a, lead + (3,)).reshape(P, 3)

    mask = gbuffer.get("mask")
    mask = (np.ones(P, bool) if mask is None
            else np.broadcast_to(np.asarray(mask, bool), lead).reshape(P))
    # Empty pixels may hold anything (NaN, zeros): give them a harmless dummy receiver.
    up = np.array([0.0, 0.0, 1.0])
    pos = np.where(mask[:, None], pos.reshape(P, 3), 0.0)
    nrm = np.where(mask[:, None], field3("normal"), up)
    nrm = nrm / np.linalg.norm(nrm, axis=1, keepdims=True)
    view = np.where(mask[:, None], field3("view"), up)
    view = view / np.linalg.norm(view, axis=1, keepdims=True)
    tangent = field3("tangent") if gbuffer.get("tangent") is not None else None
    X, Y = tangent_frame(nrm, None if tangent is None else np.where(mask[:, None], tangent, 0.0))
    if "params" in gbuffer:
        params = np.asarray(gbuffer["params"], dtype=np.float64)
    else:
        params = pack_params(gbuffer.get("material"))
    if params.shape[-1] != PARAM_COUNT:
        raise ValueError(f"gbuffer['params'] must be (..., {PARAM_COUNT}), got {params.shape}")
    params = np.broadcast_to(params, lead + (PARAM_COUNT,)).reshape(P, PARAM_COUNT)
    params = np.where(mask[:, None], params, 0.0)
    return lead, pos, nrm, view, X, Y, params, mask


def reference_render(gbuffer: dict, cloud_positions, cloud_normals, cloud_colors,
                     disc_radius=None, n_samples: int = 256, seed: int = 0,
                     background=0.0, backface: str = "black", sampling: str = "cosine",
                     brdf=None, t_min: float | None = None, return_stderr: bool = False):
    """Outgoing radiance L_o (lead shape + (3,)) per G-buffer pixel:
    L_o = 1/n sum f(w_i, w_o) L_i(w_i) (n . w_i) / pdf(w_i), with L_i from the nearest disc.

    sampling: "cosine" (pdf = cos / pi; the estimator is pi f L_i) or "mixture" (cosine + GGX
    visible normals + GTR1, app.pbgi.brdf.sample_mixture; far less noise on glossy materials).
    brdf: callable(params, L, V, N, X, Y) -> (..., 3); default the Disney Principled BRDF.
    t_min: minimum hit distance (default 1e-6 of the cloud's bounding-box diagonal).
    return_stderr: also return the per-pixel standard error of the mean.
    Fixed ``seed``: the same inputs give bit-identical outputs.
    """
    if backface not in BACKFACE_MODES:
        raise ValueError(f"backface must be one of {BACKFACE_MODES}, got {backface!r}")
    if sampling not in ("cosine", "mixture"):
        raise ValueError(f"sampling must be 'cosine' or 'mixture', got {sampling!r}")
    if n_samples < 1:
        raise ValueError("n_samples must be >= 1")
    brdf = principled_brdf if brdf is None else brdf
    lead, pos, nrm, view, X, Y, params, mask = _gbuffer_arrays(gbuffer)
    cpos = np.asarray(cloud_positions, dtype=np.float64).reshape(-1, 3)
    cnrm = np.asarray(cloud_normals, dtype=np.float64).reshape(-1, 3)
    ccol = np.asarray(cloud_colors, dtype=np.float64).reshape(-1, 3)
    if not (len(cpos) == len(cnrm) == len(ccol)):
        raise ValueError("cloud positions, normals and colours differ in length")
    cnrm = cnrm / np.maximum(np.linalg.norm(cnrm, axis=1, keepdims=True), 1e-300)
    radius = estimate_disc_radius(cpos) if disc_radius is None else disc_radius
    # Work relative to the cloud's centre: the |o - c|^2 expansion keeps its precision even for
    # scans far from the origin.
    centre = cpos.mean(axis=0) if len(cpos) else np.zeros(3)
    cpos_c, pos_c = cpos - centre, pos - centre
    if t_min is None:
        ext = np.ptp(cpos, axis=0) if len(cpos) else np.ones(3)
        t_min = 1e-6 * max(float(np.linalg.norm(ext)), 1e-12)
    bg = np.broadcast_to(np.asarray(background, dtype=np.float64), (3,))

    P = len(pos)
    out = np.zeros((P, 3))
    err = np.zeros((P, 3))
    for b0 in range(0, P, _PIXELS_PER_RNG_BLOCK):
        sl = slice(b0, min(P, b0 + _PIXELS_PER_RNG_BLOCK))
        rng = np.random.default_rng([seed, b0 // _PIXELS_PER_RNG_BLOCK])
        m = len(range(*sl.indices(P)))
        Nb, Xb, Yb, Vb = (a[sl][:, None, :] for a in (nrm, X, Y, view))
        pb = params[sl][:, None, :]
        if sampling == "cosine":
            u1, u2 = rng.random((2, m, n_samples))
            loc = sample_cosine(u1, u2)
            pdf = loc[..., 2] / np.pi
        else:
            v_loc = np.stack([np.sum(Vb * Xb, -1), np.sum(Vb * Yb, -1), np.sum(Vb * Nb, -1)], -1)
            loc, pdf, _ = sample_mixture(np.broadcast_to(pb, (m, n_samples, PARAM_COUNT)),
                                         np.broadcast_to(v_loc, (m, n_samples, 3)), rng)
        wi = loc[..., 0:1] * Xb + loc[..., 1:2] * Yb + loc[..., 2:3] * Nb
        wi = wi / np.linalg.norm(wi, axis=-1, keepdims=True)
        cos = np.sum(wi * Nb, -1)
        usable = (pdf > 0) & (cos > 0)
        weight = np.where(usable, cos / np.where(usable, pdf, 1.0), 0.0)
        f = brdf(pb, wi, Vb, Nb, Xb, Yb)

        origins = np.broadcast_to(pos_c[sl][:, None, :], wi.shape)
        idx, _, front = nearest_disc_hit(origins.reshape(-1, 3), wi.reshape(-1, 3), cpos_c,
                                         cnrm, radius, t_min, front_only=backface == "cull")
        li = np.where((idx < 0)[:, None], bg[None, :], ccol[np.maximum(idx, 0)])
        if backface == "black":
            li = np.where(((idx >= 0) & ~front)[:, None], 0.0, li)
        li = li.reshape(m, n_samples, 3)
        est = f * li * weight[..., None]
        out[sl] = est.mean(axis=1)
        if n_samples > 1:
            err[sl] = est.std(axis=1, ddof=1) / np.sqrt(n_samples)
    out[~mask] = 0.0
    err[~mask] = 0.0
    out = out.reshape(lead + (3,))
    return (out, err.reshape(lead + (3,))) if return_stderr else out
