"""``scanlight bench profile``: where a frame's time goes, per mode and material, so that a change
is judged by its effect on the part it targets (issue 19: "build what the profile says").

Parts, from each render's own timers (app/pbgi/stats.py, every one measured between
``ctx.finish()`` calls, so a part is the GPU work it names):

* ``gbuffer``: rasterising the asset and compacting its receivers;
* ``cut``: the hierarchy walk and the rasterisation of the accepted nodes into the micro-buffers;
  for Hybrid its far-field block walks and the per-receiver near field (``far`` / ``near``);
* ``lobe``: the glossy receivers' importance-warped micro-buffers and their ray casts
  (app/pbgi/lobe.py), zero for a rough material;
* ``gather``: the final gather with the BRDF;
* ``other``: the rest of ``ms`` (buffer set-up, read-back).

Hybrid chooses its blocks on the host before the cut's timer starts (CutFinder.begin_group,
``ShareFigures.ms_share_chosen_before``); the profile moves that time from ``other`` to the
sharing (below), where it belongs.

The walk and the rasterisation are one shader pass per batch, so a timer cannot split them;
each cell is also rendered by a second Relighter whose walks rasterise and ray cast nothing
(``Relighter.walks_only``: the same walks, the same visits, empty micro-buffers), interleaved
with the real one. Its cut and lobe times are the walks' (``walk``, ``lobe_walk``; Hybrid's
``far_walk`` / ``near_walk``), and the rest of the real render's is the rasterisation
(``raster``; ``far_raster`` / ``near_raster``) and the lobe's ray casts (``lobe_cast``):
differences of two fastest-of-n timings, so noisy to a few ms, and clamped at zero. Hybrid's
cut also holds the sharing itself (``share``: the blocks' levels, and copying each block's
micro-buffer into its receivers', ``merge``, timed apart by the far field), which is neither
walk nor raster; ``share`` adds the blocks' choice (``choose``), made before the cut.

Node visits and micro-buffer entry tests per receiver are the walks' own counts (means; the
lobe walk's separately, over all receivers). ``floor_ms`` is
what those visits cost at the plain per-pixel walk's rate the guide measured on this machine
(FLOOR_VISITS_PER_S), i.e. how far the cut is from a walk that does nothing but visit nodes.
That rate is llvmpipe's on two cores: on any other GL renderer (a GPU) the floor is not known,
and the record has NaN there.
Every mode runs on the same demo scene in one run, interleaved, the fastest of ``--repeat``
renders per cell (the machine is shared and noisy: ratios within one run only).
"""

from __future__ import annotations

import logging

from app.bench.records import record
from app.commands.options import add_param_options, param_values

log = logging.getLogger(__name__)

MODES = ("classic", "mipmapped", "hybrid", "envmap")
FLOOR_VISITS_PER_S = 100e6    # a plain GLSL per-pixel walk of a 200k-point hierarchy here
MATERIALS = {
    "diffuse": dict(base_color=(0.8, 0.8, 0.8), roughness=0.5),
    "glossy": dict(base_color=(1.0, 0.78, 0.34), roughness=0.25, metallic=1.0),
}


def _names(allowed):
    def parse(text: str) -> list[str]:
        out = [t.strip() for t in str(text).split(",") if t.strip()]
        bad = [t for t in out if t not in allowed]
        if bad or not out:
            import argparse
            raise argparse.ArgumentTypeError(f"unknown {', '.join(bad) or 'empty list'} "
                                             f"(known: {', '.join(allowed)})")
        return out
    return parse


def add_arguments(parser) -> None:
    parser.add_argument("--viewport", type=int, default=128, help="square viewport (default 128)")
    parser.add_argument("--view", choices=("closeup", "whole"), default="closeup")
    parser.add_argument("--modes", type=_names(MODES), default=list(MODES),
                        help="comma-separated modes (default all)")
    parser.add_argument("--materials", type=_names(tuple(MATERIALS)), default=list(MATERIALS),
                        help="comma-separated: diffuse, glossy (default both)")
    parser.add_argument("--repeat", type=int, default=3,
                        help="renders per cell; the fastest counts (default 3)")
    parser.add_argument("--points", type=int, default=200_000, help="points of the demo room")
    from app.pbgi.lobe import LOBE_TUNINGS
    parser.add_argument("--lobe-tuning", choices=("auto", *LOBE_TUNINGS), default="auto",
                        help="the lobe walk's private-memory tuning (app/pbgi/lobe.py: "
                             "LobeWalkTuning): auto = the GL renderer's own (default)")
    add_param_options(parser, "bench profile")     # --microbuffer: the table's


