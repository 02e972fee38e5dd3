"""The demo opens lit by its room's HDR light, not by the clipped LDR scan.

A newcomer's first picture used to be the asset lit by the LDR scan (a flat, dim disc), and the
HDR light appeared only after an expansion they did not know to run. So when the session is the
untouched demo (built-in room and photo, capture cameras, no HDR cloud yet), the viewer runs the
demo's own expansion at start: from the cache when an earlier start computed it
(app/demo/cache.py, keyed by the inputs and the expansion code), else as an ordinary background
job whose result switches the view to HDR and says so. Offscreen runs compute it before the
first frame, so their screenshots never depend on timing.
"""

from __future__ import annotations

from app.hdr.job import ExpandRequest
from app.settings import Session

STARTED = "Demo room: expanding the scan's HDR light in the background; the view switches to " \
          "it when it is ready"
LOADED = "Demo room: lit by its HDR-expanded light (the expansion's saved result)"
READY = "Demo room: the HDR light is ready; now showing the HDR-expanded room"


def wants_demo_light(session: Session, engine) -> bool:
    """The untouched demo: the built-in room and photo, capture cameras, no HDR cloud."""
    return (session.cloud == "demo" and session.photo == "demo" and not session.hdr_cloud
            and bool(session.capture_cameras) and engine.cloud is not None
            and engine.cloud.hdr is None and engine.photo is not None)


def demo_request(session: Session, engine) -> ExpandRequest:
    return ExpandRequest.from_settings(engine.cloud.ldr, engine.photo,
                                       [c.position for c in session.capture_cameras],
                                       session.settings)


def cached_result(request: ExpandRequest):
    from app.demo.cache import load_demo_expansion
    return load_demo_expansion(request)


def remember(request: ExpandRequest, result) -> None:
    from app.demo.cache import store_demo_expansion
    store_demo_expansion(request, result)


def expand_now(session: Session, engine) -> str | None:
    """Offscreen: the demo's HDR light before the first frame (cached, or computed here and
    kept); the message to show, or None when the session is not the untouched demo."""
    from app.ui.hdr_task import ExpansionTask
    if not wants_demo_light(session, engine):
        return None
    req = demo_request(session, engine)
    result = cached_result(req)
    said = LOADED
    if result is None:
        task = ExpansionTask(req, synchronous=True)
        if task.state != "done":
            return f"Demo room: the HDR expansion failed ({task.error}); lit by the LDR scan"
        result, said = task.result, READY
        remember(req, result)
    engine.set_hdr_cloud(result.cloud, None)
    return said
