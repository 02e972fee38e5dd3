"""``scanlight turntable``: an image sequence orbiting the relit asset (or along a camera path),
and an MP4 of it.

    scanlight turntable --cloud C.ply --object O.json|MESH --count N --out DIR
                        [--range A-B] [--path cameras.json] [--size WxH] [--elevation DEG]
                        [--distance M] [--fov DEG] [--background] [--material M.json]
                        [--fps 24] [--no-video] [--force] [--quality NAME] [render flags]

Frame k (0-based) is ``DIR/frame_%04d.exr`` (linear RGBA, premultiplied, as ``render --out``)
and ``DIR/frame_%04d.png`` (``--exposure``, then ``--tonemap`` and sRGB, alpha kept),
written together and atomically (app/io/outputs.py: temporaries, then renamed): a failure or
Ctrl-C leaves only complete frames. The cloud and the asset are loaded once and one Relighter
renders every frame; only the camera changes (and with ``--background`` the asset's shadow on
the scan is gathered once: it does not depend on the camera).

The orbit (no ``--path``): about the centre of the asset's bounding box, +y up (app/camera.py),
at ``--elevation`` degrees above the horizontal through it and ``--distance`` metres from it
(default: the distance at which the asset's bounding sphere just fills the narrower field of
view). Frame k sits at the angle 360 k / N about +y from the +z side: position =
centre + d (cos e sin t, sin e, cos e cos t), looking at the centre - counter-clockwise seen from
above, the object JSON's rotation convention. ``--path cameras.json`` gives the cameras instead:
a JSON list of camera objects in app/camera.py's format (or ``{"cameras": [...]}``), one frame
each, all of one image size (or ``--size``).

A render farm splits the work with ``--range A-B`` (inclusive, 0-based): each machine renders
only its frames into the shared DIR. An existing DIR is fine; an existing frame of the range is
overwritten only with ``--force`` (otherwise the run stops before rendering, naming it, exit 3).
``DIR/turntable.mp4`` (H.264, yuv420p, ``--fps``) is assembled from the PNGs by whichever run
finds all N of them in DIR when it ends - a full run, or the farm's last machine - unless
``--no-video``; H.264 needs even sizes, so an odd width or height is padded by one repeated
edge pixel (and said). The MP4 is derived from the frames and is rewritten (atomically)
whenever it is assembled.
"""

from __future__ import annotations

import contextlib
import logging
import math
import re
import signal
import threading
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from app.camera import Camera, camera_from_dict, parse_size
from app.commands.asset_args import add_object_arguments, check_object_args, load_placed_asset
from app.commands.options import add_param_options, given_values, param_values
from app.errors import ScanlightError, UsageError

log = logging.getLogger(__name__)

FRAME_PATTERN = "frame_{:04d}"           # frame_0000.exr, frame_0000.png
VIDEO_NAME = "turntable.mp4"
MAX_FRAMES = 100_000                     # ~70 minutes at 24 fps
DEFAULT_SIZE = "640x480"
DEFAULT_ELEVATION = 20.0                 # degrees: a little above, so the top shows
VIDEO_CRF = 10                           # libx264 quality (imageio-ffmpeg's quality 8)


def add_arguments(parser) -> None:
    parser.add_argument("--cloud", required=True, metavar="C.ply", help="point cloud (PLY/PCD/XYZ)")
    add_object_arguments(parser)
    parser.add_argument("--material", metavar="M.json",
                        help="Disney material JSON for the whole asset (default: its own)")
    parser.add_argument("--out", required=True, metavar="DIR",
                        help="folder of the sequence: frame_0000.exr/.png ..., turntable.mp4 "
                             "(an existing folder is fine)")
    parser.add_argument("--count", type=int, metavar="N",
                        help="frames in the orbit (with --path: the cameras' count; optional)")
    parser.add_argument("--path", metavar="CAMERAS.json",
                        help="cameras instead of the orbit: a JSON list of camera objects "
                             "(position, look_at, up, fov_y_deg, width, height), one frame each")
    parser.add_argument("--range", dest="frame_range", metavar="A-B",
                        help="render only frames A..B (inclusive, 0-based) of the N: split the "
                             "work across machines writing into one DIR (default: all)")
    parser.add_argument("--size", metavar="WxH",
                        help=f"image size (default {DEFAULT_SIZE}; with --path the cameras')")
    parser.add_argument("--elevation", type=float, metavar="DEG",
                        help=f"orbit: degrees above the asset centre's horizontal "
                             f"(default {DEFAULT_ELEVATION:g}; -89 .. 89)")
    parser.add_argument("--distance", type=float, metavar="M",
                        help="orbit: metres from the asset's centre (default: its bounding "
                             "sphere fills the field of view)")
    parser.add_argument("--background", action="store_true",
                        help="composite over the room's point splats (with the asset's shadow "
                             "and bounce on the scan: --differential)")
    parser.add_argument("--fps", type=float, default=24.0, metavar="FPS",
                        help="frame rate of the MP4 (default 24)")
    parser.add_argument("--no-video", action="store_true",
                        help="do not assemble DIR/turntable.mp4 even when every frame is there")
    parser.add_argument("--force", action="store_true",
                        help="overwrite frames of the range that already exist in DIR")
    add_param_options(parser, "turntable")


