"""One HDR expansion as an app.jobs job: the request and its work function.

``ExpandRequest`` is the one request type: ``scanlight expand`` builds it from its options, the
viewer from its settings (``ExpandRequest.from_settings``), the tests directly. It is immutable
and picklable, so the same request runs in a thread or in a separate process (app.jobs).
``run_expand_request`` is the work: it loads what the request names by path, runs the pipeline
(app.hdr.pipeline, everything in memory) and writes the outputs only on success, atomically, so
an interrupted or failed run never leaves a half-written cloud or report.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from app.camera import Camera, camera_from_dict
from app.errors import ScanlightError
from app.hdr.pipeline import ExpandParams, Expansion, run_expansion
from app.io.files import read_json, require_file, write_json
from app.io.limits import MAX_CAPTURE_PIXELS
from app.io.schema import Fields, vec3_value


def load_cameras(path) -> list:
    """Capture cameras from JSON: a list of ``{"position": [x, y, z]}`` (an axis-aligned cube
    map there) or full camera objects (with ``look_at``: one rendering with that camera);
    ``{"cameras": [...]}`` and a single object are accepted too. Every field is typed
    (app.io.schema); positions lie within MAX_COORD, camera images within MAX_CAMERA_PIXELS."""
    p = require_file(path, "cameras", (".json",))
    data = read_json(p, "cameras")
    if isinstance(data, dict):
        data = data.get("cameras", [data])
    if not isinstance(data, list) or not data:
        raise ScanlightError(p, "expected a non-empty list of cameras")
    out = []
    for i, d in enumerate(data):
        what = f"capture camera {i}"
        if isinstance(d, (list, tuple)):
            out.append(np.asarray(vec3_value(d, what, p)))
        elif isinstance(d, dict) and "look_at" in d:
            out.append(camera_from_dict(d, p, what))
        else:
            f = Fields(d, what, p, ("position", "name"))
            f.string("name", "")
            out.append(np.asarray(f.vec3("position")))
    return out


def check_capture_size(cams, face_size: int, source=None) -> None:
    """All capture images of one expansion together (a cube map is six faces of ``face_size``
    squared; a camera its own image) within MAX_CAPTURE_PIXELS, before anything is rendered."""
    total = sum(c.width * c.height if isinstance(c, Camera) else 6 * face_size ** 2
                for c in (cams or ()))
    if total > MAX_CAPTURE_PIXELS:
        raise ScanlightError(source, f"{len(cams)} capture camera(s) at face size {face_size} "
                                     f"make {total:,} capture pixels, more than the limit of "
                                     f"{MAX_CAPTURE_PIXELS:,} (fewer cameras or a smaller "
                                     "--face-size)")


@dataclass(frozen=True)
class ExpandRequest:
    """Inputs are in-memory objects or file paths (paths are cheaper to send to a process).

    cloud: PointCloud or path; photo: (H, W, 3) linear array, an image path, or an image already
    read from its file (app.io.exr.LinearImage, see ``with_photo_read``); cameras: a sequence
    of positions / Camera objects or a cameras JSON path; params: the ExpandParams (the method
    included). out_path / report_path: where the work writes the results (atomically); with
    ``return_cloud=False`` the result carries only the report (no large pickle back).
    """

    cloud: object
    photo: object
    cameras: object
    params: ExpandParams = field(default_factory=ExpandParams)
    out_path: str | None = None
    report_path: str | None = None
    return_cloud: bool = True
    output_name: str | None = None   # the cloud's final name, for the report (out_path may be
    #                                  a temporary the command renames when everything is done)

    def __post_init__(self):
        if not isinstance(self.params, ExpandParams):
            raise TypeError(f"ExpandRequest.params must be an ExpandParams, not "
                            f"{type(self.params).__name__} (ExpandParams.from_dict builds one)")
        if isinstance(self.cameras, list):
            object.__setattr__(self, "cameras", tuple(self.cameras))

    @property
    def method(self) -> str:
        return self.params.method

    def with_photo_read(self) -> "ExpandRequest":
        """This request with its photo (when given as a path) read here, on the caller's thread,
        into a LinearImage that keeps the path as its name.

        The command line calls it on its main thread before a thread worker starts. OpenEXR
        prints its own messages about a damaged file ("(EXR_ERR_BAD_CHUNK_LEADER) ..." to file
        descriptor 2, "Warning: Exception raised ..." to stdout), and app.io.exr can fold them
        into the one error line only on the main thread: a redirection of descriptor 2 is
        process-wide, so on a worker it would also swallow the main thread's progress lines.
        A worker process reads the photo on its own main thread and needs none of this (and
        would only pay for pickling the pixels)."""
        if not isinstance(self.photo, (str, Path)):
            return self
        from app.io.exr import read_image
        return replace(self, photo=replace(read_image(self.photo), source=str(self.photo)))

    @staticmethod
    def from_settings(cloud, photo, positions, settings, **kw) -> "ExpandRequest":
        """The viewer's request: its settings (anything indexable by the ``hdr.*`` keys) give
        the parameters; capture ``positions`` are copied, so later edits do not reach the job."""
        return ExpandRequest(cloud, photo, tuple(tuple(map(float, p)) for p in positions),
                             ExpandParams.from_settings(settings), **kw)


def run_expand_request(req: ExpandRequest, progress=None, cancel=None) -> Expansion:
    """The expansion job's work: load what is given as paths, expand, write the outputs.

    Returns app.hdr.result.Expansion (its ``cloud`` None when ``return_cloud`` is False).
    """
    from app.io.exr import LinearImage, read_image
    from app.io.pointcloud import load_cloud, save_cloud

    names = {}
    cloud = req.cloud
    if isinstance(cloud, (str, Path)):
        names["cloud"] = str(cloud)
        cloud = load_cloud(cloud)
    photo = req.photo
    photo_warnings = []
    if isinstance(photo, (str, Path)):
        photo = replace(read_image(photo), source=str(photo))   # named as the user named it
    if isinstance(photo, LinearImage):   # read from a file, here or by with_photo_read
        img = photo
        if img.source:
            names["photo"] = str(img.source)
        if not img.hdr:
            photo_warnings.append(f"{img.source or 'photo'}: an 8-bit image, not HDR: the "
                                  "expansion cannot recover radiance above its clipping point")
        photo = img.rgb
    cams = req.cameras
    if isinstance(cams, (str, Path)):
        names["cameras"] = str(cams)
        cams = load_cameras(cams)
    check_capture_size(cams, req.params.face_size, names.get("cameras"))
    res = run_expansion(cloud, photo, cams, params=req.params, progress=progress, cancel=cancel,
                        names=names)
    res.report["warnings"][:0] = photo_warnings
    res.report["inputs"] = {k: names.get(k) for k in ("cloud", "photo", "cameras")}
    if req.out_path:
        save_cloud(res.cloud, req.out_path)
        res.report["output"] = str(req.output_name or req.out_path)
    if req.report_path:
        write_json(req.report_path, res.report)   # atomic; NaN is written as null
    if not req.return_cloud:
        res = Expansion(None, res.report, res.labels, [])
    return res


__all__ = ["ExpandRequest", "check_capture_size", "load_cameras", "run_expand_request"]