def parts(s, walks=None, floor: bool = True) -> dict:
    """ms per part of one render's RenderStats (module docstring), and the walk's figures;
    ``walks``: the same cell's RenderStats with Relighter.walks_only (the walk / raster
    split); ``floor``: the renderer is the one FLOOR_VISITS_PER_S was measured on."""
    out = {"ms": s.ms, "gbuffer_ms": s.ms_gbuffer, "cut_ms": s.ms_cut, "lobe_ms": s.ms_lobe,
           "gather_ms": s.ms_gather}
    chosen = 0.0                        # Hybrid's blocks, chosen before the cut's timer
    if s.share is not None:
        out["far_ms"], out["near_ms"] = s.share.ms_share_far, s.share.ms_share_near
        out["levels_ms"] = s.share.ms_share_levels
        out["merge_ms"] = s.share.ms_share_merge
        out["choose_ms"] = chosen = s.share.ms_share_chosen_before
    out["other_ms"] = max(s.ms - s.ms_gbuffer - s.ms_cut - s.ms_lobe - s.ms_gather - chosen,
                          0.0)
    out["receivers"] = s.receivers
    out["visits_per_receiver"] = float(s.nodes_visited)
    out["tests_per_receiver"] = float(s.splat_tests or 0.0)
    out["lobe_visits_per_receiver"] = float(s.lobe_visited)
    out["lobe_tests_per_receiver"] = float(s.lobe_tests)
    visits = float(s.nodes_visited) * s.receivers
    out["floor_ms"] = visits / FLOOR_VISITS_PER_S * 1e3 if floor else float("nan")
    out["cut_over_floor"] = s.ms_cut / out["floor_ms"] if out["floor_ms"] > 0 else float("nan")
    if walks is not None:
        out["walk_ms"], out["lobe_walk_ms"] = walks.ms_cut, walks.ms_lobe
        out["raster_ms"] = max(s.ms_cut - walks.ms_cut, 0.0)
        out["lobe_cast_ms"] = max(s.ms_lobe - walks.ms_lobe, 0.0)
        if s.share is not None and walks.share is not None:
            # the far part also copies the blocks' rows into their receivers' (merge_ms), the
            # same work in both renders: neither walk nor raster
            w = walks.share
            out["far_walk_ms"] = max(w.ms_share_far - w.ms_share_merge, 0.0)
            out["far_raster_ms"] = max(s.share.ms_share_far - s.share.ms_share_merge
                                       - out["far_walk_ms"], 0.0)
            out["near_walk_ms"] = w.ms_share_near
            out["near_raster_ms"] = max(s.share.ms_share_near - w.ms_share_near, 0.0)
            out["walk_ms"] = out["far_walk_ms"] + out["near_walk_ms"]
            out["raster_ms"] = out["far_raster_ms"] + out["near_raster_ms"]
        # Hybrid's sharing itself: choosing the blocks, their levels, the copies
        out["share_ms"] = max(s.ms_cut - out["walk_ms"] - out["raster_ms"], 0.0) + chosen
        out["walk_over_floor"] = (out["walk_ms"] / out["floor_ms"] if out["floor_ms"] > 0
                                  else float("nan"))
        out["walk_visits_per_receiver"] = float(walks.nodes_visited)
        out["walk_lobe_visits_per_receiver"] = float(walks.lobe_visited)
    return out


