"""``scanlight view [CLOUD] [ASSET]``: the look-dev window; headless machines fall back to the demo.

    scanlight view room.ply bunny.glb [--fit S] [--translate X,Y,Z] [--rotate X,Y,Z]

CLOUD and ASSET (either order, each optional) open that scan and that asset instead of the demo's:
a mesh stands on the scan's floor below the room's centre, in its own units unless ``--fit``, as
``render --object`` places it (app/commands/asset_args.py, app/io/placement.py); an object JSON
where it says; a cloud alone gets the default sphere standing on its floor. The view starts
framed on the asset. A missing or unreadable file is one line, exit 3."""

from __future__ import annotations

import logging
import sys

from app.render.context import is_headless_display

log = logging.getLogger(__name__)


def add_arguments(parser) -> None:
    from app.commands.asset_args import add_placement_arguments
    parser.add_argument("cloud", nargs="?", metavar="CLOUD",
                        help="open this point cloud (PLY/PCD/XYZ) instead of the demo room")
    parser.add_argument("asset", nargs="?", metavar="ASSET",
                        help="open this asset: a mesh (.glb/.gltf/.obj), standing on the "
                             "scan's floor, or an object JSON (either order with CLOUD)")
    add_placement_arguments(parser)
    parser.add_argument("--session", metavar="JSON", help="open a saved session")
    parser.add_argument("--last", action="store_true", help="reopen the last session")
    parser.add_argument("--offscreen", action="store_true",
                        help="no window: render through EGL (tests, batch screenshots)")
    parser.add_argument("--frames", type=int, default=0,
                        help="quit after N frames (0 = run until closed)")
    parser.add_argument("--screenshot", metavar="PNG",
                        help="save a screenshot (PNG, plus EXR of the linear image) before quitting")
    parser.add_argument("--size", default="1280x800", help="window size WxH")
    parser.add_argument("--script", metavar="FILE",
                        help="automation: a Python file defining on_frame(viewer, frame_index), "
                             "called after each frame (window or --offscreen) with the viewer "
                             "(viewer.engine, viewer.session, viewer.quit(), "
                             "viewer.save_window_png(path)); for automated tests and batch "
                             "capture")
    parser.add_argument("--script-arg", metavar="TEXT", action="append", default=[],
                        help="a string for the --script, in viewer.script_args (repeatable; "
                             "e.g. out=shots/)")
    parser.add_argument("--no-native-dialogs", action="store_true",
                        help="use the viewer's own file browser instead of the desktop's "
                             "dialogs (zenity / kdialog)")
    parser.add_argument("--out", default="scanlight-demo", help="output folder of the headless fallback")
    from app.demo.pipeline import DEFAULT_SIZE
    parser.add_argument("--demo-size", type=int, default=DEFAULT_SIZE,
                        help=f"render size of the headless fallback demo (default {DEFAULT_SIZE}, "
                             "as scanlight demo)")


def run(args) -> int:
    if not args.offscreen and is_headless_display():
        if args.script or getattr(args, "cloud", None) or getattr(args, "asset", None):
            from app.errors import UsageError
            what = "--script drives the viewer" if args.script else "the files open in the viewer"
            raise UsageError(None, f"{what}, but there is no display (DISPLAY "
                                   "is not set): add --offscreen, or run under xvfb-run")
        print("scanlight view: no display found (DISPLAY is not set); running the headless demo "
              f"instead, writing to {args.out}/ (use xvfb-run for a virtual screen)", file=sys.stderr)
        from app.commands import demo
        return demo.run(args)
    from app.ui.app import run_viewer
    return run_viewer(args)
