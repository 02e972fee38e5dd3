"""``scanlight view``: open the session (or the demo), then run the window or the offscreen loop.

Offscreen (``--offscreen``) runs the same ViewerEngine on the headless EGL context: the frames are
drawn exactly as in the window (same passes, same size), without the imgui panels. A screenshot
is always taken once the progressive refinement has finished, so batch images do not depend on
how fast the machine is.

Automation (``--script FILE``): a Python file defining ``on_frame(viewer, frame_index)``, called
after each frame in either mode with the viewer (``ViewerWindow`` or ``OffscreenViewer``: its
``engine``, ``session``, ``quit()``, ``save_window_png()``, and ``script_args``, the
``--script-arg`` strings). The window tests (tests/ui/ui_window_script.py) and the README
screenshot (app/ui/screenshot.py) are such scripts.

Both viewers pass the renderer the viewer ships, ``app.pbgi.renderer.Relighter``, to their
engine (``relighter=``; tests inject theirs the same way).
"""

from __future__ import annotations

import importlib.util
import logging
import sys
from pathlib import Path

from app.camera import parse_size as camera_parse_size
from app.errors import ScanlightError, UsageError
from app.pbgi.renderer import Relighter
from app.settings import Session, load_last_session, load_session
from app.ui import demo_light
from app.ui.shots import check_screenshot, save_png

log = logging.getLogger(__name__)


# The viewer's side limit: its splat pass draws a guard band around the window, so a side near
# the 16384 of app.io.limits overflowed llvmpipe's largest framebuffer (16383 x 16: "framebuffer
# is not complete", an internal error); no screen is wider than 8192.
VIEWER_MAX_SIDE = 8192


def parse_size(text) -> tuple[int, int]:
    """The window size: at least 16x16 so the panels and the viewport fit, at most
    VIEWER_MAX_SIDE a side."""
    size = camera_parse_size(text, minimum=16)
    if max(size) > VIEWER_MAX_SIDE:
        raise UsageError(None, f"--size: a viewer side of more than {VIEWER_MAX_SIDE} pixels is "
                               f"not supported, got {size[0]}x{size[1]}")
    return size


def load_script(path):
    """The ``on_frame(viewer, frame_index)`` function of the script file ``path``; a missing or
    broken file is a ScanlightError naming it."""
    p = Path(path)
    if not p.is_file():
        raise ScanlightError(p, "script not found")
    spec = importlib.util.spec_from_file_location("scanlight_ui_script", p)
    if spec is None or spec.loader is None:
        raise ScanlightError(p, "cannot load the script (not a Python file?)")
    mod = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(mod)
    except Exception as exc:
        raise ScanlightError(p, f"the script failed to load: {type(exc).__name__}: {exc}") \
            from exc
    if not callable(getattr(mod, "on_frame", None)):
        raise ScanlightError(p, "the script defines no on_frame(viewer, frame_index) function")
    on_frame = mod.on_frame

    def run_script(viewer, frame_index):
        # a script's own error (a raise, a wrong signature, a bad value handed to the viewer) is
        # the script's line, exit 3, not an internal error of the viewer
        try:
            return on_frame(viewer, frame_index)
        except ScanlightError as err:     # a value the viewer refused: say which script sent it
            raise ScanlightError(p, f"on_frame failed at frame {frame_index}: {err}") from err
        except Exception as exc:
            raise ScanlightError(p, f"on_frame failed at frame {frame_index}: "
                                    f"{type(exc).__name__}: {exc}") from exc
    return run_script


def open_session(args, cloud: str | None = None, asset: str | None = None) -> Session:
    """The session to open: --session, --last, or the demo's (with ``cloud``, that scan instead
    of the demo room; the asset is placed once the cloud is loaded: app.ui.files.open_at_start)."""
    from app.ui.engine import default_session
    if getattr(args, "session", None) and getattr(args, "last", False):
        raise UsageError(None, "give either --session or --last, not both")
    if (cloud or asset) and (getattr(args, "session", None) or getattr(args, "last", False)):
        raise UsageError(None, "give either CLOUD/ASSET or --session/--last, not both")
    if cloud:
        s = default_session()
        s.cloud, s.photo = cloud, None       # the demo's photo is of the demo room
        return s
    if getattr(args, "session", None):
        return load_session(args.session)
    if getattr(args, "last", False):
        return load_last_session()
    return default_session()


