"""Disney Principled BRDF in numpy: the twin of shaders/lib/principled.glsl, used by tests and
by the CPU reference renderer, plus importance sampling and directional albedo.

Same conventions as the GLSL header: unit vectors, L to the light, V to the viewer, X/Y an
orthonormal tangent frame with N; ``principled_brdf`` returns f without the cosine and 0 below
the surface; base colour is linear RGB; alphas are clamped to >= 1e-3. Computed in float64.

Parameters travel as one array of 13 floats per material (``PARAM_NAMES``): base colour RGB,
then app.material.SCALAR_PARAMS in order - exactly the GLSL packing.
"""

from __future__ import annotations

import numpy as np

from app.material import SCALAR_NAMES, Material

PARAM_NAMES = ("base_r", "base_g", "base_b") + SCALAR_NAMES
PARAM_COUNT = len(PARAM_NAMES)  # 13
MIN_ALPHA = 1e-3
LOBES = ("diffuse", "sheen", "specular", "clearcoat")
_IDX = {name: i for i, name in enumerate(PARAM_NAMES)}


def pack_params(material: Material | dict | None = None, **overrides) -> np.ndarray:
    """13 floats (float64) for one material: a Material, a dict of parameter names, or defaults."""
    if isinstance(material, Material):
        d = material.to_dict()
    else:
        d = Material().to_dict()
        d.update(material or {})
    d.update(overrides)
    out = np.empty(PARAM_COUNT, dtype=np.float64)
    out[0:3] = d["base_color"]
    out[3:] = [d[n] for n in SCALAR_NAMES]
    return out


def _dot(a, b):
    return np.sum(a * b, axis=-1)


def _schlick_weight(c):
    m = np.clip(1.0 - c, 0.0, 1.0)
    m2 = m * m
    return m2 * m2 * m


def _mix(a, b, t):
    return a + (b - a) * t


def _smith_ggx(n_dot_v, alpha):
    a, b = alpha * alpha, n_dot_v * n_dot_v
    return 1.0 / (n_dot_v + np.sqrt(a + b - a * b))


def _smith_ggx_aniso(n_dot_v, v_dot_x, v_dot_y, ax, ay):
    return 1.0 / (n_dot_v + np.sqrt((v_dot_x * ax) ** 2 + (v_dot_y * ay) ** 2 + n_dot_v ** 2))


def _gtr2_aniso(n_dot_h, h_dot_x, h_dot_y, ax, ay):
    t = (h_dot_x / ax) ** 2 + (h_dot_y / ay) ** 2 + n_dot_h ** 2
    return 1.0 / (np.pi * ax * ay * t * t)


def _gtr1(n_dot_h, sin2_h, a):
    a2 = a * a
    return (a2 - 1.0) / (np.pi * np.log(a2) * (a2 * n_dot_h ** 2 + sin2_h))


def spec_alphas(params) -> tuple[np.ndarray, np.ndarray]:
    """(ax, ay) of the GGX lobe, as the shader computes them."""
    p = np.asarray(params, dtype=np.float64)
    rough = np.clip(p[..., _IDX["roughness"]], 0.0, 1.0)
    aniso = np.clip(p[..., _IDX["anisotropic"]], 0.0, 1.0)
    aspect = np.sqrt(1.0 - 0.9 * aniso)
    return np.maximum(MIN_ALPHA, rough ** 2 / aspect), np.maximum(MIN_ALPHA, rough ** 2 * aspect)


def clearcoat_alpha(params) -> np.ndarray:
    gloss = np.clip(np.asarray(params, dtype=np.float64)[..., _IDX["clearcoat_gloss"]], 0.0, 1.0)
    return _mix(0.1, 0.001, gloss)


def colour_factors(params) -> tuple[np.ndarray, np.ndarray]:
    """(spec0, sheen colour), each (..., 3), of params (..., 13): the specular lobe's F0 and the
    sheen's colour before its amount (principled.glsl's q.spec0 and q.sheen_w / sheen), from
    the tint hue base / lum(base) (the explorer's 0.3 R + 0.6 G + 0.1 B)."""
    p = np.clip(np.asarray(params, dtype=np.float64), 0.0, 1.0)
    base = p[..., 0:3]
    lum = (0.3 * base[..., 0] + 0.6 * base[..., 1] + 0.1 * base[..., 2])[..., None]
    tint = np.where(lum > 0.0, base / np.where(lum > 0.0, lum, 1.0), 1.0)

    def s(name):
        return p[..., _IDX[name]][..., None]
    spec0 = _mix(s("specular") * 0.08 * _mix(1.0, tint, s("specular_tint")), base, s("metallic"))
    return spec0, _mix(1.0, tint, s("sheen_tint"))


