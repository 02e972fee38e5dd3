"""``scanlight view``: the look-dev window; headless machines fall back to the demo."""

from __future__ import annotations

import logging
import sys

from app.render.context import is_headless_display

log = logging.getLogger(__name__)


def add_arguments(parser) -> None:
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
    parser.add_argument("--demo-size", type=int, default=128,
                        help="render size of the headless fallback demo")


def run(args) -> int:
    if not args.offscreen and is_headless_display():
        if args.script:
            from app.errors import UsageError
            raise UsageError(None, "--script drives the viewer, but there is no display (DISPLAY "
                                   "is not set): add --offscreen, or run under xvfb-run")
        print("scanlight view: no display found (DISPLAY is not set); running the headless demo "
              f"instead, writing to {args.out}/ (use xvfb-run for a virtual screen)", file=sys.stderr)
        from app.commands import demo
        return demo.run(args)
    from app.ui.app import run_viewer
    return run_viewer(args)
