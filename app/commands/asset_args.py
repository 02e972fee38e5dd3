"""The asset options shared by the commands that light one (``render``, the turntable):
``--object`` names an object JSON (scripted use: placement in the file) or a mesh file
(.glb/.gltf/.obj) opened directly, placed standing on the scan's floor (app/io/placement.py).

    --object model.glb [--fit S] [--translate X,Y,Z] [--rotate X,Y,Z]
    --object obj.json

A direct mesh keeps the file's own units (glTF is metres; OBJ has none: read as metres) unless
``--fit S`` scales its largest extent to S metres. ``--rotate`` (degrees, the object JSON's
``rotate_deg`` convention: R = Rz @ Ry @ Rx about world axes) turns it before it is stood on the
floor, so a turned model still stands on it; ``--translate`` (metres) then moves it from that
spot (app/io/placement.py has the order and how the floor is found). A vector starting with a
minus needs the ``=`` form: ``--translate=-1,0,0``. The JSON carries its own placement, so these
three flags with a JSON are a usage error (exit 2): one source of truth for where it stands.
"""

from __future__ import annotations

import logging
from pathlib import Path

from app.errors import UsageError
from app.io.limits import MAX_COORD, OBJECT_SCALE

log = logging.getLogger(__name__)


def _vec3(flag: str, text: str | None):
    if text is None:
        return None
    parts = text.replace(" ", "").split(",")
    try:
        v = tuple(float(p) for p in parts)
    except ValueError:
        v = ()
    if len(v) != 3 or not all(abs(x) <= MAX_COORD for x in v):   # also rejects nan/inf
        raise UsageError(None, f"{flag} expects three finite numbers X,Y,Z, got {text!r}")
    return v


def add_object_arguments(parser) -> None:
    parser.add_argument("--object", required=True, metavar="O.json|MESH",
                        help="the asset: a mesh file (.glb/.gltf/.obj; placed on the scan's "
                             "floor below the room's centre, in the file's units: glTF metres, "
                             "OBJ read as metres) or an object JSON {\"mesh\": ..., "
                             "\"translate\": ..., \"scale\": ..., \"rotate_deg\": ...}, or the "
                             "built-ins sphere / knot (placed like a mesh, 1 m)")
    add_placement_arguments(parser)


def add_placement_arguments(parser) -> None:
    """--fit, --translate, --rotate: where a mesh opened directly stands (``scanlight view``
    takes them too, for its ASSET)."""
    parser.add_argument("--fit", type=float, metavar="S",
                        help="mesh only: scale its largest extent to S metres (default: the "
                             "file's own units)")
    parser.add_argument("--translate", metavar="X,Y,Z",
                        help="mesh only: move it by this many metres from its floor spot "
                             "(--translate=-1,0,0 for a leading minus)")
    parser.add_argument("--rotate", metavar="X,Y,Z",
                        help="mesh only: rotate by XYZ Euler degrees (R = Rz Ry Rx, world axes, "
                             "as the JSON's rotate_deg) before standing it on the floor")


def placement_options(args) -> tuple[float | None, tuple | None, tuple | None]:
    """(fit, translate, rotate) from the flags, checked (usage errors exit 2)."""
    fit = getattr(args, "fit", None)
    if fit is not None and not OBJECT_SCALE[0] <= fit <= OBJECT_SCALE[1]:   # also nan
        raise UsageError(None, f"--fit must be a size in metres from {OBJECT_SCALE[0]:g} to "
                               f"{OBJECT_SCALE[1]:g}, got {fit!r}")
    return (fit, _vec3("--translate", getattr(args, "translate", None)),
            _vec3("--rotate", getattr(args, "rotate", None)))


def check_object_args(args) -> None:
    """The checks that need no cloud, for a command to run before loading one: the flags
    (exit 2) and that ``--object`` names a readable file of a known kind (exit 3)."""
    from app.io.files import require_file
    from app.io.formats import BUILTIN_MESHES, load_object
    from app.io.mesh import MESH_EXTENSIONS
    fit, translate, rotate = placement_options(args)
    name = str(args.object)
    if Path(name).suffix.lower() == ".json":
        given = [f for f, v in (("--fit", fit), ("--translate", translate),
                                ("--rotate", rotate)) if v is not None]
        if given:
            verb = "applies" if len(given) == 1 else "apply"
            raise UsageError(None, f"{', '.join(given)} only {verb} to a mesh given directly; "
                                   f"the object JSON {name} carries its own placement "
                                   "(translate, scale, rotate_deg)")
    if name not in BUILTIN_MESHES:
        require_file(name, "object", (".json",) + MESH_EXTENSIONS)
    if Path(name).suffix.lower() == ".json":
        load_object(name)            # a bad JSON fails before a large cloud loads


def load_placed_asset(args, cloud):
    """(mesh, description): the asset placed in the room for Relighter.set_asset, and a dict for
    the stats JSON (source, how it was placed, the floor height, the scale)."""
    from app.io.formats import BUILTIN_MESHES, load_object, placed_mesh
    check_object_args(args)
    fit, translate, rotate = placement_options(args)
    name = str(args.object)
    if Path(name).suffix.lower() == ".json":
        spec = load_object(name)
        mesh = placed_mesh(spec)
        lo, hi = mesh.bounds()
        return mesh, {"source": name, "placement": "object JSON", "mesh": spec.mesh,
                      "scale": spec.scale, "translate": list(spec.translate),
                      "rotate_deg": list(spec.rotate_deg),
                      "bounds": [lo.tolist(), hi.tolist()]}
    from app.io.placement import load_floor_spec, room_of
    if name not in BUILTIN_MESHES:
        name = str(Path(name).resolve())
    room = room_of(cloud)
    if not room.floor_found:
        log.warning("%s: no floor found in the scan (%s): the asset stands at y = %g",
                    getattr(cloud, "source", None) or "cloud", room.floor_from, room.floor_y)
    spec, mesh, extent = load_floor_spec(name, room, fit, translate, rotate)
    lo, hi = mesh.bounds()
    return mesh, {"source": str(args.object), "placement": "on the scan's floor",
                  **room.to_dict(), "fit": fit, "file_extent": extent,
                  "scale": spec.scale / extent,        # metres per unit of the file
                  "translate": list(translate or (0.0, 0.0, 0.0)),
                  "rotate_deg": list(spec.rotate_deg), "bounds": [lo.tolist(), hi.tolist()]}


__all__ = ["add_object_arguments", "add_placement_arguments", "check_object_args",
           "load_placed_asset", "placement_options"]
