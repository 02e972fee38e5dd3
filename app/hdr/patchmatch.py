"""Generalised PatchMatch (Barnes et al. 2010): a nearest-neighbour field over translation,
rotation and scale from every pixel of image A to image B, with an SSD quality field.

Vectorised over all pixels: each step proposes one candidate transform per pixel and keeps it
where its patch distance is lower, so the Python loop runs over steps, never over pixels. The
serial scan-order propagation of the original becomes parallel propagation from the four
neighbours (as GPU PatchMatch does), which carries a good match one pixel per step, so the search
runs coarse to fine on an image pyramid: at the coarse levels a patch covers enough context to tell
apart two regions that clip to the same white (a lamp and a window), and the finer levels refine.

Coordinates: pixel (row i, column j) has its centre at (x, y) = (j, i). A transform maps the
patch offset (u, v) around an A pixel to B at c + s * R(theta) @ (u, v).
Patch distance: sum over the patch samples (a (2r+1)^2 grid, or every ``stride``-th of it) and the
channels of squared differences, scaled to a dense 7x7 patch (so the paper's threshold th = 1
means the same whatever the sampling: an RMS difference of 0.14 per value in luminance, 0.08 in
RGB);
B is sampled at the nearest pixel (bilinear=True: interpolated, several times slower and no
better in our tests), clamped to the border: a lamp cut by the photo's frame is taken to
continue beyond it (penalising outside samples left the cut-off part of the demo's ceiling lamp
unmatched).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

CHUNK = 4096
REFERENCE_SAMPLES = 49  # costs are scaled to the SSD of a dense 7x7 patch with the same mean error


@dataclass
class NNField:
    """Per A pixel: the matched B centre (x, y), angle (radians), scale and SSD cost; ``flat``
    marks the pixels whose whole patch is clipped (their SSD is no evidence, see evidence_cost)."""

    x: np.ndarray
    y: np.ndarray
    angle: np.ndarray
    scale: np.ndarray
    cost: np.ndarray
    flat: np.ndarray | None = None

    def map(self, ax: np.ndarray, ay: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """B positions of continuous A positions, through the nearest pixel's transform."""
        h, w = self.x.shape
        j = np.clip(np.rint(ax), 0, w - 1).astype(np.int64)
        i = np.clip(np.rint(ay), 0, h - 1).astype(np.int64)
        du, dv = ax - j, ay - i
        c, s = np.cos(self.angle[i, j]), np.sin(self.angle[i, j])
        sc = self.scale[i, j]
        return (self.x[i, j] + sc * (c * du - s * dv), self.y[i, j] + sc * (s * du + c * dv))


def downsample2(img: np.ndarray) -> np.ndarray:
    """Half resolution by 2x2 box averaging (an odd last row/column is dropped)."""
    h, w = img.shape[0] // 2 * 2, img.shape[1] // 2 * 2
    a = img[:h, :w]
    return 0.25 * (a[0::2, 0::2] + a[1::2, 0::2] + a[0::2, 1::2] + a[1::2, 1::2])


