"""Every user-facing parameter of Scanlight, declared once.

``PARAMS`` is the one table: key, kind, default, range, unit, help, and what a change redoes.
Everything else is generated from it:

- the viewer's widgets (app/ui/widgets.py) and its plain settings model and session JSON
  (app/settings.py);
- the parameter records the engines take, ``RenderParams`` (app/pbgi/modebase.py) and
  ``ExpandParams`` (app/hdr/pipeline.py), through ``param_record``: a record's fields, defaults
  and validation are its group's rows;
- the command-line options of ``render``, ``expand``, ``evaluate`` and ``bench``
  (app/commands/options.py maps flag names onto keys, as f3d's F3DOptionsTools maps its CLI
  onto options.json);
- the README's parameter table (``markdown_table``; tests/cli/test_params.py keeps it in sync).

So the CLI and the window share defaults by construction, and a range is checked in one place.

Kinds: ``float``, ``int``, ``bool``, ``choice`` (one of ``choices``). ``optional`` parameters may
also be None ("not set": the engine decides, e.g. the exposure search finds alpha). A value out
of ``lo .. hi`` is an error for a record or a command line (``Param.check``); the viewer clamps
instead (``Param.clamp``: a slider or an old session never fails). ``ui`` rows get a widget;
``soft`` narrows a slider's travel below the full range (Blender's soft limits). ``when``
names the choice values under which a parameter matters (Hybrid's tolerances, PatchMatch's t_h):
the viewer greys the widget out otherwise instead of hiding it, so the panel never reflows
under the cursor.

``redo`` says what a change invalidates, for the engine's change handlers: "gi" re-gathers the
asset, "display" only re-tone-maps / recomposites, "room" redraws the point splats, "job" only
affects the next background job, "passes" re-gathers only when the viewer's number of idle passes
for the scene changes (their samples are centred for their count, so a new count starts them
over), "none" nothing already computed.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from app.errors import ScanlightError
from app.render.tonemap import DEFAULT as DEFAULT_TONEMAP, NAMES as TONEMAPPERS

KINDS = ("float", "int", "bool", "choice")
REDO = ("gi", "display", "room", "job", "passes", "none")


@dataclass(frozen=True)
class Param:
    key: str                      # "group.name"; ``name`` is the record field
    kind: str
    default: Any
    help: str
    lo: float | None = None
    hi: float | None = None
    unit: str = ""
    choices: tuple[str, ...] = ()
    label: str = ""
    log: bool = False             # logarithmic slider
    redo: str = "none"
    ui: bool = True
    optional: bool = False        # None allowed ("not set")
    soft: tuple[float, float] | None = None   # the slider's travel, inside lo .. hi
    when: tuple[str, tuple[str, ...]] | None = None  # (choice key, its values where this matters)

    def __post_init__(self):
        assert self.kind in KINDS and self.redo in REDO, self.key
        assert self.kind != "choice" or self.default in self.choices, self.key
        assert self.optional or self.default is not None, self.key

    def applies(self, values) -> bool:
        """Whether this parameter matters under ``values`` (a mapping of keys to values)."""
        return self.when is None or values[self.when[0]] in self.when[1]

    @property
    def group(self) -> str:
        return self.key.split(".", 1)[0]

    @property
    def name(self) -> str:
        return self.key.split(".", 1)[1]

    @property
    def title(self) -> str:
        return self.label or self.name.replace("_", " ")

    @property
    def slider_range(self) -> tuple[float, float]:
        return self.soft if self.soft is not None else (self.lo, self.hi)

    def range_text(self) -> str:
        if self.kind == "choice":
            return " / ".join(self.choices)
        if self.kind == "bool":
            return ""
        if self.kind == "int":
            return f"{int(self.lo)} .. {int(self.hi)}"
        return f"{self.lo:g} .. {self.hi:g}"

    def _typed(self, value, what: str, source):
        """``value`` converted to the kind (no range check), or a ScanlightError."""
        if value is None and self.optional:
            return None
        if self.kind == "bool":
            if isinstance(value, (bool, np.bool_)):
                return bool(value)
            if isinstance(value, (int, float)) and value in (0, 1):
                return bool(value)
            raise ScanlightError(source, f"{what} must be true or false, got {value!r}")
        if self.kind == "choice":
            if isinstance(value, str) and value in self.choices:
                return value
            raise ScanlightError(source, f"{what} must be one of {', '.join(self.choices)}, "
                                         f"got {value!r}")
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.number)):
            raise ScanlightError(source, f"{what} must be a number, got {value!r}")
        try:
            v = float(value)
        except OverflowError:     # a JSON integer of 400 digits
            v = math.inf
        if not math.isfinite(v):
            raise ScanlightError(source, f"{what} must be finite, got {value!r}")
        if self.kind == "int" and v != int(v):
            raise ScanlightError(source, f"{what} must be a whole number, got {value!r}")
        return int(v) if self.kind == "int" else v

    def check(self, value, source=None, what: str | None = None):
        """The value, typed and inside ``lo .. hi``; otherwise a ScanlightError naming it."""
        what = what or f"parameter {self.key!r}"
        v = self._typed(value, what, source)
        if v is not None and self.kind in ("float", "int") and not self.lo <= v <= self.hi:
            rng = self.range_text().replace(" .. ", ", ")
            unit = f" {self.unit}" if self.unit else ""
            raise ScanlightError(source, f"{what} must be in [{rng}]{unit}, got {value!r}")
        return v

    def clamp(self, value, source=None, what: str | None = None):
        """The value typed and clamped to ``lo .. hi`` (the viewer's and sessions' rule)."""
        what = what or f"setting {self.key!r}"
        if self.kind == "int" and isinstance(value, (float, np.floating)) \
                and math.isfinite(value):
            value = int(round(float(value)))       # a slider or a hand-edited session
        v = self._typed(value, what, source)
        if v is None or self.kind not in ("float", "int"):
            return v
        v = min(max(v, self.lo), self.hi)
        return int(v) if self.kind == "int" else float(v)


def _f(key, default, help, lo, hi, unit="", **kw) -> Param:
    return Param(key, "float", default, help, lo, hi, unit, **kw)


def _i(key, default, help, lo, hi, unit="", **kw) -> Param:
    return Param(key, "int", default, help, lo, hi, unit, **kw)


def _c(key, default, help, choices, **kw) -> Param:
    return Param(key, "choice", default, help, choices=tuple(choices), **kw)


def _b(key, default, help, **kw) -> Param:
    return Param(key, "bool", default, help, **kw)


RENDER_MODES = ("classic", "mipmapped", "hybrid", "envmap")   # app/pbgi/modes.py: one class each
HDR_METHODS = ("pmatch-rgb", "pmatch-lum", "landis", "banterle", "landis-pc", "banterle-pc")

# Quality presets: named bundles of the settings that trade speed for accuracy, chosen from the
# Pareto front that ``scanlight bench tradeoff`` measures (README, "Speed against accuracy":
# its suggest_presets picked these three from the full grid on both rooms and five materials -
# preview the fastest within 2.5x the best error of every case, balanced within 1.5x, final
# the least at GI scale 1 everywhere, near ties broken by time (tradeoff.FINAL_TIE); re-run
# the bench when the renderer changes: final was Classic M 24 until Hybrid's block levels made
# Hybrid M 24 the least, 1.08x against Classic's 1.28x, and balanced was M 24 until the block
# levels over the far field's share put M 20 within its budget, 1.41x, at 0.7-0.85x its time on the
# rough spheres). The viewer's passes where every lobe is rough (pbgi.rough_idle_passes) are
# not in the grid (one pass each): 2 in preview and balanced, where the passes' noise was
# measured small, bring the orbit of the demo close-up within issue 19's 3 s on the 2-core CPU
# (README, "Fewer idle passes where the light is rough").
# ``pbgi.quality`` selects one; DEFAULT_QUALITY's values are the table's defaults (checked
# below), so a fresh viewer and a command line without --quality get exactly that preset.
QUALITY_PRESETS: dict[str, dict[str, Any]] = {
    "preview": {"pbgi.mode": "hybrid", "pbgi.microbuffer": 16, "pbgi.render_scale": 0.5,
                "pbgi.rough_render_scale": 0.5, "pbgi.rough_idle_passes": 2,
                "pbgi.parallax_tolerance": 1.0, "pbgi.stop_factor": 4.0},
    "balanced": {"pbgi.mode": "hybrid", "pbgi.microbuffer": 20, "pbgi.render_scale": 1.0,
                 "pbgi.rough_render_scale": 0.5, "pbgi.rough_idle_passes": 2,
                 "pbgi.parallax_tolerance": 1.0, "pbgi.stop_factor": 4.0},
    "final": {"pbgi.mode": "hybrid", "pbgi.microbuffer": 24, "pbgi.render_scale": 1.0,
              "pbgi.rough_render_scale": 1.0, "pbgi.rough_idle_passes": 4,
              "pbgi.parallax_tolerance": 1.0, "pbgi.stop_factor": 4.0},
}
DEFAULT_QUALITY = "balanced"
CUSTOM_QUALITY = "custom"

PARAMS: tuple[Param, ...] = (
    # -- display (the viewer) -------------------------------------------------------------------
    _f("view.exposure", 0.0, "Exposure before the tone mapper: radiance x 2^EV.", -10.0, 10.0,
       "EV", redo="display"),
    _c("view.tonemap", DEFAULT_TONEMAP, "Tone mapper (app/render/tonemap.py): Khronos PBR "
       "Neutral keeps base colours recognisable and rolls off highlights; 'aces' is Stephen "
       "Hill's fitted ACES RRT+ODT; 'agx' is Blender's AgX base (polynomial sigmoid); 'clamp' "
       "shows linear values clipped at 1.", TONEMAPPERS, redo="display"),
    _b("view.false_colour", False, "Show the luminance x 2^EV in false colour: bands of stops "
       "around middle grey 0.18 (legend in the Display panel) instead of the tone-mapped image.",
       label="false colour EV", redo="display"),
    _c("view.cloud", "ldr", "Which room colours to show: the LDR scan, the HDR-expanded cloud, "
       "or in false colour the difference map log2(Y_hdr / Y_ldr) (paper Fig. 1) or each "
       "point's provenance (where its HDR colour came from). All but 'ldr' light the asset with "
       "the HDR cloud.", ("ldr", "hdr", "difference", "provenance"), label="cloud colours",
       redo="gi"),
    _f("view.fov_y", 50.0, "Vertical field of view of the viewport camera.", 10.0, 120.0, "deg",
       label="field of view", redo="gi"),
    _f("view.splat_scale", 1.0, "Radius multiplier of the room's point splats (1 = each "
       "point's own radius, from its local spacing; the hole filling closes what gaps remain, "
       "larger values blur and widen the outline).", 0.25, 4.0, "x", label="splat size",
       redo="room"),
    _b("view.eye_dome", False, "Eye-dome lighting on the room backdrop: darkens each pixel by "
       "how far it lies behind its neighbours (as Potree and CloudCompare do) for depth "
       "perception of the scan; the asset is not shaded.", label="eye-dome lighting",
       redo="room"),
    _b("view.show_cameras", True, "Draw the capture cameras as gizmos.", redo="display"),
    _b("view.show_gizmo", True, "Show the asset transform gizmo in the viewport.",
       redo="display"),
    _f("view.fly_speed", 1.0, "Fly-mode walking speed.", 0.05, 20.0, "m/s", log=True),
    _b("view.free_orbit", False, "Let the orbit, pan and zoom take the eye under the scan's "
       "floor (off: the eye stays 5 cm above it; app/ui/navigation.py)."),
    # -- the viewer's light and its A/B compare (app/ui/engine.py, app/ui/compare.py) -----------
    _c("light.source", "scan", "What lights the asset in the viewer: the scan (PBGI), or the "
       "session's HDRI file (an equirectangular EXR through the environment map, shown as the "
       "background: render --hdri).", ("scan", "hdri"), label="light", redo="gi"),
    _f("light.hdri_rotation", 0.0, "Turn the HDRI about +y, counter-clockwise seen from above "
       "(render --hdri-rotation).", -180.0, 180.0, "deg", label="HDRI rotation", redo="gi",
       when=("light.source", ("hdri",))),
    _b("compare.enabled", False, "A/B split screen: A (the current settings) left of the "
       "divider, B right; B differs from A by 'compare.b'.", label="A/B compare", redo="gi"),
    _c("compare.b", "mode", "What B changes: another render mode, another quality preset, the "
       "HDR (expanded) cloud lighting B where A has the LDR scan, or the session's HDRI lighting "
       "B where A has the scan.", ("mode", "quality", "cloud", "hdri"), label="B differs by",
       redo="gi"),
    _c("compare.mode", "classic", "B's render mode (compare.b = mode).", RENDER_MODES,
       label="B mode", redo="gi", when=("compare.b", ("mode",))),
    _c("compare.quality", "final", "B's quality preset (compare.b = quality).",
       tuple(QUALITY_PRESETS), label="B quality", redo="gi", when=("compare.b", ("quality",))),
    _f("compare.split", 0.5, "Where the divider stands, as a fraction of the viewport's width "
       "(drag it in the viewport).", 0.0, 1.0, label="divider", redo="display"),
    # -- PBGI: RenderParams, plus the viewer-only render_scale, preview_scale, frame_budget_ms -----
    _c("pbgi.quality", DEFAULT_QUALITY, "Quality preset: sets the mode, micro-buffer size, GI "
       "render scale, rough scenes' GI scale, parallax tolerance and node stop factor together, "
       "from the measured speed/accuracy trade (preview: fastest, final: most accurate); "
       "'custom' once one of them is changed by hand.", (*QUALITY_PRESETS, CUSTOM_QUALITY), label="quality", redo="none"),
    _c("pbgi.mode", "hybrid", "Classic: one hierarchy walk per pixel. Mipmapped: walks shared "
       "through the G-buffer pyramid. Hybrid: far field shared between neighbouring pixels, "
       "near field per pixel (several times faster). Environment map: one cube map from the "
       "asset centre.", RENDER_MODES, redo="gi"),
    _i("pbgi.microbuffer", 20, "Micro-buffer resolution M (M x M micro-pixels per receiver).",
       8, 32, "px", redo="gi"),
    _f("pbgi.glossy_below", 0.5, "Specular lobes smoother than this roughness (and every "
       "clearcoat) are gathered from a second micro-buffer warped to the lobe (glossy and "
       "mirror materials without dots); 0 = cosine micro-buffer only.", 0.0, 1.0, "",
       label="lobe buffer below", redo="gi"),
    _b("pbgi.asset_occlusion", True, "The asset's own surface, sampled into surfels, in every "
       "micro-buffer: it shadows the room for itself (self-occlusion) and carries the bounce "
       "below. Off: the asset is lit as if it were alone and convex. A convex asset needs "
       "none and is rendered without them (it cannot shadow or light itself).",
       label="asset self-occlusion", redo="gi"),
    _i("pbgi.asset_bounces", 1, "Bounces the asset's surfels carry (inter-reflection: the asset "
       "lights itself; diffuse, or glossy for a metal); 0 = occlusion only. Needs asset "
       "self-occlusion.", 0, 2, "",
       label="asset bounces", redo="gi"),
    _i("pbgi.asset_surfels", 4096, "Surfels the asset is sampled into (self-occlusion, bounce "
       "and its shadow on the scan); more resolve smaller creases.", 1024, 262144, "",
       label="asset surfels", redo="gi"),
    _f("pbgi.envmap_beyond", 4.0, "Clearance (distance from the asset to the nearest scan point, "
       "in asset radii) from which Classic, Mipmapped and Hybrid hand the frame to the "
       "environment map: far from every surface the room looks the same from all of the asset. "
       "Only for rough materials and an asset that cannot shadow itself (convex, or asset "
       "self-occlusion off); 0 = never.", 0.0, 1000.0, "x radius", label="envmap beyond",
       redo="gi", ui=False),
    _b("pbgi.shader_variants", True, "The final gather compiled for the material features in "
       "use: no subsurface, anisotropy, sheen or clearcoat code when every material has that "
       "parameter at 0 (one program per feature set, cached); off: one program with all of "
       "them. The same image either way.", label="shader variants", redo="gi", ui=False),
    _i("pbgi.lobe_only_microbuffer", 8, "Micro-buffer size M used instead of "
       "pbgi.microbuffer for each receiver of a glossy metal (metallic 1, "
       "smooth enough that the lobe micro-buffers take its whole specular lobe; other "
       "receivers of the same image keep pbgi.microbuffer): its "
       "light comes from the lobe buffers, and the cosine micro-buffer then holds only the "
       "lobe's far tail (a metal has no diffuse, sheen or subsurface). 0 = always "
       "pbgi.microbuffer; 1-7 act as 8.", 0, 32, "px", label="M for glossy metals",
       redo="gi", ui=False),
    _b("pbgi.differential", True, "Differential rendering: the scan's points near the asset get "
       "its shadow and bounce (gathered with and without the asset, times the points' estimated "
       "albedo) in the background composite.", label="shadow on the scan", redo="gi"),
    _i("pbgi.passes", 1, "Passes averaged in a final render (`scanlight render`): each samples "
       "every pixel at another point inside it (anti-aliased edges and mirror images) and "
       "rotates the lobe micro-buffers (their noise averages out); the time grows with them.",
       1, 64, "", redo="none", ui=False),
    _i("pbgi.glossy_passes", 4, "Passes averaged in a final render (`render`, `turntable`) "
       "where a metal is smoother than pbgi.rough_scale_from: one pass of its lobe micro-buffers "
       "casts one ray per micro-pixel, so a bright light in the lobe's tail counts fully or "
       "not at all (a halo of bright dots around its reflection), and the passes average that "
       "noise as the viewer's idle passes do. The higher of it and pbgi.passes applies; 1 = "
       "pbgi.passes everywhere (README, 'A glossy metal's final render takes 4 passes').", 1,
       64, "", redo="none", ui=False),
    _i("pbgi.edge_samples", 8, "Samples per pixel on the asset's silhouettes in a final render "
       "(`scanlight render`, `turntable`): where coverage or depth changes inside a pixel, "
       "more jittered samples of the G-buffer are gathered there only, so each pixel is "
       "box-filtered over its footprint and alpha is its true coverage; 1 = pixel centres only.",
       1, 64, "", redo="none", ui=False),
    _i("pbgi.idle_passes", 4, "Passes the viewer averages while the view stays still, after "
       "the first full-resolution image (the same jitter as `render --passes`); 1 = none.",
       1, 64, "", label="idle passes", redo="passes"),
    _i("pbgi.rough_idle_passes", 2, "Idle passes when every material is rough (the test of "
       "pbgi.rough_render_scale: pbgi.rough_scale_from): a rough lobe's light changes little "
       "from pass to pass (the demo close-up at balanced: 2.7% per pixel from the converged "
       "mean after 2 passes, 2.1% after 4; a gold at roughness 0.25 11% and 7.7%), so fewer "
       "passes converge it; the lower of it and idle_passes applies (README, 'Fewer idle "
       "passes where the light is rough').", 1, 64, "", label="rough idle passes",
       redo="passes"),
    _f("pbgi.render_scale", 1.0, "GI resolution of a final image relative to its size (the "
       "viewer's layer, refined in tiles when the view is idle, and `render`), brought back to "
       "full resolution by joint bilateral upsampling guided by the full-resolution G-buffer.",
       0.125, 1.0, "x", redo="gi"),
    _f("pbgi.rough_render_scale", 0.5, "GI resolution when every material's specular lobe is "
       "at least pbgi.rough_scale_from rough (no roughness texture): that light is smooth "
       "across a surface, and the trade-off bench measured half resolution as accurate as full "
       "at a third of the time or less; the lower of it and render_scale applies. Narrower "
       "reflections keep render_scale (finer than a low-resolution pixel).", 0.125, 1.0, "x",
       label="rough GI scale", redo="gi"),
    _f("pbgi.rough_scale_from", 0.35, "Roughness from which a specular lobe counts as rough for "
       "pbgi.rough_render_scale (an anisotropic lobe by its narrow axis; a clearcoat does not "
       "count: its lobe is weak), and for pbgi.rough_idle_passes. Measured per roughness "
       "against the path tracer (README, "
       "'Speed against accuracy'); 1 = only fully rough materials.", 0.0, 1.0, "",
       label="rough GI scale from", redo="gi", ui=False),
    _f("pbgi.preview_scale", 0.25, "GI resolution while the camera or a slider moves; upsampled "
       "with joint bilateral weights (depth and normal), as `render --render-scale`.",
       0.0625, 1.0, "x", redo="gi"),
    _f("pbgi.stop_factor", 4.0, "A node is accepted into a receiver's micro-buffer once its solid "
       "angle is at most this times a micro-pixel's (Section 5.3 of the paper: 4); 1 refines "
       "further (sharper near field, slower). Classic, Mipmapped and Hybrid.", 1.0, 16.0, "x",
       label="node stop factor", log=True, redo="gi", ui=False,
       when=("pbgi.mode", ("classic", "mipmapped", "hybrid"))),
    _f("pbgi.omega_tr_factor", 32.0, "Exact Hybrid (parallax tolerance 0): a node is refined "
       "per pixel once its solid angle drops below this factor times the micro-pixel's.",
       1.0, 256.0, "x", label="Omega_tr factor", log=True, redo="gi",
       when=("pbgi.mode", ("hybrid",))),
    _f("pbgi.parallax_tolerance", 1.0, "Hybrid: the far field is walked once per block of "
       "pixels where seen from any pixel of the block it moves by less than this "
       "(micro-pixels); 0 = the exact Hybrid (the same cut as Classic, slower).", 0.0, 4.0, "px",
       label="parallax tolerance", redo="gi", when=("pbgi.mode", ("hybrid",))),
    _f("pbgi.memory_budget_mb", 1024.0, "GPU memory the micro-buffers and the mipmapped/hybrid "
       "pair lists may use before they fall back to smaller batches.", 0.01, 65536.0, "MB",
       label="memory budget", log=True, soft=(64.0, 8192.0), redo="gi"),
    _f("pbgi.frame_budget_ms", 80.0, "GI work per frame while refining: tiles are sized so one "
       "frame stays near this time.", 10.0, 1000.0, "ms", label="frame budget", log=True),
    _i("pbgi.envmap_face", 128, "Environment-map baseline: cube-map face size of the room seen "
       "from the asset centre.", 8, 2048, "px", label="envmap face", redo="gi", ui=False,
       when=("pbgi.mode", ("envmap",))),
    # -- HDR expansion (ExpandParams) -----------------------------------------------------------
    _c("hdr.method", "pmatch-rgb", "Expansion strategy: generalised PatchMatch transferring "
       "colour or luminance from the photo, or inverse tone mapping (Landis / Banterle; '-pc' = "
       "per point).", HDR_METHODS, redo="job"),
    _c("hdr.registration", "auto", "Find the photo's camera in the scan (photometric alignment, "
       "no calibration) and project the photo's HDR values through it; 'off', or when no camera "
       "makes the photo agree with the scan: the method's matching (PatchMatch or ITMO).",
       ("auto", "off"), redo="job"),
    _c("hdr.unseen", "matching", "Registered path: the overexposed points the photo does not see "
       "are filled by Poisson editing, or first matched (the method's PatchMatch / ITMO) when "
       "the matching agrees with the photo on the points both see.", ("matching", "poisson"),
       redo="job",
       when=("hdr.registration", ("auto",))),
    _f("hdr.consistency", 0.35, "Never worse than the scan: an expanded value is rejected (left "
       "to Poisson) when a channel the scan did not clip differs from it by more than this "
       "fraction, or a clipped one falls below its clip level by more than half of it.",
       0.0, 10.0, "", soft=(0.05, 2.0), ui=False, redo="job"),
    _i("hdr.face_size", 512, "Cube-map face resolution of each capture.", 16, 8192, "px",
       soft=(64, 2048), redo="job"),
    _f("hdr.threshold_ldr", 0.9, "t_l: only points whose LDR luminance exceeds this are "
       "expanded.", 0.01, 0.999, "", label="t_l (overexposed)", soft=(0.5, 0.999), redo="job"),
    _f("hdr.threshold_ssd", 1.0, "t_h: PatchMatch matches with a patch SSD above this are "
       "rejected.", 0.001, 1000.0, "", label="t_h (match SSD)", log=True, soft=(0.01, 10.0),
       redo="job", when=("hdr.method", ("pmatch-rgb", "pmatch-lum"))),
    _i("hdr.neighbours", 16, "k of the k-nearest-neighbour graph of the Poisson colour editing.",
       1, 256, "", label="Poisson k", soft=(4, 64), redo="job"),
    _i("hdr.bins", 128, "Histogram bins of the exposure search.", 2, 65536, "",
       soft=(16, 1024), redo="job"),
    _i("hdr.iterations", 50, "Maximum bisection steps of the exposure search.", 0, 1000, "",
       label="exposure iterations", soft=(1, 200), redo="job"),
    _f("hdr.alpha", None, "The scan's exposure alpha (LDR = clamp(alpha x HDR)); not set: found "
       "by the exposure search (paper eq. 1).", 1e-9, 1e9, "", optional=True, ui=False,
       redo="job"),
    _b("hdr.exposure_include_clipped", False, "Exposure search: also match the photo's clipped "
       "pixels (see app/hdr/exposure.py).", ui=False, redo="job"),
    _f("hdr.splat_scale", 1.0, "Capture splat radius relative to the point spacing.", 0.01,
       100.0, "x", ui=False, redo="job"),
    _i("hdr.pm_face_size", 128, "PatchMatch works on capture faces box-downsampled to this.",
       16, 4096, "px", ui=False, redo="job"),
    _i("hdr.pm_photo_size", 256, "PatchMatch works on the photo box-downsampled to this.", 16,
       4096, "px", ui=False, redo="job"),
    _i("hdr.pm_patch_radius", 3, "PatchMatch patch radius (3 = 7x7 patches).", 1, 8, "px",
       ui=False, redo="job"),
    _i("hdr.pm_iterations", 4, "PatchMatch iterations per pyramid level.", 1, 100, "",
       ui=False, redo="job"),
    _i("hdr.pm_levels", 3, "PatchMatch pyramid levels.", 1, 8, "", ui=False, redo="job"),
    _f("hdr.pm_scale_min", 0.25, "PatchMatch: smallest patch scale searched.", 1e-3, 1e3, "x",
       ui=False, redo="job"),
    _f("hdr.pm_scale_max", 4.0, "PatchMatch: largest patch scale searched.", 1e-3, 1e3, "x",
       ui=False, redo="job"),
    _c("hdr.pm_match", "rgb", "PatchMatch matches on colour or luminance (what is transferred "
       "is the method's: pmatch-rgb colour, pmatch-lum luminance).", ("rgb", "luminance"),
       ui=False, redo="job"),
    _f("hdr.pm_scale_tolerance", 0.75, "Octaves a match's scale may stray from the common one; "
       "not set: no check.", 0.0, 100.0, "octaves", optional=True, ui=False, redo="job"),
    _f("hdr.good_match_ssd", 0.02, "A textured pixel matched better than this x t_h is a close "
       "match.", 0.0, 1.0, "", ui=False, redo="job"),
    _f("hdr.good_match_min", 0.02, "Warn (another scene?) when fewer textured pixels match "
       "closely.", 0.0, 1.0, "", ui=False, redo="job"),
    _f("hdr.landis_threshold", None, "Landis' operator threshold; not set: t_l.", 0.0, 1.0, "",
       optional=True, ui=False, redo="job"),
    _f("hdr.landis_exponent", 2.0, "Landis' operator exponent.", 0.01, 100.0, "", ui=False,
       redo="job"),
    _f("hdr.l_max_percentile", 99.9, "Inverse tone mapping peak: this percentile of the photo's "
       "luminance.", 50.0, 100.0, "%", ui=False, redo="job"),
    _c("hdr.poisson_solver", "auto", "Poisson fill solver: sparse LU, conjugate gradients, or "
       "auto (LU up to 100k unknowns; app/hdr/poisson.py).", ("auto", "direct", "cg"),
       ui=False, redo="job"),
    _i("hdr.seed", 0, "Random seed of PatchMatch's initialisation.", 0, 2**31 - 1, "",
       ui=False, redo="job"),
)

BY_KEY: dict[str, Param] = {p.key: p for p in PARAMS}
assert len(BY_KEY) == len(PARAMS), "a key is declared twice"
assert all(p.when is None or set(p.when[1]) <= set(BY_KEY[p.when[0]].choices) for p in PARAMS)
QUALITY_KEYS = tuple(dict.fromkeys(k for preset in QUALITY_PRESETS.values() for k in preset))
assert all(set(p) == set(QUALITY_KEYS) for p in QUALITY_PRESETS.values()), \
    "every preset sets the same keys"
assert all(BY_KEY[k].check(v) == v for p in QUALITY_PRESETS.values() for k, v in p.items())
assert all(BY_KEY[k].default == v for k, v in QUALITY_PRESETS[DEFAULT_QUALITY].items()), \
    "the table's defaults are the default preset's values"


def group(name: str, ui_only: bool = False) -> tuple[Param, ...]:
    return tuple(p for p in PARAMS if p.group == name and (p.ui or not ui_only))


# ------------------------------------------------------------------------------------------------
# Records: a dataclass whose fields are rows of the table.

def param_record(*keys: str):
    """Class decorator: the class becomes a frozen dataclass with one field per key (named by the
    key's ``name``, default from the table) plus ``validated()``, ``from_dict()``,
    ``from_settings()`` and ``to_settings()``. The class body keeps its own methods and
    properties; it declares no field of its own."""

    def make(cls):
        specs = [BY_KEY[k] for k in keys]
        fields = [(p.name, Any, dataclasses.field(default=p.default)) for p in specs]
        ns = {k: v for k, v in vars(cls).items() if k not in ("__dict__", "__weakref__")}
        rec = dataclasses.make_dataclass(cls.__name__, fields, namespace=ns, frozen=True)
        rec.__module__ = cls.__module__
        rec.__qualname__ = cls.__qualname__
        rec.PARAMS = tuple(specs)
        rec.KEYS = tuple(keys)

        def validated(self, source=None):
            """self with every field checked against its row (typed, in range), or a
            ScanlightError naming the first bad one."""
            vals = {p.name: p.check(getattr(self, p.name), source,
                                    f"{cls.__name__.lower().replace('params', '')} parameter "
                                    f"{p.name!r}")
                    for p in specs}
            out = dataclasses.replace(self, **vals)
            extra = getattr(out, "_check", None)
            if extra is not None:
                extra(source)
            return out

        def from_dict(d: dict, source=None):
            """From field names (or full keys); unknown names are an error."""
            names = {p.name for p in specs}
            vals = {}
            for k, v in dict(d).items():
                n = k.split(".", 1)[1] if k in BY_KEY and BY_KEY[k] in specs else k
                if n not in names:
                    raise ScanlightError(source, f"unknown {cls.__name__} field {k!r} "
                                                 f"(known: {', '.join(sorted(names))})")
                vals[n] = v
            return rec(**vals).validated(source)

        def from_settings(settings, **overrides):
            """From anything indexable by key (app.settings.Settings, a dict of keys); fields
            given as ``overrides`` (by field name) replace the settings' values."""
            vals = {p.name: settings[p.key] for p in specs if p.name not in overrides}
            return rec(**vals, **overrides).validated()

        def to_settings(self) -> dict:
            return {p.key: getattr(self, p.name) for p in specs}

        rec.validated = validated
        rec.from_dict = staticmethod(from_dict)
        rec.from_settings = staticmethod(from_settings)
        rec.to_settings = to_settings
        return rec

    return make


RENDER_KEYS = ("pbgi.mode", "pbgi.microbuffer", "pbgi.omega_tr_factor",
               "pbgi.parallax_tolerance", "pbgi.memory_budget_mb", "pbgi.envmap_face",
               "pbgi.glossy_below", "pbgi.asset_occlusion", "pbgi.asset_bounces",
               "pbgi.asset_surfels", "pbgi.stop_factor", "pbgi.shader_variants",
               "pbgi.envmap_beyond", "pbgi.lobe_only_microbuffer")
EXPAND_KEYS = tuple(p.key for p in PARAMS if p.group == "hdr")


def markdown_table(keys=None) -> str:
    """The parameter table for the README (tests/cli/test_params.py checks the README holds it)."""
    rows = ["| key | type | default | range | unit | what it does |", "|---|---|---|---|---|---|"]
    for p in (BY_KEY[k] for k in (keys or BY_KEY)):
        default = "not set" if p.default is None else p.default
        rows.append(f"| `{p.key}` | {p.kind} | {default} | {p.range_text()} | {p.unit} | "
                    f"{p.help} |")
    return "\n".join(rows)
