"""The viewer's engine: reads the session, owns the scene, the renderers and the refinement, and
draws one frame. No imgui here: the window (app/ui/app.py) and the offscreen runner both drive
this class, so batch screenshots are what the window shows.

The renderer is injected: ``ViewerEngine(ctx, session, size, relighter=...)`` takes a relighter
(anything with the ``app.pbgi.renderer.Relighter`` interface) or a factory ``f(ctx=...)`` making
one. The window and the offscreen runner pass the real ``Relighter``; tests pass theirs the same
way. A factory that raises leaves the viewer running: the reason is a message, and the asset
shows the "renderer unavailable" placeholder.

Each frame ``frame()`` takes the session's change set and dispatches it to the handlers
connected in ``_connect_handlers`` (``app.settings.ChangeHandlers``), in this order:

    files.cloud, files.hdr_cloud   reload the scan (and photo); new splats; Relighter.set_cloud
    files.photo (alone)            reload the photo
    view.cloud                     new splat colours; relight with that cloud (cheap set_cloud)
    files.asset                    load the mesh; new G-buffer geometry; Relighter.set_asset
    asset.transform                re-place the mesh (no reload); set_asset; its G-buffer
    view.fov_y                     the navigator's field of view
    camera                         the navigator follows the session's camera
    materials                      recombine the layer's gather in parts when the edit allows
                                   (app/pbgi/gather_parts.py: base colour, metallic, specular,
                                   sheen, clearcoat amount); else re-gather (uniforms)
    files.hdri, light.source, light.hdri_rotation, compare.enabled, compare.b
                                   which HDRI lights A and B (Relighter.set_hdri; the panorama
                                   replaces the room behind that side); re-gather
    table parameters by their ``Param.redo`` (app/params.py): "room" redraws the splats, "gi"
    re-gathers, "display" re-composites, "passes" re-gathers when the scene's count of idle
    passes changes; "job" and "none" redo nothing here.

The A/B compare (app/ui/compare.py): a second GI layer ``gi_b`` gathered by a second renderer
with B's settings, refined in turns with A under the same frame budget, composited right of the
divider (``compare.split``); ``compare_metrics`` once both are refined.

A camera move (any navigation, or the field of view) redraws the room and G-buffer and
re-gathers; ``frame()`` finds it by comparing cameras, not through the change set.

The asset in the room (app/pbgi/asset_scene.py): while the user drags (``interacting``) and the
asset's surfel tree or bounce would have to be rebuilt, the previews render without them rather
than wait for a rebuild per frame; the first render after the drag builds them. Its shadow and
bounce on the scan (``pbgi.differential``) are gathered once the picture is refined, in steps
of DIFFERENTIAL_CHUNK points, as many as the frame's budget allows
(``Relighter.differential_steps``), and then shown on the splats as a
per-point factor (L + delta) / L of the lighting cloud's radiance, so the LDR, HDR and expanded
displays all darken by the same ratio. A moved asset drops the old shadow at once.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field, replace

import numpy as np

from app.camera import Camera
from app.errors import ScanlightError
from app.pbgi.renderer import RenderParams
from app.pbgi.stats import RenderStats
from app.settings import ChangeHandlers, Session
from app.ui.compare import b_settings, label_rects, layer_metrics, side_names, split_column
from app.ui.navigation import ViewNavigator, scan_floor
from app.ui.refine import ProgressiveGI, scaled_camera, screen_rect
from app.ui.scene import Asset, Cloud, copy_materials, load_cloud_files
from app.ui.viewport import ViewportRenderer

log = logging.getLogger(__name__)

# scan points the differential gathers per step: a step is the frame's smallest unit of work
# (tens of ms on llvmpipe), so a drag that starts during one is not swallowed by it
DIFFERENTIAL_CHUNK = 64

# the session-document keys whose change re-composites the whole picture (room pass included)
RECOMPOSITE_KEYS = ("files.cloud", "files.hdr_cloud", "files.photo", "files.asset",
                    "asset.transform", "camera", "view.cloud", "view.fov_y")


@dataclass
class Message:
    text: str
    level: str = "error"   # error | warning | info
    time: float = field(default_factory=time.time)


def make_relighter(relighter, ctx):
    """The relighter itself when given one, else what the factory ``relighter(ctx=ctx)`` makes.
    A class is a factory (``Relighter`` is passed as its own factory)."""
    if hasattr(relighter, "render") and not isinstance(relighter, type):
        return relighter
    return relighter(ctx=ctx)


def text_image(text: str, scale: int = 2) -> np.ndarray:
    """White text with a dark outline as an RGBA8 image (row 0 at the top)."""
    from PIL import Image, ImageDraw, ImageFont
    font = ImageFont.load_default()
    probe = ImageDraw.Draw(Image.new("L", (1, 1)))
    x0, y0, x1, y1 = probe.textbbox((0, 0), text, font=font)
    w, h = x1 - x0 + 8, y1 - y0 + 8
    img = Image.new("RGBA", (w, h), (0, 0, 0, 170))
    ImageDraw.Draw(img).text((4 - x0, 4 - y0), text, fill=(255, 255, 255, 255), font=font)
    a = np.asarray(img)
    return np.repeat(np.repeat(a, scale, axis=0), scale, axis=1) if scale > 1 else a


class ViewerEngine:
    def __init__(self, ctx, session: Session, size=(960, 600), *, relighter):
        self.ctx = ctx
        self.session = session
        self.size = tuple(int(v) for v in size)
        self.messages: list[Message] = []
        self.view = ViewportRenderer(ctx)
        self.view.resize(*self.size)
        self.cloud: Cloud | None = None
        self.photo: np.ndarray | None = None
        self.asset: Asset | None = None
        self.mesh = None
        self.relighter = None
        self._layer_scale = 1.0           # the GI layer's resolution as _restart_gi chose it
        self.relighter_error: str | None = None
        self._lit_cloud = None
        self.gi = ProgressiveGI(self._render_gi)
        # the A/B compare (app/ui/compare.py): B's GI layer and its own renderer, so neither
        # side's caches are thrown away by the other's renders
        self.gi_b = ProgressiveGI(self._render_gi_b)
        self.relighter_b = None
        self._b_active = False          # B is being refined and shown
        self._b_turn = False            # B's frame (A and B refine in turns)
        self._b_given: dict = {}        # what relighter_b was last handed (cloud, mesh, hdri)
        self.compare_labels = None
        self.compare_metrics: dict | None = None    # B against A, once both are refined
        # HDRI lighting (light.source, session.hdri): the file loaded once, rotated per setting
        self._hdri = None               # (path, Hdri)
        self._hdri_failed = None        # the path that failed to load (reported once)
        self.hdri_a = self.hdri_b = None    # the HDRI lighting each side, None: the scan
        self.gi_stats: RenderStats | None = None    # the last gather that had receivers
        self._gathered_materials = None     # the materials A's layer was gathered with
        # the last material edit: "recombined", or why it was gathered again
        self.material_edit: str | None = None
        self._recoloured = False        # this frame recombined the layer: present it first
        self.gi_failed = False
        self.frame_ms: list[float] = []
        self.timings: dict = {}
        self._last_camera_key = None
        self._room_dirty = True
        self._room_fast = False         # the backdrop on screen is the moving camera's cheap one
        self._gbuffer_dirty = True      # the asset's G-buffer alone (a new placement)
        self._composite_dirty = True
        self._asset_dirty = True
        self._gi_dirty = True
        self.nav = ViewNavigator(fov_y_deg=session.settings["view.fov_y"])
        self.floor_y: float | None = None     # the scan's floor, for the navigator
        self._interacting = False
        self._diff_steps = None         # the differential being gathered (a generator)
        self._diff_steps_key = None
        self._diff_shown_key = None     # the differential on the splats (None: plain colours)
        self.differential_progress = 0.0
        self.changes = ChangeHandlers()
        self._connect_handlers()
        self._init_camera()
        self._start_relighter(relighter)
        self.load_cloud()
        self.load_asset()
        self._sync_light()

    # -- messages --------------------------------------------------------------------------------
    def error(self, text: str, level: str = "error") -> None:
        """A message for the user: the window shows it, an offscreen run prints it (or fails
        with it); the log keeps it at debug level so stderr carries each line once."""
        log.debug("%s: %s", level, text)
        if not self.messages or self.messages[-1].text != text:
            self.messages.append(Message(text, level))
        del self.messages[:-20]

    def guard(self, what: str, fn, *args, **kwargs):
        """Run ``fn``; a failure becomes a message in the window, never a crash."""
        try:
            return fn(*args, **kwargs)
        except Exception as exc:  # a bug: say what failed, keep the viewer alive
            self.report_failure(what, exc)
        return None

    def report_failure(self, what: str, exc: Exception) -> None:
        """One message for a failure: a ScanlightError says its reason, so does the machine's
        refusal (a full disk, a read-only folder, no memory left: OSError, MemoryError - the
        environment, not a bug); anything else is a bug, logged with its traceback."""
        from app.errors import refusal
        if isinstance(exc, ScanlightError):
            self.error(f"{what}: {exc}")
        elif refusal(exc) is not None:
            self.error(f"{what}: {refusal(exc)}")
        else:
            log.exception("%s failed", what)
            self.error(f"{what} failed: {type(exc).__name__}: {exc}")

    # -- loading ---------------------------------------------------------------------------------
    def _init_camera(self) -> None:
        s = self.session
        if s.camera is not None:
            self.nav = ViewNavigator.from_camera(s.camera)
            s.settings.set("view.fov_y", s.camera.fov_y_deg)
        else:
            from app.demo.room import default_views
            self.nav = ViewNavigator.from_camera(default_views()["whole"])
            self.nav.fov_y_deg = s.settings["view.fov_y"]

    def _start_relighter(self, relighter) -> None:
        """Take the injected relighter (or make it); a failure leaves the viewer without one."""
        # B's renderer is made the same way (a relighter handed in: another of its class)
        self._relighter_factory = (relighter if isinstance(relighter, type)
                                   or not hasattr(relighter, "render") else type(relighter))
        try:
            self.relighter = make_relighter(relighter, self.ctx)
        except Exception as exc:  # a missing module, no compute shaders, ...: the viewer runs on
            self.relighter_error = f"{type(exc).__name__}: {exc}"
            self.error(f"relighting renderer failed to start: {self.relighter_error}")

    @property
    def renderer_available(self) -> bool:
        return self.relighter is not None

    def load_cloud(self) -> None:
        loaded = self.guard("opening the scan (its clouds and photo)", load_cloud_files,
                            self.session)
        if loaded is None:
            if self.cloud is None:  # nothing to show yet: an empty room
                from app.cloud import PointCloud
                empty = PointCloud(np.zeros((1, 3)), np.array([[0, 1, 0]]), np.zeros((1, 3)))
                self.cloud = Cloud(empty)
                self.view.set_cloud(empty)
            return
        self.cloud, photo = loaded
        self.floor_y = scan_floor(self.cloud.ldr.positions, self.cloud.ldr.normals)
        self.sync_nav()
        if photo is not None or self.session.photo is None:
            self.photo = photo
        self.view.set_cloud(self.cloud.ldr)
        if self.cloud.hdr is not None and self.session.settings["view.cloud"] == "ldr":
            self.session.settings.set("view.cloud", "hdr")
        self._apply_colors()

    def set_hdr_cloud(self, hdr, path: str | None = None) -> None:
        """The expansion result: switch the display and the lighting to HDR."""
        self.cloud.hdr = hdr
        self.session.hdr_cloud = path
        self.session.settings.set("view.cloud", "hdr")
        self._apply_colors()

    def _apply_colors(self) -> None:
        which = self.session.settings["view.cloud"]
        self.view.set_colors(self.cloud.colors(which), categorical=which == "provenance")
        self._diff_shown_key = None
        self._room_dirty = True
        lit = self.cloud.lighting(which)
        if self.relighter is not None and lit is not self._lit_cloud:
            self._lit_cloud = lit
            t0 = time.perf_counter()
            self.guard("building the light hierarchy", self.relighter.set_cloud, lit)
            self.timings["set_cloud_ms"] = (time.perf_counter() - t0) * 1e3
        self._gi_dirty = True

    def load_asset(self) -> None:
        asset = self.guard("opening the asset", Asset, self.session.asset)
        if asset is None:
            return
        self.asset = asset
        mats = self.session.materials
        if mats is None or len(mats) != len(asset.materials):
            if mats is not None:
                self.error(f"the session has {len(mats)} materials but the asset has "
                           f"{len(asset.materials)}: using the asset's", "warning")
            self.session.materials = copy_materials(asset.materials)
        self.place_asset()

    def place_asset(self) -> None:
        if self.asset is None:
            return
        mesh = self.guard("placing the asset", self.asset.placed, self.session.transform)
        if mesh is None:
            return
        self.mesh = mesh
        self.view.set_asset(mesh)
        if self.relighter is not None:
            self.guard("uploading the asset", self.relighter.set_asset, mesh)
        self._gbuffer_dirty = self._gi_dirty = True
        self._show_differential(None)       # the old shadow is in the wrong place now

    def reset_materials(self) -> None:
        if self.asset is not None:
            self.session.set_materials(copy_materials(self.asset.materials))

    # -- bounds / framing ------------------------------------------------------------------------
    def asset_sphere(self) -> tuple[np.ndarray, float]:
        if self.mesh is None:
            return np.asarray(self.session.transform.translate, float), 0.5
        lo, hi = (np.asarray(v, float) for v in self.mesh.bounds())
        return (lo + hi) / 2, float(np.linalg.norm(hi - lo)) / 2

    def room(self):
        """The scan's floor and centre (app/io/placement.py: Room), where a mesh opened directly
        stands (drag-and-drop, ``scanlight view CLOUD ASSET``)."""
        from app.io.placement import room_of
        return room_of(self.cloud.ldr)

    def frame_asset(self) -> None:
        c, r = self.asset_sphere()
        self.nav.frame(c, r, self.size[0] / self.size[1])

    def camera(self) -> Camera:
        return self.nav.camera(*self.size)

    # -- the frame -------------------------------------------------------------------------------
    def resize(self, width: int, height: int) -> None:
        if (width, height) != self.size and width > 0 and height > 0:
            self.size = (int(width), int(height))
            self.view.resize(*self.size)
            self._room_dirty = self._gi_dirty = True

    # -- change handlers -------------------------------------------------------------------------
    def _connect_handlers(self) -> None:
        """Who handles which change key. The connection order is the order of the work: the
        room before its colours, the asset before its placement, the field of view before the
        session camera (which carries its own)."""
        c = self.changes
        c.connect(("files.cloud", "files.hdr_cloud", "files.photo"), self._on_room_files)
        c.connect("view.cloud", self._on_cloud_colors)
        c.connect(("files.asset", "asset.transform"), self._on_asset)
        c.connect("view.fov_y", self._on_fov)
        c.connect("camera", self._on_camera)
        c.connect("materials", self._on_materials)
        c.connect(("files.hdri", "light.source", "light.hdri_rotation", "compare.enabled",
                   "compare.b"), self._on_light)
        c.connect(RECOMPOSITE_KEYS, self._redo_composite)
        # table parameters: what a change invalidates is their Param.redo (app/params.py)
        c.connect_redo("room", self._redo_room)
        c.connect_redo("gi", self._redo_gi)
        c.connect_redo("display", self._redo_composite)
        c.connect_redo("passes", self._on_idle_passes)

    def apply_changes(self) -> frozenset:
        """Hand the session's change set to the handlers; returns it."""
        changes = self.session.settings.take_changes()
        if changes:
            self.changes.dispatch(changes)
        return changes

    def _on_room_files(self, keys) -> None:
        if keys & {"files.cloud", "files.hdr_cloud"}:
            self._lit_cloud = None
            self.load_cloud()       # the photo comes with the scan
        elif self.session.photo:
            photo = self.guard("opening the photo", self._load_photo)
            if photo is not None:
                self.photo = photo

    def _on_cloud_colors(self, keys) -> None:
        self._apply_colors()

    def _on_asset(self, keys) -> None:
        if "files.asset" in keys:
            self.load_asset()       # places it too
        else:
            self.place_asset()

    def _on_light(self, keys) -> None:
        if "files.hdri" in keys:
            self._hdri = self._hdri_failed = None
        self._sync_light()
        self._room_dirty = self._gi_dirty = True

    # -- HDRI lighting and the A/B compare -------------------------------------------------------
    @property
    def compare_on(self) -> bool:
        return bool(self.session.settings["compare.enabled"]) and self.mesh is not None

    @property
    def b_refining(self) -> bool:
        """B's layer of the compare is shown and still refining."""
        return self._b_active and self.gi_b.refining

    def _load_hdri(self):
        """The session's HDRI at the rotation setting, or None (no file, or a bad one: one
        message per file, then the scan lights)."""
        path = self.session.hdri
        if path is None:
            self.error("light: no HDRI file chosen (Light panel: open...): lit by the scan",
                       "warning")
            return None
        if self._hdri_failed == path:
            return None
        if self._hdri is None or self._hdri[0] != path:
            from app.pbgi.hdri import load_hdri
            try:
                self._hdri = (path, load_hdri(path))
            except Exception as exc:
                self._hdri_failed = path
                self.report_failure("opening the HDRI", exc)
                return None
        hdri, rot = self._hdri[1], float(self.session.settings["light.hdri_rotation"])
        return hdri if hdri.rotation_deg == rot else hdri.rotated(rot)

    def _sync_light(self) -> None:
        """Which HDRI lights A (``light.source``) and B (the other light when B compares
        lights); A's renderer gets its HDRI here, B's in ``_sync_b``."""
        s = self.session.settings
        a = s["light.source"] == "hdri"
        b = (not a) if self.compare_on and s["compare.b"] == "hdri" else a
        hdri = self._load_hdri() if (a or b) else None
        self.hdri_a, self.hdri_b = (hdri if a else None), (hdri if b else None)
        key = None if self.hdri_a is None else self.hdri_a.key
        given = getattr(getattr(self.relighter, "hdri", None), "key", None)
        if self.relighter is not None and given != key:
            self.guard("lighting with the HDRI", self.relighter.set_hdri, self.hdri_a)
            self._show_differential(None)       # the scan's shadow is not shown under an HDRI

    def _b_cloud(self):
        """The cloud lighting B: A's, or the other one when B compares clouds."""
        s = self.session.settings
        lit = self.cloud.lighting(s["view.cloud"])
        if s["compare.b"] != "cloud":
            return lit
        if self.cloud.hdr is None:
            self.error("compare: no HDR cloud yet (run the HDR expansion): B is lit by the "
                       "scan too", "warning")
            return lit
        return self.cloud.ldr if lit is self.cloud.hdr else self.cloud.hdr

    def _sync_b(self) -> bool:
        """Hand B's renderer what changed since (made on the first compare); False: none."""
        if self.relighter is None:
            return False
        if self.relighter_b is None:
            t0 = time.perf_counter()
            self.relighter_b = self.guard("starting B's renderer", make_relighter,
                                          self._relighter_factory, self.ctx)
            self.timings["compare_start_ms"] = (time.perf_counter() - t0) * 1e3
            self._b_given = {}
            if self.relighter_b is None:
                return False
        r, given = self.relighter_b, self._b_given
        cloud, key = self._b_cloud(), None if self.hdri_b is None else self.hdri_b.key
        if given.get("cloud") is not cloud:
            t0 = time.perf_counter()
            try:
                r.set_cloud(cloud)
            except Exception as exc:
                self.report_failure("building B's light hierarchy", exc)
                return False
            self.timings["set_cloud_b_ms"] = (time.perf_counter() - t0) * 1e3
            given["cloud"] = cloud
        if given.get("mesh") is not self.mesh:
            self.guard("uploading the asset for B", r.set_asset, self.mesh)
            given["mesh"] = self.mesh
        if given.get("hdri", ()) != key:
            self.guard("lighting B with the HDRI", r.set_hdri, self.hdri_b)
            given["hdri"] = key
        return True

    def _set_side_labels(self) -> None:
        s = self.session.settings
        a_hdr = self.cloud.lighting(s["view.cloud"]) is self.cloud.hdr
        b_hdr = a_hdr if s["compare.b"] != "cloud" or self.cloud.hdr is None else not a_hdr
        names = side_names(s, None if self.hdri_a is None else self.session.hdri,
                           None if self.hdri_b is None else self.session.hdri, a_hdr, b_hdr)
        if names != self.compare_labels:
            self.compare_labels = names
            self.view.set_side_labels([text_image(n, 1) for n in names])

    def _draw_backdrops(self, cam: Camera) -> None:
        """The HDRI's panorama behind the side it lights, instead of the room's splats."""
        from app.pbgi.hdri import hdri_backdrop
        t = time.perf_counter()
        for side, hdri in ((self.view.side_a, self.hdri_a),
                           (self.view.side_b, self.hdri_b if self.compare_on else None)):
            self.view.set_backdrop(side, None if hdri is None else hdri_backdrop(hdri, cam))
        self.timings["backdrop_ms"] = (time.perf_counter() - t) * 1e3

    def _on_fov(self, keys) -> None:
        self.nav.fov_y_deg = self.session.settings["view.fov_y"]

    def _on_camera(self, keys) -> None:
        if self.session.camera is not None:
            self.nav = ViewNavigator.from_camera(self.session.camera)
            self.sync_nav()

    def sync_nav(self) -> None:
        """The navigator keeps the eye above the scan's floor unless the user freed it."""
        self.nav.floor_y = self.floor_y
        self.nav.free = bool(self.session.settings["view.free_orbit"])

    def _redo_room(self, keys) -> None:
        self._room_dirty = self._composite_dirty = True

    def _redo_gi(self, keys) -> None:
        self._gi_dirty = True

    def _on_materials(self, keys) -> None:
        """A material edit: the layer's gather in parts recombined with the new materials where
        that is what a new gather would give (app/pbgi/gather_parts.py), else a new gather."""
        why = self._recombine_materials()
        self.material_edit = "recombined" if why is None else why
        if why is not None:
            self._redo_gi(keys)

    def _recombine_materials(self) -> str | None:
        """Recolour A's layer for the session's materials; None when done, else why not."""
        from app.pbgi.gather_parts import changed, recombinable, recombine
        old, r = self._gathered_materials, self.relighter
        if self._gi_dirty or old is None or self.mesh is None:
            return "the picture is gathered anew anyway"
        if not self.renderer_available or self.gi_failed:
            return "no renderer"
        if self._b_active:
            return "the A/B compare gathers both sides again"
        params = RenderParams.from_settings(self.session.settings)
        try:
            old, new = r.materials_for(old), r.materials_for(self.session.materials)
        except ScanlightError as exc:
            return str(exc)
        why = recombinable(old, new, params, r.walks_asset(params))
        if why is not None:
            return why
        if self.layer_scale(self.session.settings) != self._layer_scale:
            return "the GI resolution changes (pbgi.rough_render_scale)"
        if self.layer_passes(self.session.settings) != self.gi.passes:
            return "the number of idle passes changes (pbgi.rough_idle_passes)"
        edited = [i for i, (a, b) in enumerate(zip(old, new)) if changed(a, b)]
        if edited and not self.gi.recolour(edited, lambda rec, i: recombine(rec, new[i])):
            return "the picture holds no parts, or a pixel mixes an edited material with another"
        self._gathered_materials = list(self.session.materials)
        self._asset_dirty = self._recoloured = True
        return None

    def _on_idle_passes(self, keys) -> None:
        """A new count of idle passes (``layer_passes``) starts the passes over: each pass's
        sample is placed for the count (app/pbgi/gbuffer.py: pass_jitter centres them), so
        passes cannot be added to or cut from a mean already begun. An edit that leaves the
        scene's count as it is (4 -> 8 idle passes of a rough scene that takes 2) redoes
        nothing."""
        s = self.session.settings
        if self.layer_passes(s) != self.gi.passes or (
                self._b_active and self.layer_passes(b_settings(s)) != self.gi_b.passes):
            self._redo_gi(keys)

    def _redo_composite(self, keys) -> None:
        self._composite_dirty = True

    def _load_photo(self):
        from app.ui.scene import load_photo
        return load_photo(self.session.photo)

    def reset_gl_state(self) -> None:
        """Back to GL defaults (no blending, no depth test, no scissor): the imgui renderer leaves
        blending on, which would silently mask the G-buffer writes of the passes that follow."""
        import moderngl
        self.ctx.enable_only(moderngl.NOTHING)
        self.ctx.scissor = None

    def frame(self, interacting: bool = False, budget_ms: float | None = None) -> dict:
        """Advance one frame; returns what happened (for stats and tests)."""
        t0 = time.perf_counter()
        self.reset_gl_state()
        self.apply_changes()
        self.sync_nav()
        cam = self.camera()
        key = (tuple(np.round(cam.position, 9)), tuple(np.round(cam.look_at, 9)),
               cam.fov_y_deg, cam.width, cam.height)
        if key != self._last_camera_key:
            self._last_camera_key = key
            self._room_dirty = self._gi_dirty = True
        if self._room_fast and not interacting:
            self._room_dirty = True         # the camera stopped: the full backdrop now
        info = {"room": False, "gi": False}
        if self._room_dirty:
            t = time.perf_counter()
            # while the camera moves, the cheap backdrop (several times faster at window size)
            self._room_fast = bool(interacting)
            self.view.draw_room(cam, self.session.settings["view.splat_scale"],
                                self.session.settings["view.eye_dome"], fast=self._room_fast)
            info["room_fast"] = self._room_fast
            self.view.draw_gbuffer(cam)
            self.timings["room_ms"] = (time.perf_counter() - t) * 1e3
            self._draw_backdrops(cam)
            self._room_dirty = self._gbuffer_dirty = False
            self._composite_dirty = info["room"] = True
        elif self._gbuffer_dirty:
            # the asset moved but not the camera: its silhouette and depth follow it, and the
            # whole picture is re-composited (the room reappears where the asset was)
            self.view.draw_gbuffer(cam)
            self._gbuffer_dirty = False
            self._composite_dirty = True
        if self._gi_dirty:
            self._restart_gi(cam)
        budget = self.session.settings["pbgi.frame_budget_ms"] if budget_ms is None else budget_ms
        self._interacting = bool(interacting)
        # A and B (the compare) share the frame's budget: while both refine they take turns
        layers = [g for g in (self.gi, self.gi_b if self._b_active else None)
                  if g is not None and g.refining]
        if self.renderer_available and not self.gi_failed and layers:
            self.reset_gl_state()
            t = time.perf_counter()
            self._b_turn = not self._b_turn
            layer = layers[-1] if self._b_turn else layers[0]
            if layer.step(budget, allow_tiles=not interacting):
                info["gi"] = True
            self.timings["gi_frame_ms"] = (time.perf_counter() - t) * 1e3
            self._compare_metrics()
        elif not interacting and not self._recoloured:
            # (a recoloured picture is shown first: the new shadow's first step, the asset's
            # bounce for the new albedo, can take a whole budget)
            self.reset_gl_state()
            info["differential"] = self._advance_differential(budget)
        self._recoloured = False
        if self._room_dirty:                # the differential changed the splats' colours
            self.view.draw_room(cam, self.session.settings["view.splat_scale"],
                                self.session.settings["view.eye_dome"])
            self._room_dirty = False
            self._composite_dirty = True
        whole = self._asset_dirty           # set before the new tiles: the whole asset
        tiles = self._upload_gi()
        if self._composite_dirty or self._asset_dirty:
            self._composite(cam, room=self._composite_dirty,
                            only=None if whole or self._b_active else tiles)
        ms = (time.perf_counter() - t0) * 1e3
        self.frame_ms.append(ms)
        del self.frame_ms[:-240]
        info["ms"] = ms
        return info

    def layer_scale(self, values) -> float:
        """The GI layer's resolution for these settings and the session's materials
        (app/pbgi/upsample.py: gi_scale - ``pbgi.rough_render_scale`` while every material is
        at least ``pbgi.rough_scale_from`` rough, ``pbgi.render_scale`` otherwise)."""
        from app.pbgi.upsample import gi_scale_of
        materials = self._scene_materials()
        if materials is None:
            return float(values["pbgi.render_scale"])
        return gi_scale_of(values, materials)

    def _scene_materials(self):
        """The renderer's materials for the session's, or None: nothing to gather yet, or
        materials the asset cannot take (then the plain scale and passes apply)."""
        r = self.relighter
        if r is None or r.mesh is None:
            return None
        try:
            return r.materials_for(self.session.materials)
        except ScanlightError:
            return None

    def layer_passes(self, values) -> int:
        """Idle passes for these settings and the session's materials: the lower of
        ``pbgi.idle_passes`` and ``pbgi.rough_idle_passes`` while every material is rough in the
        sense of ``layer_scale`` (app/pbgi/upsample.py: rough_scene), ``pbgi.idle_passes``
        otherwise. Passes average pass-to-pass noise, and a rough lobe has little of it."""
        from app.pbgi.upsample import rough_scene
        idle = int(values["pbgi.idle_passes"])
        materials = self._scene_materials()
        if materials is None:
            return idle
        if rough_scene(materials, values["pbgi.rough_scale_from"]):
            return min(idle, int(values["pbgi.rough_idle_passes"]))
        return idle

    def _restart_gi(self, cam: Camera) -> None:
        self._gi_dirty = False
        self.gi_failed = False
        if self.mesh is None:
            return
        self._layer_scale = self.layer_scale(self.session.settings)
        layer = scaled_camera(cam, self._layer_scale)
        rect = screen_rect(layer, *self.mesh.bounds())
        s = self.session.settings
        self.gi.restart(layer, rect, s["pbgi.preview_scale"], s["pbgi.frame_budget_ms"],
                        self.layer_passes(s))
        self._gathered_materials = (None if self.session.materials is None
                                    else list(self.session.materials))
        self._asset_dirty = True
        self.compare_metrics = None
        self._b_active = self.compare_on and self.renderer_available and self._sync_b()
        if self._b_active:
            layer_b = scaled_camera(cam, self.layer_scale(b_settings(s)))
            self.gi_b.restart(layer_b, screen_rect(layer_b, *self.mesh.bounds()),
                              s["pbgi.preview_scale"], s["pbgi.frame_budget_ms"],
                              self.layer_passes(b_settings(s)))
            self._set_side_labels()

    def _compare_metrics(self) -> None:
        """B against A (render --compare's metrics) once both layers are refined."""
        if (self._b_active and self.compare_metrics is None and not self.gi.refining
                and not self.gi_b.refining and not self.gi_failed):
            t = time.perf_counter()
            self.compare_metrics = self.guard("the A/B metrics", layer_metrics, self.gi.full,
                                              self.gi_b.full) or {}
            self.timings["compare_metrics_ms"] = (time.perf_counter() - t) * 1e3

    def _upload_gi(self):
        """Send what the GI layers changed to their textures. Returns the screen rectangles
        (x0, y0, x1, y1), row 0 at the top, that A's new tiles can change in the composite
        when they are all that changed (else None: the whole asset)."""
        if self.gi.full is None:
            return None
        preview, reset, rects = self.gi.take_dirty()
        changed = None
        if preview:
            self.view.upload_preview(self.gi.preview)
            self._asset_dirty = True
        if reset:
            self.view.upload_full(self.gi.full)
            self._asset_dirty = True
        elif rects:
            self.view.upload_full(self.gi.full, rects)
            self._asset_dirty = True
            if not preview:
                changed = self._screen_bounds(rects)
        if self._b_active and self.gi_b.full is not None:
            changed = None
            side = self.view.side_b
            preview, reset, rects = self.gi_b.take_dirty()
            if preview or side.preview_tex is None:
                self.view.upload_preview(self.gi_b.preview, side)
            if reset or side.full_tex is None:
                self.view.upload_full(self.gi_b.full, side=side)
            elif rects:
                self.view.upload_full(self.gi_b.full, rects, side)
            self._asset_dirty = self._asset_dirty or preview or reset or bool(rects)
        return changed

    def _screen_bounds(self, rects):
        """The screen pixels the composite's upsampling of A's layer reads ``rects`` (layer
        texels, top-left x, y, w, h) for: per band of rows (a strip's tiles share their rows),
        the bounding box of its tiles scaled to the window, grown by the 2 x 2 taps of
        lib/joint_bilateral.glsl and a pixel of rounding. One box per band, not one for the
        frame: the refinement runs the centre rows first, alternating above and below, so a
        frame's tiles can lie in two strips far apart, and the box around both covered the
        rows between them (about 20 ms a frame of compositing where the bands took 5)."""
        layer = self.gi.camera
        sx, sy = self.size[0] / layer.width, self.size[1] / layer.height
        pad = int(np.ceil(max(sx, sy))) + 2
        bands: dict = {}
        for r in rects:
            bands.setdefault((r[1], r[3]), []).append(r)
        out = []
        for group in bands.values():
            x0 = min(r[0] for r in group)
            y0 = min(r[1] for r in group)
            x1 = max(r[0] + r[2] for r in group)
            y1 = max(r[1] + r[3] for r in group)
            out.append((max(int(np.floor(x0 * sx)) - pad, 0),
                        max(int(np.floor(y0 * sy)) - pad, 0),
                        min(int(np.ceil(x1 * sx)) + pad, self.size[0]),
                        min(int(np.ceil(y1 * sy)) + pad, self.size[1])))
        return out

    def _label(self, cam: Camera):
        if self.renderer_available or self.mesh is None:
            self.view.set_label(None)
            return None
        if self.view.label_size == (0, 0):
            self.view.set_label(text_image("renderer unavailable"))
        rect = screen_rect(cam, *self.mesh.bounds())
        if rect is None:
            return None
        x, y, w, h = rect
        lw, lh = self.view.label_size
        cx, cy = x + w // 2, y + h // 2
        return (cx - lw // 2, cam.height - (cy + lh // 2), lw, lh)

    def _composite(self, cam: Camera, room: bool = True, only=None) -> None:
        """Composite the picture: the room too when ``room``; the asset's pixels inside the
        boxes ``only`` ((x0, y0, x1, y1), row 0 at the top) alone when given - the new tiles of
        a refinement frame, whose whole-asset composite at 1280x800 cost llvmpipe about as much
        as the tiles themselves."""
        s = self.session.settings
        label = self._label(cam)
        rect = None if self.mesh is None else screen_rect(cam, *self.mesh.bounds())
        rects = [rect]
        if rect is not None and only is not None and not room and label is None:
            rects = []
            for box in only:
                x0, y0 = max(rect[0], box[0]), max(rect[1], box[1])
                x1, y1 = min(rect[0] + rect[2], box[2]), min(rect[1] + rect[3], box[3])
                if x1 > x0 and y1 > y0:
                    rects.append((x0, y0, x1 - x0, y1 - y0))
        # a failed relighting shows the placeholder hatch (the reason is in the messages), so
        # the asset never silently vanishes from the picture
        kw = dict(raw_room=self.cloud.false_colour(s["view.cloud"]),
                  unavailable=not self.renderer_available or self.gi_failed,
                  label_rect=label, room=room, false_colour=s["view.false_colour"])
        for rect in rects:
            if not self._b_active:
                self.view.composite(cam, s["view.exposure"], s["view.tonemap"], asset_rect=rect,
                                    **kw)
            else:       # A left of the divider, B right of it, each side its own dispatch
                w = self.size[0]
                x = split_column(s["compare.split"], w)
                self.view.composite(cam, s["view.exposure"], s["view.tonemap"], columns=(0, x),
                                    divider=x, asset_rect=rect, **kw)
                self.view.composite(cam, s["view.exposure"], s["view.tonemap"], columns=(x, w),
                                    divider=x, side=self.view.side_b, asset_rect=rect, **kw)
                self.view.draw_side_labels(label_rects(x, w, *self.view.side_label_sizes))
        self._composite_dirty = self._asset_dirty = False

    # -- the asset's shadow and bounce on the scan ---------------------------------------------
    def _differential_params(self):
        s = self.session.settings
        if (not self.renderer_available or self.mesh is None or self.cloud is None
                or not s["pbgi.differential"] or self.cloud.false_colour(s["view.cloud"])
                or self.hdri_a is not None):
            return None
        return RenderParams.from_settings(s)

    def _advance_differential(self, budget_ms: float) -> bool:
        """Gather the differential for ``budget_ms``; show it when done. True: it changed."""
        params = self._differential_params()
        if params is None:
            self._diff_steps = None
            return self._show_differential(None)
        mats = self.session.materials
        key = self.guard("the asset's shadow", self.relighter.differential_key, mats, params)
        if key is None or key == self._diff_shown_key:
            return False
        if self._diff_steps is None or self._diff_steps_key != key:
            self._diff_steps = self.relighter.differential_steps(mats, params,
                                                                 chunk=DIFFERENTIAL_CHUNK)
            self._diff_steps_key = key
            self.differential_progress = 0.0
        t0 = time.perf_counter()
        try:
            while (time.perf_counter() - t0) * 1e3 < budget_ms:
                self.differential_progress = next(self._diff_steps)
        except StopIteration as done:
            self._diff_steps = None
            self.differential_progress = 1.0
            return self._show_differential(done.value, key)
        except Exception as exc:            # a failure is a message; do not retry this key
            self._diff_steps = None
            self._diff_shown_key = key
            self.report_failure("the asset's shadow on the scan", exc)
        return False

    def differential_settled(self) -> bool:
        """Does the scan show the asset's shadow and bounce for the current settings and
        materials (or is the differential off)? (The benchmark's end of a change.)"""
        params = self._differential_params()
        if params is None:
            return True
        key = self.guard("the asset's shadow", self.relighter.differential_key,
                         self.session.materials, params)
        return key is None or key == self._diff_shown_key

    def _show_differential(self, diff, key=None) -> bool:
        """Put ``diff`` on the splats (None: the plain colours). True: the colours changed."""
        if diff is None and self._diff_shown_key is None:
            return False
        base = self.cloud.colors(self.session.settings["view.cloud"])
        if diff is None:
            self.view.set_colors(base)
        else:
            lit = np.asarray(self._lit_cloud.colors if self._lit_cloud is not None
                             else base, np.float32)[diff.index]
            factor = np.clip((lit + diff.delta) / np.maximum(lit, 1e-6), 0.0, 4.0)
            cols = np.array(base, np.float32, copy=True)
            cols[diff.index] = cols[diff.index] * factor
            if self.session.settings["view.cloud"] == "ldr":
                np.minimum(cols, 1.0, out=cols)     # an 8-bit scan stays within its range
            self.view.set_colors(cols)
        self._diff_shown_key = key if diff is not None else None
        self._room_dirty = True
        return True

    def _render_gi(self, camera: Camera, tile, pass_index: int = 0, layer=None):
        """A's tile: texels and the gather in parts (``_on_materials`` recombines them)."""
        return self._gather(self.relighter, self.session.settings, camera, tile, pass_index,
                            layer, parts=True, passes=self.gi.passes)

    def _render_gi_b(self, camera: Camera, tile, pass_index: int = 0,
                     layer=None) -> np.ndarray:
        """B's layer: B's settings (app/ui/compare.py), B's renderer; its stats stay B's."""
        return self._gather(self.relighter_b, b_settings(self.session.settings), camera, tile,
                            pass_index, layer, keep_stats=False, passes=self.gi_b.passes)

    def _gather(self, relighter, s, camera: Camera, tile, pass_index: int = 0, layer=None,
                keep_stats: bool = True, parts: bool = False, passes: int = 1):
        """One tile of a pass: ``passes``, the refinement's count, the passes whose samples
        gbuffer.pass_jitter centres on each pixel (the preview and pass 0 are among them)."""
        params = RenderParams.from_settings(s)
        if (self._interacting and params.asset_occlusion and relighter is not None
                and not relighter.asset_scene_ready(self.session.materials, params)):
            params = replace(params, asset_occlusion=False)   # built after the drag
        try:
            res = relighter.render(camera, self.session.materials, params, tile=tile,
                                   pass_index=pass_index, layer=layer,
                                   passes=max(int(passes), pass_index + 1),
                                   **({"parts": True} if parts else {}))
        except Exception as exc:
            self.gi_failed = True
            self.report_failure("relighting", exc)
            x, y, w, h = tile
            return np.zeros((h, w, 4), np.float32)
        img = np.asarray(res.image, np.float32)
        x, y, w, h = tile
        if img.shape[:2] != (h, w) and img.shape[:2] == (camera.height, camera.width):
            img = img[y:y + h, x:x + w]
        img = np.nan_to_num(img, nan=0.0, posinf=0.0, neginf=0.0)
        stats, prev = res.stats, self.gi_stats
        if not keep_stats:
            prev = stats = None
        # a tile outside the silhouette gathers nothing: keep showing the last real gather's
        # figures (same mode and micro-buffer) rather than zeros
        if stats is not None and not (
                stats.receivers == 0 and prev is not None and prev.receivers > 0
                and (prev.mode, prev.microbuffer) == (stats.mode, stats.microbuffer)):
            self.gi_stats = stats
        if not res.stats.completed:
            self.error("relighting: a render pass did not complete (GPU loop budget); the image "
                       "may be missing light", "warning")
        split = getattr(res, "parts", None) if parts else None
        if split is not None and split.shape[:2] != img.shape[:2]:
            split = split[y:y + h, x:x + w]
        return img if split is None else (img, split)

    # -- output ----------------------------------------------------------------------------------
    def finish_refinement(self) -> None:
        """Run the refinement to the end and composite (screenshots, offscreen)."""
        cam = self.camera()
        self.reset_gl_state()
        if self.renderer_available and not self.gi_failed:
            self.gi.finish()
            if self._b_active:
                self.gi_b.finish()
                self._compare_metrics()
            self._advance_differential(float("inf"))   # batch images never depend on timing
            if self._room_dirty or self._room_fast:
                self.view.draw_room(cam, self.session.settings["view.splat_scale"],
                                    self.session.settings["view.eye_dome"])
                self._room_dirty = self._room_fast = False
        self._upload_gi()
        self._composite(cam)

    def screenshot(self, path) -> list[str]:
        """PNG of the display image plus EXR of the linear composite beside it (same stem),
        written together or not at all (a full disk left the PNG without its EXR)."""
        from pathlib import Path

        from app.io.exr import write_exr
        from app.io.images import write_png
        from app.io.outputs import OutputSet
        self.finish_refinement()
        p = Path(path)
        if p.suffix.lower() != ".png":
            p = p.with_suffix(".png")
        exr = p.with_suffix(".exr")
        lin = self.view.read_linear()[..., :3]
        with OutputSet({"png": p, "exr": exr}) as outs:
            write_png(outs.temp("png"), self.view.read_display())
            write_exr(outs.temp("exr"), np.nan_to_num(lin, nan=0.0, posinf=0.0, neginf=0.0))
        return [str(p), str(exr)]

    def release(self) -> None:
        """Free the GL resources (a new session replaces this engine)."""
        for r in (self.relighter, self.relighter_b):
            if r is not None and hasattr(r, "release"):
                self.guard("releasing the renderer", r.release)
        self.view.release()

    def stats(self) -> dict:
        """The frame loop's figures (the last gather's are ``gi_stats``)."""
        ft = np.asarray(self.frame_ms[-60:]) if self.frame_ms else np.zeros(1)
        out = {"frame_ms": float(ft.mean()), "frame_ms_max": float(ft.max()),
               "refining": self.gi.refining, "progress": self.gi.progress,
               "preview_scale": self.gi.effective_scale}
        out.update({k: v for k, v in self.timings.items()})
        return out

    def capture_preview(self, position, face: int = 64) -> np.ndarray:
        """The room seen from ``position`` in six directions as a cross (uint8 sRGB, top row
        first): middle row -X, -Z, +X, +Z (turning right), +Y above and -Y below -Z. Upright
        views for the eye; the expansion's own cube faces follow OpenGL's face conventions."""
        from app.render.tonemap import tonemap_to_srgb8
        pos = np.asarray(position, float)
        views = {(1, 0): ((-1, 0, 0), (0, 1, 0)), (1, 1): ((0, 0, -1), (0, 1, 0)),
                 (1, 2): ((1, 0, 0), (0, 1, 0)), (1, 3): ((0, 0, 1), (0, 1, 0)),
                 (0, 1): ((0, 1, 0), (0, 0, 1)), (2, 1): ((0, -1, 0), (0, 0, -1))}
        out = np.zeros((3 * face, 4 * face, 3), np.uint8)
        ev = self.session.settings["view.exposure"]
        for (r, c), (d, up) in views.items():
            img = self.view.splat.render(Camera(pos, pos + np.asarray(d, float), up, 90.0,
                                                face, face))
            out[r * face:(r + 1) * face, c * face:(c + 1) * face] = tonemap_to_srgb8(
                img[..., :3], ev, self.session.settings["view.tonemap"])
        return out

def default_session() -> Session:
    """The demo scene: the LDR scan of the demo room, the default sphere, one capture camera."""
    from app.demo.room import CAPTURE_POSITIONS, default_object, default_views
    from app.settings import AssetTransform, CaptureCamera
    obj = default_object("sphere")
    s = Session(cloud="demo", photo="demo", asset="sphere",
                transform=AssetTransform(tuple(obj["translate"]), (0.0, 0.0, 0.0),
                                         float(obj["scale"])),
                capture_cameras=[CaptureCamera(f"capture {i + 1}", tuple(p))
                                 for i, p in enumerate(CAPTURE_POSITIONS)],
                camera=default_views()["whole"])
    s.settings.take_changes()
    return s


__all__ = ["ViewerEngine", "default_session", "make_relighter"]
