"""A material edit without a new gather: the gather's sums kept apart per BRDF factor.

The final gather (shaders/pbgi_gather.glsl) sums f(w_k) L_k Omega_k over a receiver's
micro-pixels. Per direction, the Disney BRDF is a few scalars (lib/principled.glsl:
PrincipledParts) times factors that depend only on the material and the receiver:

    f = (1 - metallic) (base diffuse + sheen_w fh) + spec (spec0 (1 - fh) + fh) + clearcoat coat

with spec0 = mix(0.08 specular mix(1, tint, specular_tint), base, metallic) and
sheen_w = sheen mix(1, tint, sheen_tint), tint = base / lum(base). So the gather's GATHER_PARTS
variant keeps five RGB sums per pixel (diffuse, sheen, spec_f0, spec_one, coat:
gpu_layout.GATHER_PARTS) and a new base colour, metallic, specular, specular tint, sheen, sheen
tint or clearcoat amount is ``recombine`` - a few multiplications per pixel on the CPU - instead
of a walk and a gather (issue 19: "base colour or metallic need only a new gather"; this needs
not even that). Roughness, anisotropy, subsurface and clearcoat gloss change the per-direction
scalars themselves and are gathered again.

The recombination equals a new gather only when that gather would have used the same micro-
buffers, and ``recombinable`` says when (one reason per refusal, for the stats):

* the material's base colour and metallic are plain factors: with a texture they vary inside a
  pixel, and the passes' mean of (1 - m) base x S is not (1 - mean m) mean base x mean S;
* the lobe micro-buffer's sizing (lib/lobe_size.glsl) follows the specular lobe's share of what
  the receiver reflects, which base colour, metallic and specular move: the buffers held are
  fine for a share at most the old one (checked at both ends of the Fresnel weight, the share
  being monotone in it), not for a larger one (a dielectric made metal would read the few
  micro-pixels of a weak lobe);
* the coarse cosine micro-buffer of lobe-only receivers (a glossy metal,
  lobe.lobe_only_receivers) holds too little for a diffuse lobe: a metal made dielectric there
  is gathered again;
* a clearcoat turned on or off changes which lobes the lobe buffer holds;
* the asset's own surfels, when walked and bounced (a non-convex asset,
  ``pbgi.asset_bounces`` > 0), carry the old albedo into every receiver's light.
"""

from __future__ import annotations

from dataclasses import fields

import numpy as np

from app.pbgi.gpu_layout import GATHER_PARTS

# what recombine takes from a material; every other field's change needs a new gather
RECOMBINABLE = frozenset({"base_color", "metallic", "specular", "specular_tint", "sheen",
                          "sheen_tint", "clearcoat"})
TEXTURES = ("base_color_texture", "metallic_roughness_texture", "normal_texture")
PART_NAMES = ("diffuse", "sheen", "spec_f0", "spec_one", "coat")


def factors(material) -> dict[str, np.ndarray]:
    """The factors principled_prepare derives from one untextured material: base, metallic,
    spec0, sheen_w, clearcoat (clamped as the shader clamps them; app/pbgi/brdf.py's twin)."""
    from app.pbgi.brdf import PARAM_NAMES, colour_factors, pack_params
    p = np.clip(pack_params(material), 0.0, 1.0)
    spec0, sheen_color = colour_factors(p)
    c = {n: float(p[PARAM_NAMES.index(n)]) for n in ("metallic", "sheen", "clearcoat")}
    return {"base": p[0:3], "metallic": c["metallic"], "spec0": spec0,
            "sheen_w": c["sheen"] * sheen_color, "clearcoat": c["clearcoat"]}


def recombine(parts: np.ndarray, material) -> np.ndarray:
    """Radiance (..., 3) float32 of GATHER_PARTS records ``parts`` (any shape) lit through
    ``material``'s factors: the gather's own last step (pbgi_gather.glsl:
    gather_parts_radiance), in numpy."""
    f = factors(material)
    p = {n: parts[n].astype(np.float64) for n in PART_NAMES}
    out = ((f["base"] * p["diffuse"] + f["sheen_w"] * p["sheen"]) * (1.0 - f["metallic"])
           + f["spec0"] * p["spec_f0"] + p["spec_one"] + f["clearcoat"] * p["coat"])
    return out.astype(np.float32)


