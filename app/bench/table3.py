"""``scanlight bench table3``: the paper's Table 3 on the demo scene - Classic, Mipmapped and
Hybrid PBGI, time (ms) and extra memory (MB) per viewport x micro-buffer x view.

All modes are measured in the SAME run, cell by cell (for each viewport, micro-buffer and view the
modes run one after the other on the same G-buffer input), so their ratios are comparable even
on a shared machine; ``--repeat`` keeps the fastest of several renders per mode and cell.
Shaders are compiled and JIT-warmed on a tiny render of every mode and micro-buffer size first
(llvmpipe compiles a shader variant on its first dispatch).

Records (app/bench/records.py), keyed like ``bench classic``: case.mode, case.viewport,
case.microbuffer, case.view (closeup / whole); metrics.ms (the whole render: G-buffer, cut,
gather, measured with ctx.finish()), metrics.mb (the mode's *extra* memory: what the cut finder
allocates besides the micro-buffers, the G-buffer and the BSH, which every mode shares - the
paper's Table 3 bottom; for Classic its resume state), plus ms_cut, ms_gather, mb_total,
completed, batches, tile_halvings, nodes_visited, the accuracy side of the trade when Classic ran
in the same cell (diff_mean_pct / diff_p99_pct: per-pixel relative difference to Classic's image,
and mean_ratio), for Mipmapped and the exact Hybrid the pair counts, the phases' times and
mb_extra_used (the part of the pair streams actually filled), for the default Hybrid the far-field
sharing's blocks and times (every figure: app/pbgi/stats.py). After the plain table it prints the
markdown table laid out like the paper's (one block per mode, rows = viewports, columns = view x
micro-buffer), the classic/hybrid ratio per cell and the memory blocks.

The full grid (4 viewports x 3 micro-buffers x 2 views x 3 modes) takes a long time on a CPU:
restrict it with --viewports / --microbuffers / --views / --modes.
"""

from __future__ import annotations

import logging
import time

import numpy as np

from app.bench.arguments import int_list
from app.bench.records import record
from app.commands.options import add_param_options, param_values

log = logging.getLogger(__name__)

ALL_MODES = ("classic", "mipmapped", "hybrid")
ALL_VIEWS = ("closeup", "whole")
PAPER_TABLE3 = {
    # TOYROOM, ms: (view1 16/24/32, view2 16/24/32) per viewport; None = 'x' (failed)
    "classic": {128: (9.7, 21.3, 35.2, 7.5, 16.7, 27.0), 256: (37.8, 85.1, 254.5, 15.6, 35.2, 81.2),
                512: (138.9, 598.0, 3272.0, 41.1, 173.5, 920.6),
                1024: (752.0, None, None, 306.2, None, None)},
    "mipmapped": {128: (15.2, 31.2, 51.9, 9.9, 16.4, 24.8), 256: (40.0, 88.0, 151.0, 22.6, 47.9, 77.9),
                  512: (131.1, 293.0, 565.2, 64.5, 148.4, 281.6),
                  1024: (604.6, None, None, 244.7, None, None)},
    "hybrid": {128: (9.1, 13.3, 24.7, 6.5, 8.8, 11.5), 256: (19.3, 41.4, 82.3, 9.9, 16.9, 29.8),
               512: (62.1, 156.7, 316.2, 24.2, 53.1, 108.5),
               1024: (285.3, None, None, 115.8, None, None)},
    # MB of the transform-feedback buffers
    "mb_mipmapped": {128: (10, 16, 27, 4, 6, 11), 256: (38, 55, 90, 15, 24, 39),
                     512: (146, 206, 325, 50, 81, 135), 1024: (756, None, None, 183, None, None)},
    "mb_hybrid": {128: (5, 10, 19, 1, 2, 4), 256: (22, 39, 76, 4, 8, 15),
                  512: (89, 158, 306, 18, 32, 61), 1024: (356, None, None, 71, None, None)},
}


def _names(allowed):
    def parse(text: str) -> list[str]:
        out = [t.strip() for t in str(text).split(",") if t.strip()]
        bad = [t for t in out if t not in allowed]
        if bad:
            import argparse
            raise argparse.ArgumentTypeError(f"unknown {', '.join(bad)} (known: {', '.join(allowed)})")
        return out
    return parse


