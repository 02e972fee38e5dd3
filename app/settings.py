"""The viewer's plain settings model and its session file; no UI and no GL imports here.

The values are those of the parameter table (app/params.py, every parameter declared once): the
UI derives its widgets from it (app/ui/widgets.py) and the session JSON stores the values under
the same keys. A value out of range is clamped here (a slider or an old session never fails);
records and the command line reject it instead (``Param.check``).

Editing follows the Mitsuba pattern: whoever edits calls ``set``; the model records *which keys
changed*; the engine reads ``take_changes()`` once per frame and hands the set to its
``ChangeHandlers`` (napari's one-event-per-field model, dispatched once per frame): a BRDF slider
only re-gathers the asset, an exposure change only re-tone-maps, a new cloud rebuilds the
hierarchy. The quality preset (``pbgi.quality``) is kept consistent here: choosing one sets its
values (each recorded as changed), and changing one of them by hand makes it "custom", so the
UI only ever writes plain values. Non-settings parts of the session (files, capture cameras, asset transform,
materials, the view camera) report their changes through the same change set under the keys in
``DOCUMENT_KEYS``.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable

import numpy as np

from app.camera import Camera, camera_from_dict
from app.errors import ScanlightError
from app.io.limits import MAX_COORD, OBJECT_SCALE
from app.io.schema import Fields, show
from app.material import Material, material_from_dict
from app.params import BY_KEY, CUSTOM_QUALITY, PARAMS, QUALITY_KEYS, QUALITY_PRESETS, REDO

QUALITY = "pbgi.quality"

SESSION_VERSION = 1

# Change keys of the session parts that are not table settings.
DOCUMENT_KEYS = ("files.cloud", "files.hdr_cloud", "files.asset", "files.photo", "files.hdri",
                 "asset.transform", "materials", "capture_cameras", "camera")


class Settings:
    """Current values of the parameter table (``app.params.PARAMS``) plus the set of keys
    changed since the engine last looked."""

    def __init__(self, values: dict | None = None, source=None):
        self._values = {p.key: p.default for p in PARAMS}
        self._changed: set[str] = set()
        if values:
            self.update(values, source)

    def __getitem__(self, key: str):
        return self._values[key]

    def get(self, key: str):
        return self._values[key]

    def set(self, key: str, value, source=None) -> bool:
        """Validate and store; True (and the key recorded as changed) when the value differs."""
        spec = BY_KEY.get(key)
        if spec is None:
            raise ScanlightError(source, f"unknown setting {key!r}")
        v = spec.clamp(value, source)
        if self._values[key] == v:
            return False
        self._store(key, v)
        if key == QUALITY and v != CUSTOM_QUALITY:
            for k, pv in QUALITY_PRESETS[v].items():
                if self._values[k] != pv:
                    self._store(k, pv)
        elif key in QUALITY_KEYS:
            q = self._values[QUALITY]
            if q != CUSTOM_QUALITY and QUALITY_PRESETS[q][key] != v:
                self._store(QUALITY, CUSTOM_QUALITY)
        return True

    def _store(self, key: str, value) -> None:
        self._values[key] = value
        self._changed.add(key)

    def update(self, values: dict, source=None) -> None:
        for key, val in values.items():
            self.set(key, val, source)

    def mark(self, key: str) -> None:
        """Record a change of a non-table part of the session (see DOCUMENT_KEYS)."""
        self._changed.add(key)

    def take_changes(self) -> frozenset[str]:
        """The keys changed since the last call (the engine calls this once per frame)."""
        out, self._changed = frozenset(self._changed), set()
        return out

    def pending(self) -> frozenset[str]:
        return frozenset(self._changed)

    def reset(self, key: str) -> None:
        self.set(key, BY_KEY[key].default)

    def to_dict(self) -> dict:
        return dict(self._values)


CHANGE_KEYS = tuple(p.key for p in PARAMS) + DOCUMENT_KEYS


class ChangeHandlers:
    """What a change set sets off: handlers connected per key, per key group or per
    ``Param.redo``, called by ``dispatch`` once per frame.

    Each handler runs at most once per dispatch, with the changed keys it was connected to (a
    frozenset), and handlers run in the order they were connected: that order is the order of
    the work (a new cloud is loaded before its colours are chosen, an asset before it is
    placed). Keys nobody connected to change nothing. Connecting an unknown key, group or redo
    kind is an error, so a renamed setting cannot silently lose its handler.
    """

    def __init__(self):
        self._handlers: list[tuple[frozenset[str], Callable[[frozenset[str]], None]]] = []

    def connect(self, keys: str | Iterable[str], handler: Callable[[frozenset[str]], None]):
        """``handler(changed)`` runs when any of ``keys`` (one key or several) changed."""
        keys = frozenset((keys,) if isinstance(keys, str) else keys)
        unknown = keys - set(CHANGE_KEYS)
        if unknown or not keys:
            raise ValueError(f"no such change key: {', '.join(sorted(unknown)) or '(none)'}")
        self._handlers.append((keys, handler))
        return handler

    def connect_group(self, group: str, handler: Callable[[frozenset[str]], None]):
        """``handler(changed)`` runs when any key ``group.*`` changed (table or document key)."""
        keys = [k for k in CHANGE_KEYS if k.split(".", 1)[0] == group]
        if not keys:
            raise ValueError(f"no change keys in group {group!r}")
        return self.connect(keys, handler)

    def connect_redo(self, redo: str, handler: Callable[[frozenset[str]], None]):
        """``handler(changed)`` runs when a table parameter whose ``Param.redo`` is ``redo``
        changed: a new parameter reaches its handler through the table alone."""
        if redo not in REDO:
            raise ValueError(f"no such redo kind {redo!r} (one of {', '.join(REDO)})")
        keys = [p.key for p in PARAMS if p.redo == redo]
        return self.connect(keys, handler) if keys else handler

    def __iter__(self):
        """(keys, handler) pairs in dispatch order."""
        return iter(self._handlers)

    def handlers_for(self, key: str) -> list:
        """The handlers a change of ``key`` runs, in order."""
        return [h for keys, h in self._handlers if key in keys]

    def dispatch(self, changes: Iterable[str]) -> None:
        changes = frozenset(changes)
        for keys, handler in self._handlers:
            hit = keys & changes
            if hit:
                handler(hit)


# ---------------------------------------------------------------------------------------------
# The session: everything the user set up, saved as JSON.

@dataclass
class CaptureCamera:
    """A capture position for HDR expansion (its cube map is axis aligned, paper Section 4.1)."""

    name: str
    position: tuple[float, float, float]

    def to_dict(self) -> dict:
        return {"name": self.name, "position": [float(v) for v in self.position]}


@dataclass
class AssetTransform:
    """The object JSON's placement (see README): rotate (degrees, x then y then z), scale, move."""

    translate: tuple[float, float, float] = (0.0, 0.6, 0.0)
    rotate_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    scale: float = 0.8

    def to_dict(self) -> dict:
        return {"translate": [float(v) for v in self.translate],
                "rotate_deg": [float(v) for v in self.rotate_deg], "scale": float(self.scale)}

    def matrix(self) -> np.ndarray:
        """4x4 object -> world: translate @ scale @ R, R = Rz @ Ry @ Rx (app.io.formats)."""
        from app.io.formats import rotation_xyz
        m = np.eye(4)
        m[:3, :3] = rotation_xyz(self.rotate_deg) * float(self.scale)
        m[:3, 3] = self.translate
        return m

    @staticmethod
    def from_matrix(m: np.ndarray) -> "AssetTransform":
        """Inverse of ``matrix`` for a uniform scale (what the gizmo hands back)."""
        m = np.asarray(m, dtype=np.float64)
        lin = m[:3, :3]
        scale = float(np.cbrt(abs(np.linalg.det(lin)))) or 1e-6
        r = lin / scale
        ry = np.arcsin(np.clip(-r[2, 0], -1.0, 1.0))
        if abs(np.cos(ry)) > 1e-6:
            rx, rz = np.arctan2(r[2, 1], r[2, 2]), np.arctan2(r[1, 0], r[0, 0])
        else:  # gimbal lock: put everything into x
            rx, rz = np.arctan2(-r[1, 2], r[1, 1]), 0.0
        return AssetTransform(tuple(float(v) for v in m[:3, 3]),
                              tuple(float(v) for v in np.degrees([rx, ry, rz])), scale)


