"""Opening a file by what it is (file dialogs and drag-and-drop share this): a point cloud, an
asset, an HDR photo, a session, or an object JSON (asset + placement)."""

from __future__ import annotations

from pathlib import Path

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


def open_into(session: Session, path) -> str:
    """Point the session at ``path``; returns its kind. Sessions are not applied here (the
    caller replaces the whole session); everything else becomes a change the engine picks up."""
    kind = file_kind(path)
    p = str(Path(path).resolve())
    if kind == "cloud":
        session.hdr_cloud = None
        session.set_file("cloud", p)
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
