"""The README screenshot: the real window (panels included) on the demo scene, taken by the
project's own tooling through the viewer's automation option.

    scanlight view --size 1280x800 --script app/ui/screenshot.py \
        --script-arg out=assets/screenshot.png [--script-arg expand=no]
    python -m app.ui.screenshot [--out assets/screenshot.png] [--size 1280x800] [--no-expand]
    (packaging/screenshot.sh runs the first under Xvfb when there is no display)

This file is the ``--script``: it waits for the demo's own HDR light (app/ui/demo_light.py), or
runs the HDR expansion from the session's capture cameras with the viewer's settings when the
room has no HDR colours yet, as a user pressing "Run expansion" would, lets the progressive
refinement of the relit asset finish, then saves the window's framebuffer and quits. ``main``
starts ``scanlight view`` with it, re-running itself under xvfb-run without a display.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
from pathlib import Path

MAX_FRAMES = 20000
FRAME_BUDGET_MS = 250.0    # larger refinement tiles: nobody interacts with this window
state = {"step": 0, "since": 0}


def _options(viewer) -> dict:
    opts = {"out": "assets/screenshot.png", "expand": "yes"}
    for arg in viewer.script_args:
        key, sep, value = arg.partition("=")
        if not sep or key not in opts:
            from app.errors import UsageError
            raise UsageError(None, f"screenshot script: unknown --script-arg {arg!r} (give "
                                   f"{', '.join(k + '=...' for k in opts)})")
        opts[key] = value
    return opts


def on_frame(viewer, frame):
    """Expand (unless expand=no), wait for the refinement, clear the messages, save, quit."""
    from app.errors import ScanlightError
    e = viewer.engine
    if frame > MAX_FRAMES:
        raise ScanlightError(None, "screenshot: gave up waiting for the refinement")
    if frame == 0:
        state["opts"] = _options(viewer)
        viewer.session.settings.set("pbgi.frame_budget_ms", FRAME_BUDGET_MS)
    opts = state["opts"]
    if state["step"] == 0 and frame >= 2:
        if viewer.hdr_task is not None:       # the demo's own HDR light is on its way
            return
        has_hdr = e.cloud is not None and e.cloud.hdr is not None
        if opts["expand"] not in ("no", "0", "false") and not has_hdr:
            viewer.start_expansion(synchronous=True)
            viewer.poll_expansion()
        state["step"], state["since"] = 1, frame
    elif state["step"] == 1 and frame - state["since"] > 3 and not e.gi.refining:
        e.messages.clear()
        state["step"], state["since"] = 2, frame
    elif state["step"] == 2 and frame - state["since"] >= 2:  # the frame without messages
        out = Path(opts["out"])
        out.parent.mkdir(parents=True, exist_ok=True)
        viewer.save_window_png(out)
        print(f"screenshot: wrote {out}")
        viewer.quit()


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m app.ui.screenshot",
                                description=__doc__.split("\n")[0])
    p.add_argument("--out", default="assets/screenshot.png")
    p.add_argument("--size", default="1280x800")
    p.add_argument("--no-expand", action="store_true", help="skip the HDR expansion")
    args = p.parse_args(argv)
    if not os.environ.get("DISPLAY"):
        if not shutil.which("xvfb-run"):
            print("screenshot: no display and no xvfb-run (apt-get install xvfb)", file=sys.stderr)
            return 1
        cmd = ["xvfb-run", "-a", "-s", "-screen 0 1600x1000x24", sys.executable, "-m",
               "app.ui.screenshot"] + (argv if argv is not None else sys.argv[1:])
        return subprocess.call(cmd)
    from app.cli import main as scanlight
    out = Path(args.out)
    rc = scanlight(["view", "--size", args.size, "--script", __file__,
                    "--script-arg", f"out={out}",
                    "--script-arg", f"expand={'no' if args.no_expand else 'yes'}"])
    return rc or (0 if out.is_file() else 1)


if __name__ == "__main__":
    raise SystemExit(main())