def principled_brdf(params, L, V, N, X, Y, lobes=LOBES) -> np.ndarray:
    """f(L, V) (..., 3) in 1/sr, broadcasting params (..., 13) against the directions (..., 3).

    ``lobes`` selects a subset of ("diffuse", "sheen", "specular", "clearcoat") for tests; the
    full BRDF is their sum.
    """
    p = np.clip(np.asarray(params, dtype=np.float64), 0.0, 1.0)
    L, V, N, X, Y = (np.asarray(a, dtype=np.float64) for a in (L, V, N, X, Y))
    shape = np.broadcast_shapes(p.shape[:-1], L.shape[:-1], V.shape[:-1], N.shape[:-1],
                                X.shape[:-1], Y.shape[:-1])
    p = np.broadcast_to(p, shape + (PARAM_COUNT,))
    L, V, N, X, Y = (np.broadcast_to(a, shape + (3,)) for a in (L, V, N, X, Y))

    def s(name):  # a scalar parameter with a trailing axis for RGB broadcasting
        return p[..., _IDX[name]][..., None]

    base = p[..., 0:3]
    n_dot_l = _dot(N, L)[..., None]
    n_dot_v = _dot(N, V)[..., None]
    valid = (n_dot_l > 0.0) & (n_dot_v > 0.0)
    # Keep invalid entries finite; they are zeroed at the end.
    n_dot_l = np.where(valid, n_dot_l, 1.0)
    n_dot_v = np.where(valid, n_dot_v, 1.0)
    H = L + V
    H = np.where(valid, H, N)
    H = H / np.linalg.norm(H, axis=-1, keepdims=True)
    n_dot_h = _dot(N, H)[..., None]
    l_dot_h = _dot(L, H)[..., None]
    fh = _schlick_weight(l_dot_h)
    rough = s("roughness")
    out = np.zeros(shape + (3,))

    spec0, sheen_color = colour_factors(p)
    metallic = s("metallic")

    if "diffuse" in lobes:
        fl, fv = _schlick_weight(n_dot_l), _schlick_weight(n_dot_v)
        fd90 = 0.5 + 2.0 * l_dot_h ** 2 * rough
        fd = _mix(1.0, fd90, fl) * _mix(1.0, fd90, fv)
        fss90 = l_dot_h ** 2 * rough
        fss = _mix(1.0, fss90, fl) * _mix(1.0, fss90, fv)
        ss = 1.25 * (fss * (1.0 / np.maximum(n_dot_l + n_dot_v, 1e-6) - 0.5) + 0.5)
        out += (1.0 / np.pi) * _mix(fd, ss, s("subsurface")) * base * (1.0 - metallic)
    if "sheen" in lobes:
        out += fh * s("sheen") * sheen_color * (1.0 - metallic)
    if "specular" in lobes:
        ax, ay = (a[..., None] for a in spec_alphas(p))
        ds = _gtr2_aniso(n_dot_h, _dot(H, X)[..., None], _dot(H, Y)[..., None], ax, ay)
        fs = _mix(spec0, 1.0, fh)
        gs = (_smith_ggx_aniso(n_dot_l, _dot(L, X)[..., None], _dot(L, Y)[..., None], ax, ay)
              * _smith_ggx_aniso(n_dot_v, _dot(V, X)[..., None], _dot(V, Y)[..., None], ax, ay))
        out += gs * ds * fs
    if "clearcoat" in lobes:
        nxh = np.cross(N, H)
        dr = _gtr1(n_dot_h, _dot(nxh, nxh)[..., None], clearcoat_alpha(p)[..., None])
        fr = _mix(0.04, 1.0, fh)
        gr = _smith_ggx(n_dot_l, 0.25) * _smith_ggx(n_dot_v, 0.25)
        out += 0.25 * s("clearcoat") * gr * fr * dr
    return np.where(valid, out, 0.0)