def add_arguments(parser) -> None:
    parser.add_argument("--viewports", type=int_list, default=[128, 256, 512, 1024],
                        help="comma-separated square viewport sizes (default 128,256,512,1024)")
    parser.add_argument("--microbuffers", type=int_list, default=[16, 24, 32],
                        help="comma-separated micro-buffer sizes (default 16,24,32)")
    parser.add_argument("--views", type=_names(ALL_VIEWS), default=list(ALL_VIEWS),
                        help="comma-separated views: closeup, whole (default both)")
    parser.add_argument("--modes", type=_names(ALL_MODES), default=list(ALL_MODES),
                        help="comma-separated modes (default classic,mipmapped,hybrid)")
    parser.add_argument("--repeat", type=int, default=1, help="renders per mode and cell; the fastest counts")
    add_param_options(parser, "bench table3")   # --budget-mb, --omega-tr-factor, ...
    parser.add_argument("--points", type=int, default=200_000, help="points of the demo room")
    parser.add_argument("--object", default="sphere", help="demo object: sphere or knot")
    parser.add_argument("--markdown", metavar="PATH", help="also write the markdown table here")


def setup(points: int = 200_000, kind: str = "sphere"):
    """Relighter with the demo room and object (BSH built once: mode switches never rebuild)."""
    from app.demo.cache import load_demo
    from app.demo.room import default_object
    from app.io.formats import object_from_dict, placed_mesh
    from app.pbgi.renderer import Relighter
    scene = load_demo(points)
    r = Relighter()
    r.set_cloud(scene.gt)
    r.set_asset(placed_mesh(object_from_dict(default_object(kind), ".")))
    return r


def _material():
    from app.material import Material
    return Material(base_color=(0.8, 0.8, 0.8), roughness=0.5)


def _params(mode, m, args):
    """The cell's mode and micro-buffer; everything else from the command line, whose defaults
    are the parameter table's (the viewer's)."""
    from app.pbgi.renderer import RenderParams
    values = param_values(args, "bench table3")
    return RenderParams.from_settings({**RenderParams().to_settings(), **values},
                                      mode=mode, microbuffer=int(m))


def _render(r, cam, mode, m, args, cold: bool = False):
    """One render with the micro-buffer cache defeated (every repeat does the full work).
    ``cold``: Mipmapped's pair engine first frees what earlier cells allocated, so a cell's
    memory figure is its own (its buffers are reused across renders while big enough, and
    re-allocated on demand)."""
    r.forget_microbuffers()
    held = r.modes.get("mipmapped")
    if cold and held is not None:
        held.cut.release()
    return r.render(cam, [_material()], _params(mode, m, args))


def run(args) -> list[dict]:
    from app.demo.room import default_views
    r = setup(args.points, args.object)
    # warm-up: compile every shader variant on a tiny viewport
    for m in args.microbuffers:
        cam = default_views(16, 16)["closeup"]
        for mode in args.modes:
            _render(r, cam, mode, m, args)
    records = []
    for size in args.viewports:
        cams = default_views(size, size)
        for m in args.microbuffers:
            for view in args.views:
                best = {}
                for rep in range(max(1, args.repeat)):
                    for mode in args.modes:      # interleaved: the same conditions for all modes
                        t0 = time.perf_counter()
                        res = _render(r, cams[view], mode, m, args, cold=rep == 0)
                        wall = time.perf_counter() - t0
                        if mode not in best or res.stats.ms < best[mode][0].stats.ms:
                            best[mode] = (res, wall)
                for mode in args.modes:
                    res, wall = best[mode]
                    metrics = _metrics(res.stats, wall)
                    if "classic" in best:
                        metrics.update(difference(best["classic"][0].image, res.image))
                    records.append(record("table3", {"mode": mode, "viewport": size, "microbuffer": m,
                                                     "view": view}, metrics))
                log.info("table3 %dx%d M=%d %s: %s", size, size, m, view,
                         ", ".join(f"{k} {best[k][0].stats.ms:.0f} ms" for k in args.modes))
    text = markdown(records)
    print(text)
    if args.markdown:
        from pathlib import Path
        Path(args.markdown).write_text(text + "\n")
    return records


def difference(reference: np.ndarray, image: np.ndarray) -> dict:
    """How far a mode's image is from Classic's in the same cell (the accuracy side of the
    trade): per object pixel, |rgb - rgb_classic|_1 / |rgb_classic|_1; its mean and 99th
    percentile in percent, and the mean radiance ratio."""
    cover = reference[..., 3] > 0
    a = reference[..., :3][cover].astype(np.float64)
    b = image[..., :3][cover].astype(np.float64)
    if not len(a):
        return {}
    rel = np.abs(b - a).sum(1) / np.maximum(a.sum(1), 1e-12)
    return {"diff_mean_pct": 100.0 * float(rel.mean()),
            "diff_p99_pct": 100.0 * float(np.percentile(rel, 99)),
            "mean_ratio": float(b.mean() / max(a.mean(), 1e-30))}