def run(args) -> list[dict]:
    from app.bench.table3 import setup
    from app.demo.room import default_views
    from app.material import Material
    from app.pbgi.lobe import LOBE_TUNINGS, tuning_name
    from app.pbgi.renderer import RenderParams
    from app.render.context import is_software_renderer
    args.microbuffer = int(param_values(args, "bench profile")["pbgi.microbuffer"])
    r, rw = setup(args.points), setup(args.points)
    floor = is_software_renderer(r.ctx.info.get("GL_RENDERER", ""))
    rw.walks_only = True                          # the walks alone (module docstring)
    if args.lobe_tuning != "auto":
        r.lobe_tuning = rw.lobe_tuning = LOBE_TUNINGS[args.lobe_tuning]
    cam = default_views(args.viewport, args.viewport)[args.view]
    warm = default_views(16, 16)[args.view]
    mats = {name: Material(**kw) for name, kw in MATERIALS.items() if name in args.materials}
    params = {mode: RenderParams(mode=mode, microbuffer=args.microbuffer) for mode in args.modes}
    for mode in args.modes:                       # compile and JIT every variant first
        for mat in mats.values():
            for rel in (r, rw):
                rel.render(warm, [mat], params[mode])
    best: dict = {}
    for _ in range(max(1, args.repeat)):
        for name, mat in mats.items():
            for mode in args.modes:               # interleaved: the same conditions for all
                for rel in (r, rw):
                    rel.forget_microbuffers()
                    st = rel.render(cam, [mat], params[mode]).stats
                    key = (mode, name, rel is rw)
                    if key not in best or st.ms < best[key].ms:
                        best[key] = st
    for rel in (r, rw):
        rel.release()
    tuning = tuning_name(r.lobe_tuning)
    records = [record("profile", {"mode": mode, "material": name, "viewport": args.viewport,
                                  "microbuffer": args.microbuffer, "view": args.view,
                                  "lobe_tuning": tuning},
                      parts(best[(mode, name, False)], best[(mode, name, True)], floor))
               for name in mats for mode in args.modes]
    print(markdown(records))
    return records


def _num(v: float) -> str:
    return "-" if v != v else f"{v:.1f}"        # NaN: no floor on this renderer


def markdown(records: list[dict]) -> str:
    head = ("| mode | material | ms | G-buffer | walk | raster | sharing | lobe walk | "
            "lobe ray casts | gather | other | visits / receiver | entry tests / receiver | "
            "lobe visits, tests / receiver | floor ms | walk / floor |")
    lines = [head, "|" + "---|" * 16]
    noisy = False
    for rec in records:
        c, m = rec["case"], rec["metrics"]
        pct = (lambda k: f"{m[k]:.0f} ({100 * m[k] / m['ms']:.0f}%)" if m["ms"] > 0 else "-")
        walk, raster, share = pct("walk_ms"), pct("raster_ms"), pct("share_ms")
        if (m["walk_ms"] > 1.05 * m["cut_ms"] + 1.0
                or m["lobe_walk_ms"] > 1.05 * m["lobe_ms"] + 1.0):
            walk += " (!)"            # the walks alone took longer than the whole render
            noisy = True
        if "far_walk_ms" in m:
            walk += f" [far {m['far_walk_ms']:.0f}, near {m['near_walk_ms']:.0f}]"
            raster += f" [far {m['far_raster_ms']:.0f}, near {m['near_raster_ms']:.0f}]"
            share += (f" [choice {m['choose_ms']:.0f}, copies {m['merge_ms']:.0f}, "
                      f"levels {m['levels_ms']:.0f}]")
        lines.append(f"| {c['mode']} | {c['material']} | {m['ms']:.0f} | {pct('gbuffer_ms')} | "
                     f"{walk} | {raster} | {share} | {pct('lobe_walk_ms')} | "
                     f"{pct('lobe_cast_ms')} | "
                     f"{pct('gather_ms')} | {pct('other_ms')} | "
                     f"{m['visits_per_receiver']:.0f} | {m['tests_per_receiver']:.0f} | "
                     f"{m['lobe_visits_per_receiver']:.0f}, {m['lobe_tests_per_receiver']:.0f} | "
                     f"{_num(m['floor_ms'])} | {_num(m['walk_over_floor'])} |")
    if noisy:
        lines.append("\n(!) the walks-only render took longer than the whole one: the machine's "
                     "noise or a first render at this size; a larger --repeat settles it.")
    return "\n".join(lines)


__all__ = ["add_arguments", "run", "parts", "markdown", "FLOOR_VISITS_PER_S"]
