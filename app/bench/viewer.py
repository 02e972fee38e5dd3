"""``scanlight bench viewer``: how long the viewer takes to show a converged picture (issue 19:
"a converged frame <= 3 s after an orbit, a BRDF slider change converged <= 1 s").

The viewer's own engine (app/ui/engine.py: the same progressive GI, tiles, idle passes and
caches as the window) drives the demo scene offscreen at the window tests' size, frame after
frame at the viewer's frame budget, the way the window's loop does. Per quality preset:

* ``orbit``: from a converged close-up, one interactive frame with the camera turned (what a
  drag does), then idle frames until the refinement reaches 100% (every idle pass included);
  the time is from the camera's release to that frame;
* one row per BRDF slider: the material changed as the BRDF panel changes it
  (``Session.set_material``), then idle frames until converged. Base colour, metallic and the
  other factors of the gather reuse the held micro-buffers (only the gather runs again); the
  roughness of a glossy material needs new lobe buffers.

"first ms" is the first frame after the change (what the user waits for before anything moves);
"frames" the frames to convergence. The machine is shared: compare rows of one run only.
"""

from __future__ import annotations

import logging
import time

from app.bench.records import record

log = logging.getLogger(__name__)

PRESETS = ("preview", "balanced", "final")
# the slider changes timed, in order; each value differs from the one before it
SLIDERS = (
    ("base_color", (0.3, 0.6, 0.9)),
    ("metallic", 1.0),
    ("roughness", 0.35),
    ("specular", 0.8),
    ("clearcoat", 0.5),
    ("sheen", 0.5),
)


def _size(text: str) -> tuple[int, int]:
    import argparse
    try:
        w, h = (int(v) for v in str(text).lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT, got {text!r}") from None
    if not (16 <= w <= 4096 and 16 <= h <= 4096):
        raise argparse.ArgumentTypeError(f"size out of range: {text!r}")
    return w, h


def add_arguments(parser) -> None:
    parser.add_argument("--size", type=_size, default=(1280, 800),
                        help="viewer size WIDTHxHEIGHT (default 1280x800: the window tests')")
    parser.add_argument("--presets", default=",".join(PRESETS),
                        help="comma-separated quality presets (default all)")
    parser.add_argument("--sliders", default=",".join(name for name, _ in SLIDERS),
                        help="comma-separated BRDF sliders to time (default all; '' none)")
    parser.add_argument("--view", choices=("closeup", "whole"), default="closeup")
    parser.add_argument("--timeout", type=float, default=300.0,
                        help="seconds one convergence may take before it is reported as such")


def converge(engine, timeout_s: float, interacting_first: bool = False) -> dict:
    """Frames until the GI refinement is done; the first frame ``interacting`` when asked."""
    t0 = time.perf_counter()
    first = engine.frame(interacting=interacting_first)
    first_ms = first["ms"]
    if interacting_first:                     # the release: the clock starts here
        t0 = time.perf_counter()
        first_ms = engine.frame()["ms"]
    frames = 1
    while engine.gi.refining:
        if time.perf_counter() - t0 > timeout_s:
            return {"s": float("nan"), "frames": frames, "first_ms": first_ms,
                    "converged": False}
        engine.frame()
        frames += 1
    return {"s": time.perf_counter() - t0, "frames": frames, "first_ms": first_ms,
            "converged": True}


def run(args) -> list[dict]:
    from app.demo.room import default_views
    from app.errors import UsageError
    from app.pbgi.renderer import Relighter
    from app.render.context import get_context
    from app.ui.engine import ViewerEngine, default_session
    from app.params import QUALITY_PRESETS
    presets = [p.strip() for p in args.presets.split(",") if p.strip()]
    bad = [p for p in presets if p not in QUALITY_PRESETS]
    if bad or not presets:
        raise UsageError(None, f"--presets: unknown {', '.join(bad) or 'empty list'} "
                               f"(known: {', '.join(QUALITY_PRESETS)})")
    names = [n.strip() for n in args.sliders.split(",") if n.strip()]
    table = dict(SLIDERS)
    bad = [n for n in names if n not in table]
    if bad:
        raise UsageError(None, f"--sliders: unknown {', '.join(bad)} (known: {', '.join(table)})")
    w, h = args.size
    ctx = get_context()
    records = []
    for preset in presets:
        session = default_session()
        session.camera = default_views(w, h)[args.view]
        session.settings.set("pbgi.quality", preset)
        session.settings.take_changes()
        engine = ViewerEngine(ctx, session, size=(w, h), relighter=Relighter)
        try:
            start = converge(engine, args.timeout)          # compile, caches, first picture
            case = {"preset": preset, "size": f"{w}x{h}", "view": args.view}
            engine.nav.orbit(40.0, 0.0)                     # a short drag
            res = converge(engine, args.timeout, interacting_first=True)
            records.append(record("viewer", {**case, "change": "orbit"}, res))
            for name in names:
                session.set_material(0, {name: table[name]})
                res = converge(engine, args.timeout)
                res["reused_microbuffers"] = bool(getattr(engine.gi_stats, "reused_microbuffers",
                                                          False))
                records.append(record("viewer", {**case, "change": name}, res))
            log.info("%s: first picture %.1f s", preset, start["s"])
        finally:
            engine.release()
    print(markdown(records))
    return records


def markdown(records: list[dict]) -> str:
    lines = ["| preset | change | converged s | first frame ms | frames | gather only |",
             "|---|---|---|---|---|---|"]
    for rec in records:
        c, m = rec["case"], rec["metrics"]
        s = f"{m['s']:.2f}" if m["converged"] else "not converged"
        reuse = "" if "reused_microbuffers" not in m else ("yes" if m["reused_microbuffers"]
                                                           else "no")
        lines.append(f"| {c['preset']} | {c['change']} | {s} | {m['first_ms']:.0f} | "
                     f"{m['frames']} | {reuse} |")
    return "\n".join(lines)


__all__ = ["add_arguments", "run", "converge", "markdown"]