def orthonormal_basis(n) -> tuple[np.ndarray, np.ndarray]:
    """(t, b) with cross(t, b) = n, branchless (Duff et al. 2017), as the GLSL helper."""
    n = np.asarray(n, dtype=np.float64)
    x, y, z = n[..., 0], n[..., 1], n[..., 2]
    s = np.where(z >= 0.0, 1.0, -1.0)
    a = -1.0 / (s + z)
    c = x * y * a
    t = np.stack([1.0 + s * x * x * a, s * c, -s * x], axis=-1)
    b = np.stack([c, s + y * y * a, -y], axis=-1)
    return t, b


def tangent_frame(n, tangent=None) -> tuple[np.ndarray, np.ndarray]:
    """(X, Y) for normals n: the tangent Gram-Schmidt-orthogonalised to n (Y = n x X), or the
    Duff basis where no usable tangent is given (missing, zero or parallel to n)."""
    n = np.asarray(n, dtype=np.float64)
    t0, b0 = orthonormal_basis(n)
    if tangent is None:
        return t0, b0
    t = np.asarray(tangent, dtype=np.float64)
    t = t - _dot(t, n)[..., None] * n
    length = np.linalg.norm(t, axis=-1, keepdims=True)
    ok = length > 1e-6
    t = np.where(ok, t / np.where(ok, length, 1.0), t0)
    return t, np.cross(n, t)


# --- importance sampling (local frame: N = +z, X = +x, Y = +y) ---------------------------------

_EX, _EY, _EZ = np.eye(3)


def _local_frame_brdf(params, L, V, lobes=LOBES):
    return principled_brdf(params, L, V, _EZ, _EX, _EY, lobes)


def _sample_ggx_vndf(V, ax, ay, u1, u2):
    """Heitz 2018: a half-vector from the visible normals of anisotropic GGX."""
    vh = np.stack([ax * V[..., 0], ay * V[..., 1], V[..., 2]], axis=-1)
    vh /= np.linalg.norm(vh, axis=-1, keepdims=True)
    lensq = vh[..., 0] ** 2 + vh[..., 1] ** 2
    inv = np.where(lensq > 0, 1.0 / np.sqrt(np.where(lensq > 0, lensq, 1.0)), 0.0)
    t1 = np.where((lensq > 0)[..., None],
                  np.stack([-vh[..., 1] * inv, vh[..., 0] * inv, np.zeros_like(inv)], axis=-1),
                  np.array([1.0, 0.0, 0.0]))
    t2 = np.cross(vh, t1)
    r, phi = np.sqrt(u1), 2.0 * np.pi * u2
    p1, p2 = r * np.cos(phi), r * np.sin(phi)
    sv = 0.5 * (1.0 + vh[..., 2])
    p2 = (1.0 - sv) * np.sqrt(np.maximum(0.0, 1.0 - p1 * p1)) + sv * p2
    nh = (p1[..., None] * t1 + p2[..., None] * t2
          + np.sqrt(np.maximum(0.0, 1.0 - p1 * p1 - p2 * p2))[..., None] * vh)
    h = np.stack([ax * nh[..., 0], ay * nh[..., 1], np.maximum(1e-9, nh[..., 2])], axis=-1)
    return h / np.linalg.norm(h, axis=-1, keepdims=True)


def _sample_gtr1(a, u1, u2):
    a2 = a * a
    cos_t = np.sqrt(np.clip((1.0 - a2 ** (1.0 - u1)) / (1.0 - a2), 0.0, 1.0))
    sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t ** 2))
    phi = 2.0 * np.pi * u2
    return np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t], axis=-1)


def sample_cosine(u1, u2):
    """Cosine-weighted directions about +z (pdf = cos / pi)."""
    r, phi = np.sqrt(u1), 2.0 * np.pi * u2
    return np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(np.maximum(0.0, 1.0 - u1))], axis=-1)


def mixture_weights(params) -> np.ndarray:
    """(..., 3) technique probabilities (cosine, GGX visible normals, GTR1) for a material: the
    cosine share never drops below ~0.09 so the pdf covers the whole hemisphere (unbiased)."""
    p = np.clip(np.asarray(params, dtype=np.float64), 0.0, 1.0)
    w = np.stack([1.0 - 0.9 * p[..., _IDX["metallic"]],
                  np.ones(p.shape[:-1]),
                  0.5 * p[..., _IDX["clearcoat"]]], axis=-1)
    return w / w.sum(axis=-1, keepdims=True)