class OffscreenViewer:
    """The window's frame loop without a window (same engine, same drawing)."""

    def __init__(self, session: Session, size, script=None, *, relighter=Relighter,
                 script_args=()):
        from app.render.context import get_context
        from app.ui.engine import ViewerEngine
        self.ctx = get_context()
        self.session = session
        self.engine = ViewerEngine(self.ctx, session, size=size, relighter=relighter)
        # the demo's HDR light before the first frame: screenshots never depend on timing
        said = self.engine.guard("the demo's HDR light", demo_light.expand_now, session,
                                 self.engine)
        if said:
            self.engine.error(said, "info")
        self.fail_on_errors()        # a missing or corrupt file: exit 3 before any frame
        self.script = script
        self.script_args = list(script_args)
        self.frame_index = 0
        self.quit_requested = False

    def quit(self) -> None:
        self.quit_requested = True

    def fail_on_errors(self) -> None:
        """Offscreen runs are batch jobs: an error the window would show as a message (a file
        that did not load, a failed render) fails the run with that line instead (exit 3), so
        no screenshot of a half-loaded scene is ever passed off as a result."""
        errors = [m.text for m in self.engine.messages if m.level == "error"]
        if errors:
            raise ScanlightError(None, errors[0])

    def read_window(self):
        return self.engine.view.read_display()

    def save_window_png(self, path) -> None:
        save_png(path, self.read_window(), self.session)

    def run(self, frames: int, screenshot: str | None = None) -> int:
        frames = max(int(frames), 1)
        while self.frame_index < frames and not self.quit_requested:
            self.engine.frame()
            if self.script is not None:
                self.script(self, self.frame_index)
            self.frame_index += 1
        self.fail_on_errors()
        if screenshot:
            files = self.engine.screenshot(screenshot)
            print("screenshot: " + ", ".join(files))
        for m in self.engine.messages:
            if m.level != "info":
                print(f"scanlight view: {m.level}: {m.text}", file=sys.stderr)
        return 0


def run_viewer(args) -> int:
    from app.commands.asset_args import placement_options
    from app.ui.files import open_at_start, startup_files
    from app.render.memory import check_render_memory
    size = parse_size(getattr(args, "size", "1280x800"))
    check_render_memory(*size)           # a window's frames are renders of its size
    placement = placement_options(args)
    cloud, asset = startup_files([p for p in (getattr(args, "cloud", None),
                                              getattr(args, "asset", None)) if p])
    if not (cloud or asset) and any(v is not None for v in placement):
        raise UsageError(None, "--fit, --translate and --rotate place an ASSET or CLOUD given "
                               "on the command line")
    session = open_session(args, cloud, asset)
    script_path = getattr(args, "script", None)
    script = load_script(script_path) if script_path else None
    script_args = list(getattr(args, "script_arg", None) or [])
    frames = int(getattr(args, "frames", 0) or 0)
    if frames < 0:
        raise UsageError(None, f"--frames must be >= 0, got {frames}")
    shot = getattr(args, "screenshot", None)
    if shot and Path(shot).suffix.lower() != ".png":
        raise UsageError(None, f"--screenshot must name a .png file (an .exr of the linear "
                               f"image is written beside it), got {shot!r}")
    if shot:
        check_screenshot(shot, session, [cloud, asset, script_path])
    if getattr(args, "offscreen", False):
        viewer = OffscreenViewer(session, size, script, relighter=Relighter,
                                 script_args=script_args)
        if cloud or asset:
            open_at_start(viewer.engine, asset, *placement)
            viewer.fail_on_errors()
        return viewer.run(frames, shot)
    try:
        from app.ui.window import ViewerWindow
        native = False if getattr(args, "no_native_dialogs", False) else None
        viewer = ViewerWindow(session, size, script, relighter=Relighter,
                              script_args=script_args, native_dialogs=native)
    except ScanlightError:
        raise
    except Exception as exc:  # no usable display / GL 4.3: say so in one line
        raise ScanlightError(None, f"cannot open the viewer window ({type(exc).__name__}: {exc}); "
                                   "use --offscreen, or run under xvfb-run") from None
    if cloud or asset:
        open_at_start(viewer.engine, asset, *placement)
    return viewer.run(frames, shot)
