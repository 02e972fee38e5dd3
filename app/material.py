"""Disney Principled material (Burley 2012): the parameter table, declared once.

The table drives the BRDF panel sliders, the material JSON format and the docs. Defaults follow
Burley's BRDF explorer; ``base_color`` is linear RGB.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, make_dataclass

import numpy as np

from app.errors import ScanlightError
from app.io.schema import Fields, number_value, vec3_value


@dataclass(frozen=True)
class Param:
    name: str
    default: float
    tooltip: str
    lo: float = 0.0
    hi: float = 1.0


# Scalar parameters in the order the shaders pack them (see shaders/lib/principled.glsl).
SCALAR_PARAMS: tuple[Param, ...] = (
    Param("subsurface", 0.0, "Blends the diffuse lobe towards Hanrahan-Krueger subsurface flattening."),
    Param("metallic", 0.0, "0 = dielectric, 1 = metal (specular tinted by base colour, no diffuse)."),
    Param("specular", 0.5, "Dielectric specular amount; 0.5 = index of refraction 1.5 (F0 = 4%)."),
    Param("specular_tint", 0.0, "Tints the dielectric specular towards the base colour hue."),
    Param("roughness", 0.5, "Microfacet roughness (alpha = roughness^2)."),
    Param("anisotropic", 0.0, "Stretches the specular highlight along the surface tangent."),
    Param("sheen", 0.0, "Extra grazing-angle retro-reflection, for cloth."),
    Param("sheen_tint", 0.5, "Tints the sheen towards the base colour hue."),
    Param("clearcoat", 0.0, "A second, fixed-IOR (1.5) specular lobe, as on car paint."),
    Param("clearcoat_gloss", 1.0, "Clearcoat glossiness: 0 = satin, 1 = gloss."),
)
SCALAR_NAMES = tuple(p.name for p in SCALAR_PARAMS)
DEFAULT_BASE_COLOR = (0.82, 0.67, 0.16)
ALL_NAMES = ("base_color",) + SCALAR_NAMES


class _MaterialMethods:
    """The behaviour of Material; its fields are generated from SCALAR_PARAMS below."""

    def scalars(self) -> np.ndarray:
        return np.array([getattr(self, n) for n in SCALAR_NAMES], dtype=np.float32)

    def to_dict(self) -> dict:
        d = {"base_color": [float(c) for c in self.base_color]}
        d.update({n: float(getattr(self, n)) for n in SCALAR_NAMES})
        return d

    def updated(self, values: dict) -> "Material":
        """A copy with ``values`` applied (validated, clamped to each parameter's range)."""
        new = Material(**{f.name: getattr(self, f.name) for f in fields(self)})
        for key, val in values.items():
            set_param(new, key, val)
        return new


# One Disney Principled material, optionally with textures: base colour, the scalar parameters
# in SCALAR_PARAMS' order with its defaults (declared once, there), then name, emissive and the
# optional float32 (H, W, C) textures - base colour (linear RGB[A]), metallic-roughness (glTF:
# B = metallic, G = roughness) and the tangent-space normal map.
Material = make_dataclass(
    "Material",
    [("base_color", tuple, field(default=DEFAULT_BASE_COLOR))]
    + [(p.name, float, field(default=p.default)) for p in SCALAR_PARAMS]
    + [("name", str, field(default="material")),
       ("emissive", tuple, field(default=(0.0, 0.0, 0.0))),
       ("base_color_texture", object, field(default=None, repr=False)),
       ("metallic_roughness_texture", object, field(default=None, repr=False)),
       ("normal_texture", object, field(default=None, repr=False))],
    bases=(_MaterialMethods,))
Material.__module__ = __name__
Material.__doc__ = "One Disney Principled material (fields: see the comment above)."


PRESETS: dict[str, dict] = {
    "plastic": {"base_color": [0.6, 0.05, 0.05], "roughness": 0.3, "specular": 0.5},
    "rubber": {"base_color": [0.05, 0.05, 0.05], "roughness": 0.9, "specular": 0.3},
    "brushed metal": {"base_color": [0.9, 0.9, 0.9], "metallic": 1.0, "roughness": 0.35,
                      "anisotropic": 0.8},
    "gold": {"base_color": [1.0, 0.71, 0.29], "metallic": 1.0, "roughness": 0.2},
    "car paint": {"base_color": [0.05, 0.12, 0.5], "roughness": 0.4, "clearcoat": 1.0,
                  "clearcoat_gloss": 0.95},
    "fabric": {"base_color": [0.5, 0.2, 0.3], "roughness": 0.95, "sheen": 1.0, "sheen_tint": 0.5,
               "specular": 0.2},
    "white diffuse": {"base_color": [0.8, 0.8, 0.8], "roughness": 1.0, "specular": 0.0},
}


def set_param(mat: Material, key: str, val, source: str | None = None) -> None:
    """Set one parameter from a JSON (or UI) value: typed strictly (app.io.schema: ``"123"`` is
    not a colour, ``true`` is not 1), then clamped to the parameter's range."""
    if key == "base_color":
        rgb = vec3_value(val, "material 'base_color'", source, limit=None)
        mat.base_color = tuple(float(np.clip(v, 0.0, 1.0)) for v in rgb)
        return
    spec = next((p for p in SCALAR_PARAMS if p.name == key), None)
    if spec is None:
        raise ScanlightError(source, f"unknown material parameter {key!r} "
                                     f"(known: {', '.join(ALL_NAMES)})")
    v = number_value(val, f"material {key!r}", source)
    setattr(mat, key, float(np.clip(v, spec.lo, spec.hi)))


def material_from_dict(d: dict, source: str | None = None) -> Material:
    f = Fields(d, "material", source)
    mat = Material(name=f.string("name", "material"))
    for key, val in d.items():
        if key == "name":
            continue
        set_param(mat, key, val, source)
    return mat


def load_material(path) -> Material:
    from app.io.files import read_json
    return material_from_dict(read_json(path, "material"), str(path))
