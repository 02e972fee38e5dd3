"""Opening a file by what it is (file dialogs, drag-and-drop and ``scanlight view CLOUD ASSET``
share this): a point cloud, an asset, an HDR photo, a session, or an object JSON (asset +
placement).

A mesh opened directly (.glb/.gltf/.obj) stands on the scan's floor below the room's centre in
its own units, as ``render --object model.glb`` places it (app/io/placement.py); the viewer
passes its scan's ``Room``. The mesh is read once here for its bounds and again, normalised, by
the engine (app/ui/scene.py: Asset). An object JSON keeps the placement it states."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from app.errors import ScanlightError
from app.io.files import read_json
from app.settings import AssetTransform, Session


def file_kind(path) -> str:
    from app.io.exr import IMAGE_EXTENSIONS
    from app.io.mesh import MESH_EXTENSIONS
    from app.io.pointcloud import CLOUD_EXTENSIONS
    ext = Path(path).suffix.lower()
    if ext in CLOUD_EXTENSIONS:
        return "cloud"
    if ext in MESH_EXTENSIONS:
        return "asset"
    if ext in IMAGE_EXTENSIONS:
        return "photo"
    if ext == ".json":
        d = read_json(path, "JSON")
        return "session" if isinstance(d, dict) and "scanlight_session" in d else "object"
    raise ScanlightError(path, f"don't know how to open {ext or 'files without an extension'} "
                               f"(clouds: {', '.join(CLOUD_EXTENSIONS)}; assets: "
                               f"{', '.join(MESH_EXTENSIONS)}; photos: "
                               f"{', '.join(IMAGE_EXTENSIONS)}; sessions and objects: .json)")


def open_into(session: Session, path, room=None) -> str:
    """Point the session at ``path``; returns its kind. Sessions are not applied here (the
    caller replaces the whole session); everything else becomes a change the engine picks up.
    With ``room`` (app.io.placement.Room, or a function returning it, called only for a mesh) a
    mesh stands on its floor (``stand_asset``); without one it takes the session's transform."""
    kind = file_kind(path)
    p = str(Path(path).resolve())
    if kind == "cloud":
        session.hdr_cloud = None
        session.set_file("cloud", p)
    elif kind == "asset" and room is not None:
        stand_asset(session, p, room() if callable(room) else room)
    elif kind == "asset":
        session.materials = None
        session.set_file("asset", p)
    elif kind == "photo":
        session.set_file("photo", p)
    elif kind == "object":
        from app.io.formats import load_object
        spec = load_object(path)
        session.materials = None
        session.set_file("asset", spec.mesh)
        session.set_transform(AssetTransform(spec.translate, spec.rotate_deg, spec.scale))
    return kind


def stand_asset(session: Session, name: str, room, fit=None, translate=None, rotate=None):
    """Make the mesh file (absolute path) or built-in ``name`` the session's asset, standing on
    ``room``'s floor below its centre (app/io/placement.py: size, rotation, floor, translate);
    returns the ObjectSpec. A bad mesh raises its ScanlightError before the session changes."""
    from app.io.placement import floor_spec, read_unplaced
    quiet = _NoWarnings()              # the engine's own read of the mesh reports them, once
    mesh_log = logging.getLogger("app.io.mesh")
    mesh_log.addFilter(quiet)
    try:
        raw = read_unplaced(name)
    finally:
        mesh_log.removeFilter(quiet)
    spec = floor_spec(name, raw, room, fit, translate, rotate, source=name)
    session.materials = None
    session.set_file("asset", name)
    session.set_transform(AssetTransform(spec.translate, spec.rotate_deg, spec.scale))
    return spec


class _NoWarnings(logging.Filter):
    def filter(self, record) -> bool:
        return record.levelno > logging.WARNING


def startup_files(paths) -> tuple[str | None, str | None]:
    """(cloud, asset) of ``scanlight view [CLOUD] [ASSET]``, absolute, in either order: each path
    by its kind (a cloud; a mesh or an object JSON), checked to be a readable file (exit 3)."""
    from app.io.files import require_file
    cloud = asset = None
    for path in paths or ():
        kind = file_kind(require_file(path, "input"))
        if kind == "cloud" and cloud is None:
            cloud = str(Path(path).resolve())
        elif kind in ("asset", "object") and asset is None:
            asset = str(Path(path).resolve())
        else:
            raise ScanlightError(path, f"scanlight view opens one point cloud and one asset "
                                       f"(mesh or object JSON); this is {_A.get(kind, kind)}")
    return cloud, asset


def open_at_start(engine, asset: str | None, fit=None, translate=None, rotate=None) -> None:
    """``scanlight view [CLOUD] [ASSET]`` once the engine has loaded the session's cloud: the
    asset (or, with only a cloud, the session's default sphere at its default size) stands on
    that scan's floor, an object JSON where it says; then the view frames the asset."""
    from app.errors import UsageError
    session = engine.session
    if asset is not None and file_kind(asset) == "object":
        if fit is not None or translate is not None or rotate is not None:
            raise UsageError(None, f"--fit, --translate and --rotate apply to a mesh given "
                                   f"directly; the object JSON {asset} carries its own placement")
        open_into(session, asset)
    else:
        room = engine.room()
        if not room.floor_found:
            engine.error(f"no floor found in the scan ({room.floor_from}): the asset stands at "
                         f"y = {room.floor_y:g}", "warning")
        if asset is None and fit is None:
            fit = session.transform.scale        # the default sphere keeps its size
        stand_asset(session, asset or session.asset, room, fit, translate, rotate)
    engine.apply_changes()
    engine.frame_asset()
    _keep_eye_inside(engine)


def _keep_eye_inside(engine, margin: float = 0.1) -> None:
    """Framing a large asset backs the eye off until it fits, often through a wall of the scan,
    whose back then fills the view: come closer (same direction) until the eye is inside the
    room's robust box (2nd..98th percentile of each axis, less ``margin`` metres)."""
    from app.io.placement import CENTRE_PERCENTILES
    p = engine.cloud.ldr.positions
    p = p[np.isfinite(p).all(axis=1)]
    if len(p) < 16:
        return
    lo, hi = np.percentile(p, CENTRE_PERCENTILES, axis=0)
    lo, hi = lo + margin, hi - margin
    nav = engine.nav
    for _ in range(40):
        eye = nav.position
        if np.all((eye >= lo) & (eye <= hi)):
            return
        nav.distance *= 0.9


_A = {"cloud": "a second cloud", "asset": "a second asset", "object": "a second asset",
      "photo": "a photo (open it from the viewer)", "session": "a session (use --session)"}


def open_hdri(session: Session, path) -> None:
    """Light the asset with the HDRI ``path`` (the Light panel's open button; a dropped .exr
    stays the expansion's HDR photo). The engine loads it and reports a bad file."""
    session.set_file("hdri", str(Path(path).resolve()))
    session.settings.set("light.source", "hdri")
