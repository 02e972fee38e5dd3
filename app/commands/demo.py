"""``scanlight demo``: the whole pipeline, headless, on the built-in demo scene."""

from __future__ import annotations

import logging
import time
from pathlib import Path

from app.io.files import write_json

log = logging.getLogger(__name__)


def add_arguments(parser) -> None:
    from app.commands.options import add_param_options
    from app.demo.pipeline import DEFAULT_SIZE
    parser.add_argument("--out", default="scanlight-demo", help="output folder (created)")
    parser.add_argument("--size", type=int, default=DEFAULT_SIZE,
                        help=f"image size (square) of the renders (default {DEFAULT_SIZE})")
    parser.add_argument("--points", type=int, default=200_000, help="points in the demo room")
    add_param_options(parser, "demo")


def run(args) -> int:
    from app.commands.options import param_values
    from app.demo import pipeline
    out = Path(getattr(args, "out", "scanlight-demo"))
    size = getattr(args, "demo_size", None) or args.size  # `view` falls back here with its own args
    tonemapper = param_values(args, "demo")["view.tonemap"]   # `view`'s args: the default
    t0 = time.perf_counter()
    report = pipeline.run_demo(out, size=size, n_points=getattr(args, "points", 200_000),
                               tonemapper=tonemapper)
    report["seconds_total"] = round(time.perf_counter() - t0, 2)
    write_json(out / "report.json", report)
    print(f"demo done in {report['seconds_total']} s: images, contact_sheet.png and report.json "
          f"in {out}/ (PNGs tone-mapped with {report['tonemapper']})")
    for line in report.get("summary", []):
        print("  " + line)
    return 0
