"""The README screenshot: the real window (panels included) on the demo scene, taken by the
project's own tooling.

    python -m app.ui.screenshot [--out assets/screenshot.png] [--size 1280x800] [--no-expand]
    (packaging/screenshot.sh runs it under Xvfb)

It opens the viewer on the built-in demo scene, runs the HDR expansion from the demo's capture
camera (shown with the expansion's report in the HDR panel), lets the progressive refinement of
the relit asset finish, then saves the window's framebuffer. Without a display it re-runs itself
under xvfb-run.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
from pathlib import Path

MAX_FRAMES = 20000


def _script(out: Path, expand: bool, face: int):
    state = {"step": 0, "since": 0}

    def on_frame(viewer, frame):
        e = viewer.engine
        if frame > MAX_FRAMES:
            print("screenshot: gave up waiting for the refinement", file=sys.stderr)
            viewer.quit()
            return
        if state["step"] == 0 and frame >= 2:
            if expand:
                viewer.session.settings.set("hdr.face_size", face)
                viewer.start_expansion(synchronous=True)
                viewer.poll_expansion()
            state["step"], state["since"] = 1, frame
        elif state["step"] == 1 and frame - state["since"] > 3 and not e.gi.refining:
            e.messages.clear()
            state["step"], state["since"] = 2, frame
        elif state["step"] == 2 and frame - state["since"] >= 2:  # the frame without messages
            viewer.save_window_png(out)
            print(f"screenshot: wrote {out}")
            viewer.quit()
    return on_frame


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m app.ui.screenshot",
                                description=__doc__.split("\n")[0])
    p.add_argument("--out", default="assets/screenshot.png")
    p.add_argument("--size", default="1280x800")
    p.add_argument("--no-expand", action="store_true", help="skip the HDR expansion")
    p.add_argument("--face-size", type=int, default=256, help="cube-map face size of the expansion")
    args = p.parse_args(argv)
    if not os.environ.get("DISPLAY"):
        if not shutil.which("xvfb-run"):
            print("screenshot: no display and no xvfb-run (apt-get install xvfb)", file=sys.stderr)
            return 1
        cmd = ["xvfb-run", "-a", "-s", "-screen 0 1600x1000x24", sys.executable, "-m",
               "app.ui.screenshot"] + (argv if argv is not None else sys.argv[1:])
        return subprocess.call(cmd)
    from app.ui.app import parse_size
    from app.ui.engine import default_session
    from app.ui.window import ViewerWindow
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    session = default_session()
    session.settings.update({"pbgi.frame_budget_ms": 250.0})
    viewer = ViewerWindow(session, parse_size(args.size),
                          _script(out, not args.no_expand, args.face_size))
    viewer.run()
    return 0 if out.is_file() else 1


if __name__ == "__main__":
    raise SystemExit(main())