def mixture_pdf(params, L, V):
    """Solid-angle pdf of ``sample_mixture`` (local frame) for directions L given V."""
    p = np.asarray(params, dtype=np.float64)
    ax, ay = spec_alphas(p)
    ac = clearcoat_alpha(p)
    w = mixture_weights(p)
    n_dot_l = L[..., 2]
    n_dot_v = np.maximum(V[..., 2], 1e-12)
    h = L + V
    h = h / np.maximum(np.linalg.norm(h, axis=-1, keepdims=True), 1e-300)
    l_dot_h = np.maximum(_dot(L, h), 1e-12)
    g1v = 2.0 * n_dot_v * _smith_ggx_aniso(n_dot_v, V[..., 0], V[..., 1], ax, ay)
    pdf_s = g1v * _gtr2_aniso(h[..., 2], h[..., 0], h[..., 1], ax, ay) / (4.0 * n_dot_v)
    pdf_c = _gtr1(h[..., 2], h[..., 0] ** 2 + h[..., 1] ** 2, ac) * h[..., 2] / (4.0 * l_dot_h)
    pdf = w[..., 0] * n_dot_l / np.pi + w[..., 1] * pdf_s + w[..., 2] * pdf_c
    return np.where((n_dot_l > 0) & (h[..., 2] > 0), pdf, 0.0)


def sample_mixture(params, V, rng: np.random.Generator, u0=None):
    """Directions L (local frame, one per (params, V)) and their pdf, from a mixture of cosine,
    GGX visible-normal (Heitz 2018) and GTR1 (Burley 2012) sampling: low variance for every
    lobe, matte or mirror. Returns (L, pdf, technique index 0/1/2).

    ``u0`` (optional) picks the technique; pass stratified values to give each technique a
    fixed share of the samples (Veach's multi-sample model with the balance heuristic)."""
    p = np.asarray(params, dtype=np.float64)
    V = np.asarray(V, dtype=np.float64)
    shape = np.broadcast_shapes(p.shape[:-1], V.shape[:-1])
    p = np.broadcast_to(p, shape + (PARAM_COUNT,))
    V = np.broadcast_to(V, shape + (3,))
    u1, u2 = rng.random((2,) + shape)
    u0 = rng.random(shape) if u0 is None else np.broadcast_to(u0, shape)
    w = mixture_weights(p)
    tech = (u0 >= w[..., 0]).astype(np.int8) + (u0 >= w[..., 0] + w[..., 1])
    ax, ay = spec_alphas(p)
    h_s = _sample_ggx_vndf(V, ax, ay, u1, u2)
    h_c = _sample_gtr1(clearcoat_alpha(p), u1, u2)
    h = np.where((tech == 1)[..., None], h_s, h_c)
    l_ref = 2.0 * _dot(V, h)[..., None] * h - V
    L = np.where((tech == 0)[..., None], sample_cosine(u1, u2), l_ref)
    return L, mixture_pdf(p, L, V), tech