# -- the cameras -------------------------------------------------------------------------------

def bounding_sphere(mesh) -> tuple[np.ndarray, float]:
    """(centre of the bounding box, radius of the sphere about it holding every vertex)."""
    lo, hi = mesh.bounds()
    centre = 0.5 * (np.asarray(lo, np.float64) + np.asarray(hi, np.float64))
    used = mesh.positions[np.unique(mesh.indices)]
    return centre, float(np.linalg.norm(used - centre, axis=1).max())


def framing_distance(radius: float, fov_y_deg: float, width: int, height: int) -> float:
    """The distance from which a sphere of ``radius`` just fills the narrower field of view:
    its silhouette's half-angle asin(r / d) equals that half field of view."""
    half_y = math.radians(fov_y_deg) / 2
    half_x = math.atan(math.tan(half_y) * width / height)
    return radius / math.sin(min(half_x, half_y))


def orbit_cameras(centre, distance: float, elevation_deg: float, count: int,
                  fov_y_deg: float, width: int, height: int) -> list[Camera]:
    """Frame k at the angle 360 k / count about +y from the +z side (the module docstring)."""
    c = np.asarray(centre, np.float64)
    e = math.radians(elevation_deg)
    cams = []
    for k in range(count):
        t = 2 * math.pi * k / count
        offset = np.array([math.cos(e) * math.sin(t), math.sin(e), math.cos(e) * math.cos(t)])
        cams.append(Camera(c + distance * offset, c, (0.0, 1.0, 0.0), fov_y_deg, width, height))
    return cams


def load_camera_path(path) -> list[Camera]:
    """The cameras of ``--path``: a JSON list of camera objects or ``{"cameras": [...]}``."""
    from app.io.files import read_json, require_file
    p = require_file(path, "camera path", (".json",))
    data = read_json(p, "camera path")
    if isinstance(data, dict) and "cameras" in data:
        data = data["cameras"]
    if not isinstance(data, list) or not data:
        raise ScanlightError(p, "expected a non-empty JSON list of cameras (or {\"cameras\": "
                                "[...]})")
    if len(data) > MAX_FRAMES:
        raise ScanlightError(p, f"{len(data)} cameras: more than the limit of {MAX_FRAMES} "
                                "frames")
    return [camera_from_dict(d, p, f"camera {i}") for i, d in enumerate(data)]


def parse_range(text: str | None, count: int) -> tuple[int, int]:
    """``--range A-B`` (or ``A``) as (A, B), inclusive and within the ``count`` frames."""
    if text is None:
        return 0, count - 1
    m = re.fullmatch(r"\s*(\d+)\s*(?:-\s*(\d+)\s*)?", text)
    if not m:
        raise UsageError(None, f"--range must look like 0-99 (first-last frame, 0-based, "
                               f"inclusive), got {text!r}")
    a = int(m.group(1))
    b = int(m.group(2)) if m.group(2) is not None else a
    if a > b:
        raise UsageError(None, f"--range {text}: the first frame is after the last")
    if b >= count:
        raise UsageError(None, f"--range {text} is outside the {count} frames "
                               f"(0-{count - 1})")
    return a, b


# -- the command ---------------------------------------------------------------------------------

