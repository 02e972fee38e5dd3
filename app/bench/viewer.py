"""``scanlight bench viewer``: how long the viewer takes to show a converged picture (issue 19:
"a converged frame <= 3 s after an orbit, a BRDF slider change converged <= 1 s").

The viewer's own engine (app/ui/engine.py: the same progressive GI, tiles, idle passes and
caches as the window) drives the demo scene offscreen at the window tests' size, frame after
frame at the viewer's frame budget, the way the window's loop does. Per quality preset:

* ``orbit``: from a converged close-up, one interactive frame with the camera turned (what a
  drag does), then idle frames until the refinement reaches 100% (every idle pass included);
  the time is from the camera's release to that frame;
* one row per BRDF slider: the material changed as the BRDF panel changes it
  (``Session.set_material``), then idle frames until converged. Base colour, metallic,
  specular, sheen and the clearcoat amount recombine the layer's gather in parts
  (app/pbgi/gather_parts.py) when the micro-buffers it was gathered with serve the new material
  too; the rest (roughness, a clearcoat turned on, ...) gather again. "recombined" says which,
  with the engine's reason when not.

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
    ("specular", 0.8),
    ("sheen", 0.5),
    ("roughness", 0.35),
    ("clearcoat", 0.5),
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
    """Frames until the GI refinement is done; the first frame ``interacting`` when asked. Then
    on until the scan shows the asset's shadow and bounce for the change (``shadow_s``, from the
    same start; NaN when not within the timeout)."""
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
                    "converged": False, "shadow_s": float("nan")}
        engine.frame()
        frames += 1
    out = {"s": time.perf_counter() - t0, "frames": frames, "first_ms": first_ms,
           "converged": True, "shadow_s": float("nan")}
    settled = getattr(engine, "differential_settled", lambda: True)
    while time.perf_counter() - t0 <= timeout_s:
        if settled():
            out["shadow_s"] = time.perf_counter() - t0
            break
        engine.frame()
    return out


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
                if not (res["converged"] and res["shadow_s"] == res["shadow_s"]):
                    engine.finish_refinement()      # each change from a converged picture
                session.set_material(0, {name: table[name]})
                res = converge(engine, args.timeout)
                res["recombined"] = engine.material_edit == "recombined"
                records.append(record("viewer", {**case, "change": name,
                                                 "edit": str(engine.material_edit)}, res))
            log.info("%s: first picture %.1f s", preset, start["s"])
        finally:
            engine.release()
    print(markdown(records))
    return records


def markdown(records: list[dict]) -> str:
    lines = ["| preset | change | converged s | with the scan's shadow s | first frame ms | "
             "frames | recombined |", "|---|---|---|---|---|---|---|"]
    for rec in records:
        c, m = rec["case"], rec["metrics"]
        s = f"{m['s']:.2f}" if m["converged"] else "not converged"
        reuse = "" if "recombined" not in m else (
            "yes" if m["recombined"] else f"no ({c.get('edit', '')})")
        shadow = m.get("shadow_s", float("nan"))
        shadow = f"{shadow:.2f}" if shadow == shadow else "-"
        lines.append(f"| {c['preset']} | {c['change']} | {s} | {shadow} | {m['first_ms']:.0f} | "
                     f"{m['frames']:.0f} | {reuse} |")
    return "\n".join(lines)


__all__ = ["add_arguments", "run", "converge", "markdown"]