def _metrics(s, wall: float) -> dict:
    """A record's metrics from a render's RenderStats (app/pbgi/stats.py)."""
    out = {"ms": s.ms, "mb": s.mb_extra or 0.0, "ms_cut": s.ms_cut, "ms_gather": s.ms_gather,
           "mb_total": s.mb, "completed": 1.0 if s.completed else 0.0, "batches": s.batches,
           "tile_halvings": s.tile_halvings or 0, "nodes_visited": s.nodes_visited,
           "receivers": s.receivers, "wall_s": wall}
    p, sh = s.pairs, s.share
    if p is not None:
        out.update(pairs_processed=p.pairs_processed, stream2_items=p.stream2_items,
                   refine_passes=p.refine_passes, flushes=p.flushes, ms_refine=p.ms_refine,
                   ms_finish=p.ms_finish, ms_pyramid=p.ms_pyramid,
                   mb_extra_used=p.mb_extra_used, peak_stack_pairs=p.peak_stack_pairs,
                   peak_stream2_items=p.peak_stream2_items)
    if sh is not None:
        out.update(share_blocks=sh.share_blocks, share_receivers=sh.share_receivers,
                   share_block_visits=sh.share_block_visits, ms_share_far=sh.ms_share_far,
                   ms_share_levels=sh.ms_share_levels, ms_share_near=sh.ms_share_near,
                   share_levelled=sh.share_levelled)
    if p is not None and s.receivers:
        out["walk_visited_per_receiver"] = p.walk_visited / s.receivers
    return out


def _cell(records, mode, size, m, view, key="ms"):
    for rec in records:
        c = rec["case"]
        if (c["mode"], c["viewport"], c["microbuffer"], c["view"]) == (mode, size, m, view):
            return rec["metrics"].get(key)
    return None


def _diff(records, mode, size, m, view) -> str:
    mean = _cell(records, mode, size, m, view, "diff_mean_pct")
    p99 = _cell(records, mode, size, m, view, "diff_p99_pct")
    return "-" if mean is None or p99 is None else f"{mean:.1f} / {p99:.1f}"


def _fmt(v) -> str:
    if v is None:
        return "-"
    if v >= 10000:
        return f"{v / 1000:.1f}k"
    return f"{v:.1f}" if v < 1000 else f"{v:.0f}"


def markdown(records: list[dict]) -> str:
    """The Table 3 layout: per mode a block of rows (viewports) x columns (view x micro-buffer)."""
    cases = [r["case"] for r in records]
    sizes = sorted({c["viewport"] for c in cases})
    mbs = sorted({c["microbuffer"] for c in cases})
    views = [v for v in ALL_VIEWS if v in {c["view"] for c in cases}]
    modes = [m for m in ALL_MODES if m in {c["mode"] for c in cases}]
    cols = [(v, m) for v in views for m in mbs]
    head = "| | " + " | ".join(f"{v} {m}x{m}" for v, m in cols) + " |"
    sep = "|---" * (len(cols) + 1) + "|"
    lines = []

    def block(title, fn):
        lines.extend([f"**{title}**", "", head, sep])
        for size in sizes:
            lines.append(f"| {size}x{size} | " + " | ".join(fn(size, v, m) for v, m in cols) + " |")
        lines.append("")

    for mode in modes:
        block(f"{mode} (ms)", lambda s, v, m, mode=mode: _fmt(_cell(records, mode, s, m, v)))
    if "classic" in modes and "hybrid" in modes:
        def ratio(s, v, m):
            c, h = _cell(records, "classic", s, m, v), _cell(records, "hybrid", s, m, v)
            return "-" if not c or not h else f"{c / h:.2f}"
        block("classic / hybrid (time ratio)", ratio)
    for mode in modes:
        if mode != "classic" and any("diff_mean_pct" in r["metrics"] for r in records
                                     if r["case"]["mode"] == mode):
            block(f"{mode} vs classic: mean / 99th-percentile per-pixel difference (%)",
                  lambda s, v, m, mode=mode: _diff(records, mode, s, m, v))
    for mode in modes:
        if mode != "classic":
            block(f"{mode} extra memory (MB)",
                  lambda s, v, m, mode=mode: _fmt(_cell(records, mode, s, m, v, "mb")))
    incomplete = [r["case"] for r in records if not r["metrics"].get("completed", 1.0)]
    lines.append(f"cells completed: {len(records) - len(incomplete)}/{len(records)}"
                 + ("" if not incomplete else f" (incomplete: {incomplete})"))
    return "\n".join(lines)


if __name__ == "__main__":  # python -m app.bench.table3 (the CLI is `scanlight bench table3`)
    import argparse

    from app.bench.records import table

    ap = argparse.ArgumentParser(description=__doc__)
    add_arguments(ap)
    print(table(run(ap.parse_args())))