def _check_args(args) -> tuple[dict, dict]:
    """(values, given): the table's parameters, after the usage checks of the other flags."""
    values = param_values(args, "turntable")
    given = given_values(args, "turntable")
    if args.path is None and args.count is None:
        raise UsageError(None, "give --count N (frames in the orbit) or --path cameras.json")
    if args.count is not None and not 1 <= args.count <= MAX_FRAMES:
        raise UsageError(None, f"--count must be 1 .. {MAX_FRAMES}, got {args.count}")
    if args.path is not None:
        orbit_flags = [f for f, v in (("--elevation", args.elevation),
                                      ("--distance", args.distance),
                                      ("--fov", given.get("view.fov_y"))) if v is not None]
        if orbit_flags:
            raise UsageError(None, f"{', '.join(orbit_flags)} set the orbit; --path gives the "
                                   "cameras themselves")
    if args.elevation is not None and not -89.0 <= args.elevation <= 89.0:
        raise UsageError(None, f"--elevation must be -89 .. 89 degrees, got {args.elevation:g}")
    if args.distance is not None and not 0 < args.distance < 1e6:
        raise UsageError(None, f"--distance must be a positive number of metres, got "
                               f"{args.distance:g}")
    if not 0.1 <= args.fps <= 240:
        raise UsageError(None, f"--fps must be 0.1 .. 240, got {args.fps:g}")
    if args.size:
        parse_size(args.size)
    if args.frame_range is not None and args.count is not None:
        parse_range(args.frame_range, args.count)       # before anything is loaded
    check_object_args(args)          # the asset's flags and file, before the cloud loads
    return values, given


def frame_paths(out_dir: Path, k: int) -> tuple[Path, Path]:
    name = FRAME_PATTERN.format(k)
    return out_dir / f"{name}.exr", out_dir / f"{name}.png"


def _check_targets(args, out_dir: Path, first: int, last: int) -> None:
    """Before any work: DIR is a folder (or will be), no frame or the MP4 is an input, and the
    range's frames do not exist yet unless --force."""
    from app.io.outputs import check_outputs
    if out_dir.exists() and not out_dir.is_dir():
        raise ScanlightError(out_dir, "--out names a file, not a folder")
    inputs = {"--cloud": args.cloud, "--object": args.object, "--material": args.material,
              "--path": args.path}
    existing = []
    for k in range(first, last + 1):
        exr, png = frame_paths(out_dir, k)
        check_outputs(inputs, {f"frame {k} (EXR)": exr, f"frame {k} (PNG)": png})
        existing += [p for p in (exr, png) if p.exists()]
    if not args.no_video:
        check_outputs(inputs, {"the video": out_dir / VIDEO_NAME})
    if existing and not args.force:
        more = f" (and {len(existing) - 1} more frame files of the range)" \
            if len(existing) > 1 else ""
        raise ScanlightError(existing[0], f"exists{more}: pass --force to overwrite, or render "
                                          "another --range")


def _path_cameras(args) -> list[Camera]:
    """``--path``'s cameras, at ``--size`` if given; one image size for the whole sequence."""
    cams = load_camera_path(args.path)
    if args.count is not None and args.count != len(cams):
        raise UsageError(None, f"--count {args.count} but {args.path} has {len(cams)} cameras")
    if args.size:
        w, h = parse_size(args.size)
        cams = [replace(c, width=w, height=h) for c in cams]
    sizes = {(c.width, c.height) for c in cams}
    if len(sizes) > 1:
        raise ScanlightError(args.path, f"the cameras have {len(sizes)} different image sizes; "
                                        "a sequence needs one (or give --size)")
    return cams


def _orbit(args, values: dict, mesh) -> list[Camera]:
    """The orbit's cameras (the module docstring), at ``--size`` or DEFAULT_SIZE."""
    w, h = parse_size(args.size or DEFAULT_SIZE)
    fov = float(values["view.fov_y"])
    centre, radius = bounding_sphere(mesh)
    distance = args.distance if args.distance is not None else \
        framing_distance(radius, fov, w, h)
    elevation = DEFAULT_ELEVATION if args.elevation is None else args.elevation
    log.info("orbit about (%.3f, %.3f, %.3f): %.3f m away, %g degrees up, %d frames",
             *centre, distance, elevation, args.count)
    return orbit_cameras(centre, distance, elevation, args.count, fov, w, h)


