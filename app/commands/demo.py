"""``scanlight demo``: the whole pipeline, headless, on the built-in demo scene."""

from __future__ import annotations

import logging
import time
from pathlib import Path

from app.io.files import write_json

log = logging.getLogger(__name__)


def add_arguments(parser) -> None:
    from app.commands.options import add_param_options
    from app.demo.pipeline import DEFAULT_SIZE, POINTS_RANGE, SIZE_RANGE
    parser.add_argument("--out", default="scanlight-demo", help="output folder (created)")
    parser.add_argument("--size", type=int, default=DEFAULT_SIZE,
                        help=f"image size (square) of the renders (default {DEFAULT_SIZE}; "
                             f"{SIZE_RANGE[0]} .. {SIZE_RANGE[1]})")
    parser.add_argument("--points", type=int, default=200_000,
                        help=f"points in the demo room (default 200000; "
                             f"{POINTS_RANGE[0]} .. {POINTS_RANGE[1]})")
    add_param_options(parser, "demo")


def run(args) -> int:
    from app.commands.options import param_values
    from app.demo import pipeline
    from app.errors import UsageError
    from app.io.outputs import check_output_folder
    out = Path(getattr(args, "out", "scanlight-demo"))
    size = getattr(args, "demo_size", None) or args.size  # `view` falls back here with its own args
    n_points = getattr(args, "points", 200_000)
    for flag, value, (lo, hi) in (("--size", size, pipeline.SIZE_RANGE),
                                  ("--points", n_points, pipeline.POINTS_RANGE)):
        if not lo <= value <= hi:
            raise UsageError(None, f"{flag} must be {lo} .. {hi}, got {value}")
    check_output_folder(out, "--out")
    tonemapper = param_values(args, "demo")["view.tonemap"]   # `view`'s args: the default
    t0 = time.perf_counter()
    created = not out.exists()
    try:
        report = pipeline.run_demo(out, size=size, n_points=n_points, tonemapper=tonemapper)
        report["seconds_total"] = round(time.perf_counter() - t0, 2)
        write_json(out / "report.json", report)
    except BaseException:
        if created:
            _remove_if_empty(out)
        raise
    print(f"demo done in {report['seconds_total']} s: images, contact_sheet.png and report.json "
          f"in {out}/ (PNGs tone-mapped with {report['tonemapper']})")
    for line in report.get("summary", []):
        print("  " + line)
    return 0


def _remove_if_empty(folder: Path) -> None:
    """A failed run (a full disk at the first file, Ctrl-C while the scene is generated) leaves
    no empty ``--out`` folder of its own behind; one holding files keeps them."""
    try:
        folder.rmdir()
    except OSError:
        pass                # not empty (or already gone): leave it