def changed(old, new) -> set[str]:
    """The fields in which two materials differ (textures by identity)."""
    out = set()
    for f in fields(old):
        a, b = getattr(old, f.name), getattr(new, f.name)
        same = a is b if f.name in TEXTURES else (
            tuple(a) == tuple(b) if isinstance(a, (tuple, list)) else a == b)
        if not same:
            out.add(f.name)
    return out


def _lobe_share_bounds(material) -> tuple[np.ndarray, float]:
    """(specular luminance at Fresnel weight 0 and 1, diffuse luminance) of lobe_size.glsl's
    lobe_share (its lobe_spec_share factor depends on roughness alone, equal on both sides),
    in that shader's luminance (lib/common.glsl: Rec. 709, app.color.luminance)."""
    from app.color import luminance
    f = factors(material)
    spec = np.array([float(luminance(f["spec0"])), float(luminance(np.ones(3)))])
    return spec, (1.0 - f["metallic"]) * float(luminance(f["base"]))


def recombinable(old_materials, new_materials, params, walks_asset: bool) -> str | None:
    """None when the gather of ``old_materials`` recombined with ``new_materials`` is what a new
    gather with ``params`` would give (see the module docstring), else why not, in words."""
    from app.pbgi.lobe import lobe_only_receivers
    if len(old_materials) != len(new_materials):
        return "the number of materials changed"
    touched = [(i, o, n, changed(o, n)) for i, (o, n) in enumerate(zip(old_materials,
                                                                        new_materials))]
    touched = [t for t in touched if t[3]]
    if touched and walks_asset and int(params.asset_bounces) > 0:
        return "the asset's bounce carries its albedo"
    glossy_below = float(params.glossy_below)
    for i, old, new, names in touched:
        other = sorted(names - RECOMBINABLE)
        if other:
            return f"material {i}: {', '.join(other)} changed"
        if old.base_color_texture is not None or old.metallic_roughness_texture is not None:
            return f"material {i}: textured base colour or metallic"
        if (old.clearcoat > 0.0) != (new.clearcoat > 0.0):
            return f"material {i}: clearcoat turned on or off"
        lobed = glossy_below > 0.0 and old.roughness < glossy_below
        if lobed and old.clearcoat == 0.0:
            (s_old, d_old), (s_new, d_new) = _lobe_share_bounds(old), _lobe_share_bounds(new)
            if np.any(s_new * d_old > s_old * d_new * (1 + 1e-6) + 1e-12):
                return f"material {i}: a larger specular share needs larger lobe buffers"
        if lobed and int(params.lobe_only_microbuffer) > 0:
            was, now = (bool(lobe_only_receivers(np.array([m.metallic]), np.array([m.roughness]),
                                                 glossy_below)[0]) for m in (old, new))
            if was and not now:
                return f"material {i}: the coarse micro-buffer of a glossy metal holds no diffuse"
    return None


PART_WORDS = 3 * len(PART_NAMES)


def part_words(parts: np.ndarray) -> np.ndarray:
    """The sums of GATHER_PARTS records as (..., PART_WORDS) float32 (no material id, no
    padding: numpy leaves a structured copy's padding bytes undefined)."""
    return np.concatenate([parts[n] for n in PART_NAMES], axis=-1).astype(np.float32)


def part_records(words: np.ndarray) -> np.ndarray:
    """GATHER_PARTS records (material 0) from (..., PART_WORDS) sums: ``part_words``'s inverse."""
    words = np.asarray(words, np.float32)
    out = empty(words.shape[:-1])
    for k, n in enumerate(PART_NAMES):
        out[n] = words[..., 3 * k:3 * k + 3]
    return out


def material_ids(parts: np.ndarray) -> np.ndarray:
    """The material id of each GATHER_PARTS record (int)."""
    return np.rint(parts["material"]).astype(np.int64)


def empty(shape) -> np.ndarray:
    """Zeroed GATHER_PARTS records of ``shape``."""
    return GATHER_PARTS.zeros(int(np.prod(shape))).reshape(shape)