def run(args) -> int:
    from app.commands.progress import progress, quiet_of
    from app.render.alpha import over
    from app.io.exr import write_exr
    from app.io.images import write_png
    from app.io.outputs import OutputSet
    from app.io.pointcloud import load_cloud
    from app.material import load_material
    from app.pbgi.renderer import Relighter, RenderParams
    from app.pbgi.upsample import gi_scale_of, render_passes_of, render_upsampled
    from app.render.memory import check_render_memory
    from app.render.tonemap import tonemap_to_srgb8

    values, _ = _check_args(args)
    out_dir = Path(args.out)
    path_cams = _path_cameras(args) if args.path is not None else None
    count = len(path_cams) if path_cams is not None else args.count
    first, last = parse_range(args.frame_range, count)
    _check_targets(args, out_dir, first, last)
    w, h = ((path_cams[0].width, path_cams[0].height) if path_cams
            else parse_size(args.size or DEFAULT_SIZE))
    check_render_memory(w, h)

    cloud = load_cloud(args.cloud)
    mesh, _ = load_placed_asset(args, cloud)
    materials = [load_material(args.material)] if args.material else None
    cams = path_cams if path_cams is not None else _orbit(args, values, mesh)

    r = Relighter()
    r.set_cloud(cloud)
    r.set_asset(mesh)
    params = RenderParams.from_settings(values)
    passes = render_passes_of(values, r.materials_for(materials))
    scale = gi_scale_of(values, r.materials_for(materials))
    edge_samples = int(values["pbgi.edge_samples"])
    exposure, tonemapper = values["view.exposure"], values["view.tonemap"]
    diff = None
    if args.background and values["pbgi.differential"] and params.mode != "envmap":
        t = time.perf_counter()
        diff = r.differential(materials, params)   # the scan's change: the same for every frame
        log.info("the asset's shadow and bounce on %d scan points: %.1f s", len(diff.index),
                 time.perf_counter() - t)

    n = last - first + 1
    t0 = time.perf_counter()
    incomplete = []
    with progress(n, "turntable", unit="frame", quiet=quiet_of(args)) as bar:
        for i, k in enumerate(range(first, last + 1)):
            cam, t = cams[k], time.perf_counter()
            res = render_upsampled(r, cam, materials, params, passes, scale,
                                   edge_samples=edge_samples)
            rgba = res.image
            if args.background:
                rgba = over(rgba, r.background(cam, diff, eye_dome=values["view.eye_dome"]))
            if not res.stats.completed:
                incomplete.append(k)
            exr, png = frame_paths(out_dir, k)
            srgb8 = tonemap_to_srgb8(rgba, exposure, tonemapper)
            with ctrl_c_after_block(), OutputSet({"exr": exr, "png": png}) as outs:
                write_exr(outs.temp("exr"), rgba)
                write_png(outs.temp("png"), srgb8)
            log.info("frame %d (%d/%d of this run): %.0f ms, %s", k, i + 1, n,
                     1000 * (time.perf_counter() - t), png.name)
            bar.update(1)
    seconds = time.perf_counter() - t0
    if incomplete:
        log.warning("frames %s did not complete for every pixel (as render's stats: "
                    "completed false)", ", ".join(map(str, incomplete)))

    w, h = cams[0].width, cams[0].height
    summary = (f"rendered {n} frame{'s' if n != 1 else ''} {first}-{last} of {count}, {w}x{h} "
               f"({params.mode}, M={params.microbuffer}"
               + (f", {passes} passes each" if passes > 1 else "")
               + f") in {seconds:.1f} s into {out_dir}")
    if not args.no_video:
        missing = [k for k in range(count) if not frame_paths(out_dir, k)[1].is_file()]
        if missing:
            summary += f"; the video waits for {len(missing)} frame(s) (first: {missing[0]})"
        else:
            video = write_video(out_dir, count, args.fps)
            summary += f"; video {video} ({count} frames at {args.fps:g} fps)"
    print(summary)
    return 0


