"""``scanlight bench classic``: Classic PBGI on the demo scene, viewport x micro-buffer x view.

Per case: ``ms`` (one frame: G-buffer, cut, gather; GPU work timed with ctx.finish()), ``mb``
(extra GPU memory of the frame), ``micropixels_per_s`` (receivers x M^2 per second), and
``nodes_visited`` (mean per receiver). The minimum over ``--repeat`` runs is kept (a shared
machine only ever makes a run slower). Later modes (Mipmapped/Hybrid, ``bench table3``) are
compared against these numbers in the same run, so the case keys are shared: case.mode,
case.viewport, case.microbuffer, case.view.
"""

from __future__ import annotations

import logging

from app.bench.arguments import int_list
from app.bench.records import record
from app.commands.options import add_param_options, param_values
from app.errors import UsageError

log = logging.getLogger(__name__)

VIEWPORTS = (128, 256, 512)
MICROBUFFERS = (16, 24, 32)
VIEWS = ("closeup", "whole")


def add_arguments(parser) -> None:
    parser.add_argument("--viewports", type=int_list, default=list(VIEWPORTS),
                        help="comma-separated square viewport sizes (default 128,256,512)")
    parser.add_argument("--microbuffers", type=int_list, default=list(MICROBUFFERS),
                        help="comma-separated micro-buffer sizes (default 16,24,32)")
    parser.add_argument("--views", default=",".join(VIEWS), help="closeup,whole (default both)")
    parser.add_argument("--modes", default="classic", help="classic and/or envmap")
    parser.add_argument("--repeat", type=int, default=1, help="runs per case, the fastest kept")
    parser.add_argument("--points", type=int, default=200_000, help="points in the demo room")
    add_param_options(parser, "bench classic")   # --budget-mb


def run(args) -> list[dict]:
    from app.demo.cache import load_demo
    from app.demo.room import default_object, default_views
    from app.io.formats import object_from_dict, placed_mesh
    from app.material import Material
    from app.params import BY_KEY, RENDER_MODES
    from app.pbgi.renderer import Relighter, RenderParams

    viewports, sizes = args.viewports, args.microbuffers
    views = [v.strip() for v in args.views.split(",") if v.strip()]
    modes = [v.strip() for v in args.modes.split(",") if v.strip()]
    if any(v not in VIEWS for v in views) or not views:
        raise UsageError(None, f"--views must be among {', '.join(VIEWS)}, got {args.views!r}")
    if any(m not in RENDER_MODES for m in modes) or not modes:
        raise UsageError(None, f"--modes must be among {', '.join(RENDER_MODES)}, "
                               f"got {args.modes!r}")
    m_param = BY_KEY["pbgi.microbuffer"]
    if any(not m_param.lo <= m <= m_param.hi for m in sizes):
        raise UsageError(None, f"--microbuffers must be in [{m_param.range_text()}]")
    if any(not 1 <= v <= 4096 for v in viewports):
        raise UsageError(None, "--viewports must be in [1, 4096]")
    if args.repeat < 1:
        raise UsageError(None, "--repeat must be >= 1")

    budget = param_values(args, "bench classic")["pbgi.memory_budget_mb"]

    scene = load_demo(args.points)
    r = Relighter()
    r.set_cloud(scene.gt)
    r.set_asset(placed_mesh(object_from_dict(default_object("sphere"), ".")))
    material = Material(base_color=(0.8, 0.8, 0.8), roughness=0.5)
    for m in sizes:                       # compile and warm every program before timing
        r.render(default_views(16, 16)["closeup"], [material], RenderParams(microbuffer=m))

    records = []
    for mode in modes:
        for vp in viewports:
            for m in sizes:
                for view in views:
                    cam = default_views(vp, vp)[view]
                    best = None
                    for _ in range(args.repeat):
                        r.forget_microbuffers()   # time the whole frame, never a reuse
                        res = r.render(cam, [material], RenderParams(
                            mode=mode, microbuffer=m, memory_budget_mb=budget))
                        if best is None or res.stats.ms < best.ms:
                            best = res.stats
                    s = best
                    mps = s.receivers * m * m / max(s.ms / 1e3, 1e-9)
                    rec = record("classic", {"mode": mode, "viewport": vp, "microbuffer": m,
                                             "view": view},
                                 {"ms": s.ms, "mb": s.mb, "micropixels_per_s": mps,
                                  "receivers": s.receivers, "nodes_visited": s.nodes_visited,
                                  "ms_cut": s.ms_cut, "ms_gather": s.ms_gather,
                                  "batches": s.batches, "completed": float(s.completed)})
                    log.info("%s %d M=%d %s: %.0f ms", mode, vp, m, view, s.ms)
                    records.append(rec)
    r.release()
    return records
