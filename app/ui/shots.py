"""What a screenshot may be written over: never a file the viewer reads.

``view --screenshot`` (and the EXR beside it) and ``viewer.save_window_png`` (a --script's
screenshots) are checked the same way - a script had written the window over the scan it had
open. Its own module so that the window (app/ui/window.py) and the offscreen viewer
(app/ui/app.py) share it without importing each other.
"""

from __future__ import annotations

from pathlib import Path

from app.errors import ScanlightError
from app.settings import Session


def check_screenshot(shot: str, session: Session, paths) -> None:
    """--screenshot and the EXR written beside it name no file the viewer reads (the session, its
    cloud, photo or asset, the script: a session photo.exr was overwritten by photo.png's EXR),
    no folder and no special file (app.io.outputs.check_outputs)."""
    from app.io.outputs import check_outputs
    ins = [session.path, session.cloud, session.photo, session.hdr_cloud, session.asset,
           session.hdri, *paths]
    names = ("--session", "the session's cloud", "the session's photo", "the session's HDR cloud",
             "the session's asset", "the session's HDRI", "CLOUD", "ASSET", "--script")
    inputs = {n: str(p) for n, p in zip(names, ins) if p and Path(str(p)).exists()}
    check_outputs(inputs, {"--screenshot": shot,
                           "--screenshot's EXR": str(Path(shot).with_suffix(".exr"))})


def save_png(path, image, session: Session) -> None:
    """``viewer.save_window_png`` (a --script's screenshots): the same checks as --screenshot - a
    .png name, none of the files the viewer reads - then the PNG (a script had written the
    window over the scan it had open; the script is code and can still write anything itself,
    but this call does not overwrite an input by mistake)."""
    from app.io.images import write_png
    if Path(str(path)).suffix.lower() != ".png":
        raise ScanlightError(path, "save_window_png writes a PNG: give a .png name")
    check_screenshot(str(path), session, [])
    write_png(path, image)