@contextlib.contextmanager
def ctrl_c_after_block():
    """Ctrl-C while a frame's files are written takes effect once they are in place: the
    interrupt then lands in the rendering, where no file of the frame exists yet, and never
    between a temporary's creation and its registration in the OutputSet (which would leave
    the temporary behind). Writing a frame takes milliseconds, so the wait is short."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: caught.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
    if caught:
        raise KeyboardInterrupt


def write_video(out_dir: Path, count: int, fps: float) -> Path:
    """``DIR/turntable.mp4`` from the ``count`` PNG frames: H.264, yuv420p, over black (the
    PNGs' premultiplied colour without their alpha), an odd side padded by one edge pixel.
    ffmpeg's exit status is checked and the written file re-read before it is committed: a full
    disk or a file-size limit stops ffmpeg but leaves a truncated file behind, which must
    never be renamed into place as the video."""
    from app.io.outputs import OutputSet

    target = out_dir / VIDEO_NAME
    with OutputSet({"video": target}) as outs:
        tmp = outs.temp("video")
        _encode(_video_frames(out_dir, count), tmp, fps, target)
        _check_video(tmp, count, target)
    return target


def _video_frames(out_dir: Path, count: int):
    """The PNG frames as RGB arrays of one even size (an odd side padded by its edge pixel)."""
    from PIL import Image

    size = None
    for k in range(count):
        png = frame_paths(out_dir, k)[1]
        try:
            with Image.open(png) as im:
                rgb = np.asarray(im.convert("RGB"))
        except OSError as err:
            raise ScanlightError(png, f"cannot read the frame for the video: {err}") from None
        if size is None:
            size = rgb.shape[1], rgb.shape[0]
            even = size[0] + size[0] % 2, size[1] + size[1] % 2
            if even != size:
                log.info("H.264 needs even sizes: the video's frames are padded from %dx%d to "
                         "%dx%d", *size, *even)
        elif (rgb.shape[1], rgb.shape[0]) != size:
            raise ScanlightError(png, f"is {rgb.shape[1]}x{rgb.shape[0]}, frame 0 is "
                                      f"{size[0]}x{size[1]}: a video needs one size")
        yield np.pad(rgb, ((0, even[1] - size[1]), (0, even[0] - size[0]), (0, 0)), mode="edge")


def _encode(frames, tmp: Path, fps: float, target: Path) -> None:
    """Pipe ``frames`` through ffmpeg into ``tmp``. ffmpeg runs itself (not imageio-ffmpeg's
    writer, which neither checks its exit status nor keeps its messages off stderr) so that a
    failure is one error naming ``target`` with ffmpeg's reason."""
    import itertools
    import subprocess
    import tempfile
    from fractions import Fraction

    import imageio_ffmpeg

    first = next(frames)
    h, w = first.shape[:2]
    cmd = [imageio_ffmpeg.get_ffmpeg_exe(), "-nostdin", "-y", "-v", "error",
           "-f", "rawvideo", "-pix_fmt", "rgb24", "-s", f"{w}x{h}",
           "-r", str(Fraction(fps).limit_denominator()), "-i", "-", "-an",
           "-vcodec", "libx264", "-pix_fmt", "yuv420p", "-crf", str(VIDEO_CRF),
           "-movflags", "+faststart", str(tmp)]
    with tempfile.TemporaryFile() as messages:
        # its own session: Ctrl-C reaches Python only, which then stops ffmpeg itself
        proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL,
                                stderr=messages, start_new_session=True)
        try:
            try:
                with proc.stdin as pipe:
                    for rgb in itertools.chain([first], frames):
                        pipe.write(np.ascontiguousarray(rgb).tobytes())
            except BrokenPipeError:
                pass            # ffmpeg stopped early: its exit status and messages say why
            status = proc.wait()
        except BaseException:   # a frame that cannot be read, Ctrl-C: no video
            proc.kill()
            proc.wait()
            raise
        if status != 0:
            messages.seek(0)
            raise ScanlightError(target, "could not be written: "
                                         + _ffmpeg_failure(status, messages.read()))


def _ffmpeg_failure(status: int, messages: bytes) -> str:
    """One line for ffmpeg's failure: the signal that stopped it, or its last message without
    the ``[out#0/mp4 @ 0x...]`` prefix."""
    if status < 0:
        if status == -getattr(signal, "SIGXFSZ", 0):
            return "file too large (ffmpeg was stopped by the file-size limit)"
        return f"ffmpeg was killed by signal {-status}"
    lines = [ln.strip() for ln in messages.decode(errors="replace").splitlines() if ln.strip()]
    if not lines:
        return f"ffmpeg failed (exit status {status})"
    return "ffmpeg: " + re.sub(r"^\[[^]]*\]\s*", "", lines[-1])[:200]


def _check_video(tmp: Path, count: int, target: Path) -> None:
    """The written video must hold every frame: ffmpeg can exit 0 and still leave a video whose
    end is missing (a partial file is read without an error)."""
    import imageio_ffmpeg
    try:
        found = imageio_ffmpeg.count_frames_and_secs(str(tmp))[0]
    except (RuntimeError, OSError) as err:
        reason = str(err).strip().splitlines()[-1] if str(err).strip() else type(err).__name__
        raise ScanlightError(target, f"is not a playable video: {reason[:200]}") from None
    if found != count:
        raise ScanlightError(target, f"came out with {found} of its {count} frames")


__all__ = ["add_arguments", "run", "orbit_cameras", "framing_distance", "bounding_sphere",
           "load_camera_path", "parse_range", "write_video", "FRAME_PATTERN", "VIDEO_NAME"]