def directional_albedo(params, V, n_samples: int = 4096, seed: int = 0, lobes=LOBES,
                       return_stderr: bool = False):
    """Directional albedo a(V) = integral of f(L, V) (n.L) dL, (..., 3), by Monte Carlo with
    ``sample_mixture`` (fixed seed; each technique gets its fixed share of the samples, so the
    standard error is summed per stratum). V is in the local frame (N = +z, X = +x).

    By reciprocity this is also the hemispherical-directional reflectance towards V.
    """
    p = np.asarray(params, dtype=np.float64)
    V = np.asarray(V, dtype=np.float64)
    V = V / np.linalg.norm(V, axis=-1, keepdims=True)
    shape = np.broadcast_shapes(p.shape[:-1], V.shape[:-1])
    p_s = np.broadcast_to(np.broadcast_to(p, shape + (PARAM_COUNT,))[..., None, :],
                          shape + (n_samples, PARAM_COUNT))
    V_s = np.broadcast_to(np.broadcast_to(V, shape + (3,))[..., None, :], shape + (n_samples, 3))
    rng = np.random.default_rng(seed)
    u0 = (np.arange(n_samples) + 0.5) / n_samples  # stratified technique choice
    L, pdf, tech = sample_mixture(p_s, V_s, rng, u0)
    ok = pdf > 0
    f = _local_frame_brdf(p_s, L, V_s, lobes)
    est = f * np.where(ok, np.maximum(L[..., 2], 0.0) / np.where(ok, pdf, 1.0), 0.0)[..., None]
    mean = est.mean(axis=-2)
    if not return_stderr:
        return mean
    var = np.zeros_like(mean)
    for k in range(3):  # stratified: the variance is the sum of the per-stratum variances
        sel = (tech == k)[..., None]
        cnt = sel.sum(axis=-2)
        m_k = np.where(sel, est, 0.0).sum(axis=-2) / np.maximum(cnt, 1)
        dev2 = np.where(sel, (est - m_k[..., None, :]) ** 2, 0.0)
        v_k = dev2.sum(axis=-2) / np.maximum(cnt - 1, 1)
        var += np.where(cnt > 1, (cnt / n_samples) ** 2 * v_k / np.maximum(cnt, 1), 0.0)
    return mean, np.sqrt(var)


METAL_ALBEDO_SIZE = 16     # metal_albedo_table: roughness rows x cos(theta) columns


def metal_albedo_table(size: int = METAL_ALBEDO_SIZE, lattice: int = 48) -> np.ndarray:
    """(size, size, 2) float32 (S, B): a metal's directional albedo is F0 x S + B (Fresnel's
    F0 + (1 - F0) Fh is linear in F0 = the base colour), per roughness row r = (i + 0.5) / size
    and view cosine column mu = (j + 0.5) / size - texel centres, so a bilinear look-up at
    (mu, r) interpolates it. The split-sum factor of the asset's mirror bounce
    (shaders/pbgi_gather.glsl: node_radiance): reflected light = prefiltered incoming light x
    this albedo. The integral is taken over GGX's visible normals (Heitz 2018) on a
    ``lattice`` x ``lattice`` grid of cell centres: f cos / pdf is smooth and bounded there, so
    a deterministic grid converges fast (``directional_albedo``'s Monte Carlo, mixing its
    diffuse and clearcoat strategies in, needs far more samples for the same accuracy, which a
    test checks). Cached per process."""
    key = (int(size), int(lattice))
    if key not in _METAL_ALBEDO:
        t = (np.arange(size) + 0.5) / size
        g = (np.arange(lattice) + 0.5) / lattice
        u1, u2 = (a.ravel() for a in np.meshgrid(g, g, indexing="ij"))
        V = np.stack([np.sqrt(1.0 - t * t), np.zeros(size), t], axis=1)[:, None, :]
        out = np.zeros((size, size, 2), np.float64)
        for i, r in enumerate(t):
            # the half vectors, directions and pdf depend on the roughness, not on F0
            alpha = float(spec_alphas(pack_params(metallic=1.0, roughness=float(r)))[0])
            H = _sample_ggx_vndf(V, alpha, alpha, u1[None], u2[None])         # (size, n, 3)
            vh = np.sum(V * H, axis=-1)
            L = 2.0 * vh[..., None] * H - V
            ok = (L[..., 2] > 0) & (vh > 0)
            d = _gtr2_aniso(H[..., 2], H[..., 0], H[..., 1], alpha, alpha)
            pdf = d * 2.0 * t[:, None] * _smith_ggx(t[:, None], alpha) / (4.0 * t[:, None])
            weight = np.where(ok, np.maximum(L[..., 2], 0.0) / np.where(ok, pdf, 1.0), 0.0)
            a0, a1 = (
                (_local_frame_brdf(pack_params(base_color=(base,) * 3, metallic=1.0,
                                               roughness=float(r)),
                                   L, np.broadcast_to(V, L.shape), ("specular",))[..., 0]
                 * weight).mean(axis=1)
                for base in (0.0, 1.0))
            out[i, :, 0], out[i, :, 1] = a1 - a0, a0
        _METAL_ALBEDO[key] = out.astype(np.float32)
    return _METAL_ALBEDO[key]


_METAL_ALBEDO: dict = {}