@dataclass
class Session:
    """Files, capture cameras, asset transform, materials, view camera and settings.

    ``cloud``/``photo`` are paths or "demo" (the built-in scene); ``asset`` is a path or one of
    the built-in objects ("sphere", "knot"); ``hdr_cloud`` is the expansion result, if any;
    ``hdri`` an equirectangular EXR that lights the asset when ``light.source`` is "hdri".
    ``materials`` None means "the asset's own". Paths are stored relative to the session file.
    """

    cloud: str = "demo"
    photo: str | None = "demo"
    hdr_cloud: str | None = None
    asset: str = "sphere"
    hdri: str | None = None
    transform: AssetTransform = field(default_factory=AssetTransform)
    capture_cameras: list[CaptureCamera] = field(default_factory=list)
    materials: list[Material] | None = None
    camera: Camera | None = None
    settings: Settings = field(default_factory=Settings)
    path: Path | None = None

    # -- edits that report their change key ------------------------------------------------------
    def set_file(self, which: str, value: str | None) -> None:
        setattr(self, which, value)
        self.settings.mark(f"files.{which}")

    def set_transform(self, transform: AssetTransform) -> None:
        """The gizmo, the panel or a script moves the asset; a NaN or a value beyond the limits
        (which the next frame failed on, as an internal error) is one line here."""
        try:
            values = np.asarray([*transform.translate, *transform.rotate_deg, transform.scale],
                                dtype=np.float64)
        except (TypeError, ValueError):
            values = np.array([np.nan])
        if values.shape != (7,) or not np.isfinite(values).all():
            raise ScanlightError(self.path, "asset transform must be 3 + 3 + 1 finite numbers, "
                                            f"got {transform}")
        if (np.abs(values[:3]).max() > MAX_COORD
                or not OBJECT_SCALE[0] <= values[6] <= OBJECT_SCALE[1]):
            raise ScanlightError(self.path, f"asset transform beyond the limits (translate within "
                                            f"{MAX_COORD:g} m, scale {OBJECT_SCALE[0]:g} .. "
                                            f"{OBJECT_SCALE[1]:g}), got {transform.to_dict()}")
        if transform != self.transform:
            self.transform = transform
            self.settings.mark("asset.transform")

    def set_material(self, index: int, values: dict) -> None:
        mats = self.materials or []
        mats[index] = mats[index].updated(values)
        self.settings.mark("materials")

    def set_materials(self, materials: list[Material] | None) -> None:
        self.materials = materials
        self.settings.mark("materials")

    def set_capture_cameras(self, cams: list[CaptureCamera]) -> None:
        self.capture_cameras = cams
        self.settings.mark("capture_cameras")

    @property
    def mode(self) -> str:
        return self.settings["pbgi.mode"]

    # -- JSON ------------------------------------------------------------------------------------
    def to_dict(self, base: Path | None = None) -> dict:
        values = self.settings.to_dict()
        mode = values.pop("pbgi.mode")
        return {
            "scanlight_session": SESSION_VERSION,
            "files": {"cloud": _rel(self.cloud, base), "photo": _rel(self.photo, base),
                      "hdr_cloud": _rel(self.hdr_cloud, base), "asset": _rel(self.asset, base),
                      "hdri": _rel(self.hdri, base)},
            "capture_cameras": [c.to_dict() for c in self.capture_cameras],
            "asset_transform": self.transform.to_dict(),
            "materials": None if self.materials is None else [
                dict(m.to_dict(), name=m.name) for m in self.materials],
            "mode": mode,
            "camera": None if self.camera is None else self.camera.to_dict(),
            "settings": values,
        }

    def save(self, path, relative: bool = True) -> Path:
        """Write atomically (paths relative to the file unless ``relative`` is False) and
        remember ``path`` as this session's file."""
        from app.io.files import atomic_output
        p = Path(path)
        text = json.dumps(self.to_dict(p.resolve().parent if relative else None), indent=1)
        with atomic_output(p) as tmp:
            tmp.write_text(text)
        self.path = p
        return p


