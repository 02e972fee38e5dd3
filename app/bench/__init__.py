"""Benchmarks: each module ``app.bench.<name>`` has ``add_arguments(parser)`` and
``run(args) -> list[record]``; ``scanlight bench NAME`` prints the table and writes JSON."""

BENCHES = {
    "bsh": "app.bench.bsh",
    "classic": "app.bench.classic",
    "table3": "app.bench.table3",
    "expand": "app.bench.expand",
    "glossy": "app.bench.glossy",
    "asset": "app.bench.asset_light",
    "tradeoff": "app.bench.tradeoff",
    "nearfield": "app.bench.nearfield",
    "profile": "app.bench.profile",
    "pathtracer-ratio": "app.bench.pathtracer_ratio",
    "viewer": "app.bench.viewer",
}