def resize_area(img: np.ndarray, max_size: int) -> tuple[np.ndarray, float]:
    """Box-downsample by an integer factor so that the larger side is <= max_size.

    Returns the image and the factor f (a pixel centre x in the result is f*x + (f-1)/2 in the
    input)."""
    h, w = img.shape[:2]
    f = max(1, int(np.ceil(max(h, w) / max_size)))
    if f == 1:
        return img.astype(np.float32), 1.0
    hh, ww = h // f * f, w // f * f
    a = img[:hh, :ww].reshape(hh // f, f, ww // f, f, *img.shape[2:])
    return a.mean(axis=(1, 3)).astype(np.float32), float(f)


class _Matcher:
    """Patch distances from A to B for whole candidate fields (one level of the pyramid)."""

    def __init__(self, a: np.ndarray, b: np.ndarray, radius: int, stride: int = 1,
                 bilinear: bool = False):
        self.bilinear = bilinear
        self.h, self.w = a.shape[:2]
        self.hb, self.wb = b.shape[:2]
        self.b = [np.ascontiguousarray(b[..., ch].ravel(), dtype=np.float32)
                  for ch in range(b.shape[2])]
        r = radius
        pad = np.pad(a, ((r, r), (r, r), (0, 0)), mode="edge")
        steps = range(-r, r + 1, stride)
        offs = [(u, v) for v in steps for u in steps]
        self.u = np.array([o[0] for o in offs], dtype=np.float32)[:, None]
        self.v = np.array([o[1] for o in offs], dtype=np.float32)[:, None]
        # per pixel block and channel, (P, block): the A patch samples, fixed for the whole search;
        # blocks of CHUNK pixels keep the (P, block) temporaries in cache (faster than
        # whole-image arrays)
        n = self.h * self.w
        planes = [np.stack([pad[r + v:r + v + self.h, r + u:r + u + self.w, ch].ravel()
                            for u, v in offs]).astype(np.float32) for ch in range(a.shape[2])]
        self.blocks = [(slice(i, min(i + CHUNK, n)),
                        [np.ascontiguousarray(p[:, i:i + CHUNK]) for p in planes])
                       for i in range(0, n, CHUNK)]
        self.norm = np.float32(REFERENCE_SAMPLES / len(offs))

    def cost(self, x, y, angle, scale) -> np.ndarray:
        """SSD of the candidate transforms (flat arrays, one per A pixel)."""
        c_all = (scale * np.cos(angle)).astype(np.float32)
        s_all = (scale * np.sin(angle)).astype(np.float32)
        x = x.astype(np.float32)
        y = y.astype(np.float32)
        wb, hb = self.wb, self.hb
        total = np.empty(len(x), dtype=np.float32)
        for sl, a_off in self.blocks:
            c, s = c_all[None, sl], s_all[None, sl]
            bx = x[None, sl] + c * self.u
            bx -= s * self.v
            by = y[None, sl] + s * self.u
            by += c * self.v
            np.clip(bx, 0, wb - 1, out=bx)
            np.clip(by, 0, hb - 1, out=by)
            t = np.zeros(bx.shape[1], dtype=np.float32)
            if self.bilinear:
                x0 = np.minimum(bx.astype(np.int32), wb - 2)
                y0 = np.minimum(by.astype(np.int32), hb - 2)
                fx = bx - x0
                fy = by - y0
                k = y0 * wb + x0
                for bc, ac in zip(self.b, a_off):
                    top = np.take(bc, k)
                    top += fx * (np.take(bc, k + 1) - top)
                    bot = np.take(bc, k + wb)
                    bot += fx * (np.take(bc, k + wb + 1) - bot)
                    top += fy * (bot - top)
                    top -= ac
                    t += np.einsum("pn,pn->n", top, top)
            else:
                bx += 0.5
                by += 0.5
                k = by.astype(np.int32)
                k *= wb
                k += bx.astype(np.int32)
                for bc, ac in zip(self.b, a_off):
                    d = np.take(bc, k)
                    d -= ac
                    t += np.einsum("pn,pn->n", d, d)
            total[sl] = t
        total *= self.norm
        return total


def _clamp_centres(x, y, wb, hb):
    return np.clip(x, 0, wb - 1), np.clip(y, 0, hb - 1)


def _improve(state, cand, cost, keep_ties=False):
    better = cost <= state[4] if keep_ties else cost < state[4]
    for k in range(4):
        state[k] = np.where(better, cand[k], state[k])
    state[4] = np.where(better, cost, state[4])
    return int(better.sum())


def _propagate(m: _Matcher, state, jump: int):
    """Candidates from the neighbours ``jump`` pixels away in the four directions."""
    h, w = m.h, m.w
    x, y, ang, sc, _ = (a.reshape(h, w) for a in state)
    for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        # the neighbour q = p - jump*(dx, dy) proposes its transform, extended to p
        src_i = np.clip(np.arange(h) - jump * dy, 0, h - 1)
        src_j = np.clip(np.arange(w) - jump * dx, 0, w - 1)
        qx, qy = x[src_i][:, src_j], y[src_i][:, src_j]
        qa, qs = ang[src_i][:, src_j], sc[src_i][:, src_j]
        # offset from q to p in A pixels (0 at the border, where q == p)
        ou = (np.arange(w)[None, :] - src_j[None, :]).astype(np.float32)
        ov = (np.arange(h)[:, None] - src_i[:, None]).astype(np.float32)
        ou, ov = np.broadcast_to(ou, (h, w)), np.broadcast_to(ov, (h, w))
        c, s = np.cos(qa), np.sin(qa)
        cx = qx + qs * (c * ou - s * ov)
        cy = qy + qs * (s * ou + c * ov)
        cx, cy = _clamp_centres(cx, cy, m.wb, m.hb)
        cand = [cx.ravel(), cy.ravel(), qa.ravel(), qs.ravel()]
        _improve(state, cand, m.cost(*cand), keep_ties=True)


def _random_search(m: _Matcher, state, rng, log_scale_range, angle_range, min_radius=1.0,
                   shape_trials=4):
    """Barnes et al.'s exponentially shrinking random search, split in two: the matched position
    (radius halving from the size of B to a pixel), then the rotation and scale about the matched
    centre (halving from half their range). Perturbing all four at once almost never improves a
    match that is already close, which left the scale biased."""
    n = len(state[0])
    radius = float(max(m.wb, m.hb))
    while radius >= min_radius:
        cx = state[0] + radius * rng.uniform(-1, 1, n).astype(np.float32)
        cy = state[1] + radius * rng.uniform(-1, 1, n).astype(np.float32)
        cx, cy = _clamp_centres(cx, cy, m.wb, m.hb)
        cand = [cx, cy, state[2], state[3]]
        _improve(state, cand, m.cost(*cand))
        radius *= 0.5
    lo, hi = log_scale_range
    f = 0.5
    for _ in range(shape_trials):
        ca = state[2] + angle_range * f * rng.uniform(-1, 1, n).astype(np.float32)
        ls = np.clip(np.log(state[3]) + (hi - lo) * f * rng.uniform(-1, 1, n), lo, hi)
        cand = [state[0], state[1], ca.astype(np.float32), np.exp(ls).astype(np.float32)]
        _improve(state, cand, m.cost(*cand))
        f *= 0.5


def _fill_flat(m: _Matcher, state, flat: np.ndarray, tol: float):
    """Give pixels whose patch holds no information (all clipped) the transform of the nearest
    informative pixel, extended to them, where it matches about as well.

    Inside a clipped region every white patch of B is a perfect match, so the search alone
    scatters such pixels over all the white areas of the photo (a lamp taking a window's
    radiance). The patches on the region's border see its shape and surroundings; their
    similarity transform, extended inwards, is the coherent answer."""
    if not flat.any() or flat.all():
        return
    from scipy.ndimage import distance_transform_edt

    h, w = m.h, m.w
    _, (qi, qj) = distance_transform_edt(flat, return_indices=True)
    x, y, ang, sc, cost = (a.reshape(h, w) for a in state)
    pi, pj = np.nonzero(flat)
    qi, qj = qi[pi, pj], qj[pi, pj]
    c, s = np.cos(ang[qi, qj]), np.sin(ang[qi, qj])
    du, dv = (pj - qj).astype(np.float32), (pi - qi).astype(np.float32)
    cx = x[qi, qj] + sc[qi, qj] * (c * du - s * dv)
    cy = y[qi, qj] + sc[qi, qj] * (s * du + c * dv)
    cx, cy = _clamp_centres(cx, cy, m.wb, m.hb)
    flat_idx = pi * w + pj
    cand = [a.copy() for a in state[:4]]
    cand[0][flat_idx], cand[1][flat_idx] = cx, cy
    cand[2][flat_idx], cand[3][flat_idx] = ang[qi, qj], sc[qi, qj]
    new_cost = m.cost(*cand)
    ok = np.zeros(h * w, dtype=bool)
    ok[flat_idx] = new_cost[flat_idx] <= state[4][flat_idx] + tol
    for k in range(4):
        state[k] = np.where(ok, cand[k], state[k])
    state[4] = np.where(ok, new_cost, state[4])


def _flat_mask(a: np.ndarray, radius: int, level: float) -> np.ndarray:
    """Pixels whose whole patch is clipped (every channel >= level)."""
    from scipy.ndimage import minimum_filter

    return minimum_filter(a.min(axis=2), size=2 * radius + 1, mode="nearest") >= level


def patchmatch(a: np.ndarray, b: np.ndarray, patch_radius: int = 3, patch_stride: int = 1,
               iterations: int = 4,
               levels: int = 3, scale_range: tuple[float, float] = (0.33, 3.0),
               angle_range: float = np.pi, angle_init: float | None = None, seed: int = 0,
               clip_level: float | None = 0.99, flat_tol: float = 0.05, bilinear: bool = False,
               coarse_samples: int = 64, coarse_iterations: int | None = None,
               cancel=None, progress=None) -> NNField:
    """The NNF from ``a`` (H, W[, C]) to ``b`` (Hb, Wb[, C]), coarse to fine over ``levels``.

    ``angle_init``: a prior rotation tried at initialisation besides random ones (e.g. pi for
    the upside-down side faces of an OpenGL cube map against an upright photo).
    ``clip_level``: pixels whose whole patch is at least this bright are clipped and carry no
    information; they take the transform of the nearest informative pixel (see _fill_flat)
    when it matches within ``flat_tol``. None disables this.
    ``coarse_samples``: random transforms tried per pixel at the coarsest level, where a pixel
    costs little and a right guess anywhere is then spread by jump-flooding propagation
    (``coarse_iterations``, default 2 x ``iterations``, every one with jumps 8, 4, 2, 1).
    Without them the four-parameter search found the transform in only some runs.
    """
    a = np.asarray(a, dtype=np.float32)
    b = np.asarray(b, dtype=np.float32)
    if a.ndim == 2:
        a = a[..., None]
    if b.ndim == 2:
        b = b[..., None]
    rng = np.random.default_rng(seed)
    log_range = (float(np.log(scale_range[0])), float(np.log(scale_range[1])))
    pa, pb = [a], [b]
    for _ in range(levels - 1):
        if min(pa[-1].shape[:2]) < 4 * (2 * patch_radius + 1) or min(pb[-1].shape[:2]) < 8:
            break
        pa.append(downsample2(pa[-1]))
        pb.append(downsample2(pb[-1]))
    state = None
    n_levels = len(pa)
    for lev in range(n_levels - 1, -1, -1):
        m = _Matcher(pa[lev], pb[lev], patch_radius, patch_stride, bilinear)
        n = m.h * m.w
        if state is None:
            state = [rng.uniform(0, m.wb - 1, n).astype(np.float32),
                     rng.uniform(0, m.hb - 1, n).astype(np.float32),
                     rng.uniform(-np.pi, np.pi, n).astype(np.float32),
                     np.exp(rng.uniform(*log_range, n)).astype(np.float32)]
            state.append(m.cost(*state))
            for k in range(max(coarse_samples - 1, 0)):
                prior = angle_init is not None and k % 2 == 0  # half the tries use the prior
                cand = [rng.uniform(0, m.wb - 1, n).astype(np.float32),
                        rng.uniform(0, m.hb - 1, n).astype(np.float32),
                        (np.full(n, angle_init) + rng.normal(0, 0.1, n) if prior
                         else rng.uniform(-np.pi, np.pi, n)).astype(np.float32),
                        np.exp(rng.uniform(*log_range, n)).astype(np.float32)]
                _improve(state, cand, m.cost(*cand))
        else:
            state = _upsample(state, prev_shape, (m.h, m.w), m.wb, m.hb)
            state.append(m.cost(*state[:4]))
        coarsest = lev == n_levels - 1
        n_it = (coarse_iterations or 2 * iterations) if coarsest else iterations
        for it in range(n_it):
            if cancel is not None:
                cancel()
            for jump in ((8, 4, 2, 1) if it == 0 or coarsest else (1,)):
                _propagate(m, state, jump)
            _random_search(m, state, rng, log_range, angle_range)
            if clip_level is not None:
                _fill_flat(m, state, _flat_mask(pa[lev], patch_radius, clip_level), flat_tol)
            if progress is not None:
                done = (n_levels - 1 - lev) + (it + 1) / n_it
                progress(done / n_levels)
        prev_shape = (m.h, m.w)
    h, w = pa[0].shape[:2]
    x, y, ang, sc, cost = (s.reshape(h, w) for s in state)
    flat = _flat_mask(pa[0], patch_radius, clip_level) if clip_level is not None else None
    return NNField(x, y, np.mod(ang + np.pi, 2 * np.pi) - np.pi, sc, cost, flat)


def evidence_cost(cost: np.ndarray, flat: np.ndarray) -> np.ndarray:
    """The quality of a clipped pixel is that of the nearest pixel that carries information.

    A white patch matches any white patch with SSD 0, so its own SSD says nothing: a lamp of the
    room that the photo does not show would be matched, with perfect quality, to the one lamp the
    photo does show. Its border patches do tell: if they match badly, so does it."""
    if not flat.any() or flat.all():
        return cost
    from scipy.ndimage import distance_transform_edt

    _, (qi, qj) = distance_transform_edt(flat, return_indices=True)
    return np.where(flat, np.maximum(cost, cost[qi, qj]), cost)


def _upsample(state, coarse_shape, fine_shape, wb, hb):
    """A coarse field as the initial fine field: coarse X = (x - 0.5) / 2, fine x = 2 X + 0.5."""
    hc, wc = coarse_shape
    h, w = fine_shape
    fx = ((np.arange(w) - 0.5) / 2)[None, :].repeat(h, 0)
    fy = ((np.arange(h) - 0.5) / 2)[:, None].repeat(w, 1)
    field = NNField(*(s.reshape(hc, wc) for s in state))
    bx, by = field.map(fx, fy)
    j = np.clip(np.rint(fx), 0, wc - 1).astype(np.int64)
    i = np.clip(np.rint(fy), 0, hc - 1).astype(np.int64)
    x, y = _clamp_centres(2 * bx + 0.5, 2 * by + 0.5, wb, hb)
    return [x.ravel().astype(np.float32), y.ravel().astype(np.float32),
            field.angle[i, j].ravel(), field.scale[i, j].ravel()]