BUILTIN_ASSETS = ("sphere", "knot")


def _rel(value: str | None, base: Path | None) -> str | None:
    if value is None or value == "demo" or value in BUILTIN_ASSETS:
        return value
    if base is None:
        return str(Path(value).resolve())
    try:
        return os.path.relpath(Path(value).resolve(), base)
    except ValueError:  # another drive (Windows)
        return str(value)


def _abs(files: Fields, key: str, base: Path, default=None) -> str | None:
    value = files.path(key, default) if files.d.get(key) is not None else default
    if value is None or value == "demo" or value in BUILTIN_ASSETS:
        return value
    p = Path(value)
    return str(p if p.is_absolute() else (base / p))


def session_from_dict(d: dict, base: Path, source=None) -> Session:
    """A session from its JSON object, every part typed (app.io.schema): paths are strings,
    vectors 3 numbers within MAX_COORD, names strings; settings go through their Param (typed,
    then clamped as the viewer's sliders clamp)."""
    if not isinstance(d, dict) or "scanlight_session" not in d:
        raise ScanlightError(source, "not a Scanlight session (no 'scanlight_session' key)")
    version = d["scanlight_session"]
    if isinstance(version, bool) or version != SESSION_VERSION:     # true == 1 in Python
        raise ScanlightError(source, f"session version {show(version)} is not "
                                     f"supported (this build reads version {SESSION_VERSION})")
    top = Fields(d, "session", source)
    files = Fields(top.optional("files", dict, {}), "session 'files'", source,
                   ("cloud", "photo", "hdr_cloud", "asset", "hdri"))
    s = Session(cloud=_abs(files, "cloud", base, "demo"), photo=_abs(files, "photo", base),
                hdr_cloud=_abs(files, "hdr_cloud", base),
                asset=_abs(files, "asset", base, "sphere"), hdri=_abs(files, "hdri", base))
    for i, c in enumerate(top.optional("capture_cameras", list, [])):
        cam = Fields(c, f"session capture camera {i}", source, ("name", "position"))
        s.capture_cameras.append(CaptureCamera(cam.string("name", f"capture {i + 1}"),
                                               cam.vec3("position")))
    t = Fields(top.optional("asset_transform", dict, {}), "session 'asset_transform'", source,
               ("translate", "rotate_deg", "scale"))
    s.transform = AssetTransform(t.vec3("translate", (0.0, 0.6, 0.0)),
                                 t.vec3("rotate_deg", (0.0, 0.0, 0.0), limit=None),
                                 t.number("scale", 0.8, *OBJECT_SCALE))
    mats = top.optional("materials", list)
    if mats is not None:
        s.materials = [material_from_dict(m, source) for m in mats]
    cam = top.optional("camera", dict)
    if cam is not None:
        s.camera = camera_from_dict(cam, source, "session 'camera'")
    s.settings = Settings(top.optional("settings", dict, {}), source)
    if "mode" in d:
        s.settings.set("pbgi.mode", d["mode"], source)
    s.settings.take_changes()  # a fresh session has nothing "changed"
    return s


def load_session(path) -> Session:
    from app.io.files import read_json
    p = Path(path)
    s = session_from_dict(read_json(p, "session"), p.resolve().parent, str(p))
    s.path = p
    return s


# ---------------------------------------------------------------------------------------------
# "Last session", kept in the user's config folder.

def config_dir() -> Path:
    root = os.environ.get("SCANLIGHT_CONFIG") or os.path.join(
        os.environ.get("XDG_CONFIG_HOME", os.path.expanduser("~/.config")), "scanlight")
    return Path(root)


def last_session_path() -> Path:
    return config_dir() / "last_session.json"


def save_last_session(session: Session) -> Path:
    """A copy of the session with absolute paths, for ``scanlight view --last``. A config
    folder that cannot be written is a ScanlightError naming the file, never a bare OSError
    (which the viewer would report as a bug)."""
    p = last_session_path()
    keep = session.path
    try:
        session.save(p, relative=False)
    except OSError as exc:
        raise ScanlightError(p, f"could not be written: {exc.strerror or exc}") from None
    finally:
        session.path = keep
    return p


def load_last_session() -> Session:
    p = last_session_path()
    if not p.is_file():
        raise ScanlightError(p, "no last session yet (one is saved when the viewer closes)")
    return load_session(p)
