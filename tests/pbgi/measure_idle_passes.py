"""The README's table of idle passes per preset and material ("Fewer idle passes where the light
is rough"): what each further pass of the viewer still changes, against the path tracer and
against the renderer's own converged mean.

    python tests/pbgi/measure_idle_passes.py [--rooms demo,apartment] [--presets balanced,preview]
        [--materials diffuse,rough_metal,clearcoat,glossy,near_mirror] [--passes 1,2,3,4,8]
        [--json out.json]

Per room and material of the trade-off bench (256 x 256 close-ups, app/bench/tradeoff.py) and
per quality preset at its GI scale for that material (app/pbgi/upsample.py: gi_scale; the preset
as `bench pathtracer-ratio` renders it): the mean of N passes as the viewer makes it
(``tradeoff.render_setting`` with N passes: the same pass jitter and lobe rotations), its
per-pixel and 4x4-pooled relative RMSE and FLIP against the cached Mitsuba reference (rendered
if missing), and - what the reference's own noise (8.7% per pixel on the demo) hides - its
per-pixel relative RMSE and FLIP against the mean of 16 passes, the picture the passes converge
to. Prints a markdown table; ``--json`` keeps every number.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from app.bench import image_metrics as im  # noqa: E402
from app.bench import tradeoff as T  # noqa: E402
from app.bench.pathtracer_ratio import settings as bench_settings  # noqa: E402
from app.pbgi.renderer import Relighter  # noqa: E402

CONVERGED = 16          # passes of the mean taken as converged


def measure(room: str, kinds, presets, passes) -> list[dict]:
    cloud, mesh, cam = T.scene(room, T.SIZE)
    rl = Relighter()
    rl.set_cloud(cloud)
    rl.set_asset(mesh)
    by_name = {s.name: s for s in bench_settings()}     # the presets as the benches render them
    rows = []
    for kind in kinds:
        mat = T.material(kind)
        ref = T.reference(room, kind, rl, cloud, mesh, cam, T.SPP[room], T.reference_dir())
        for preset in presets:
            setting = by_name[preset]
            conv = T.render_setting(rl, cam, mat, setting, CONVERGED)[0]
            mask = im.erode(conv[..., 3] > 0.5, T.MASK_ERODE)
            for n in passes:
                img = T.render_setting(rl, cam, mat, setting, n)[0]
                flip = im.flip(img, conv, mask)
                row = {"room": room, "material": kind, "preset": preset, "passes": n,
                       **T.evaluate(img, ref.image),
                       "to_converged": im.relative_rmse(img, conv, mask, 1),
                       "flip_to_converged": float("nan") if flip is None else flip}
                rows.append(row)
                print(json.dumps(row), file=sys.stderr, flush=True)
    return rows


def markdown(rows: list[dict]) -> str:
    """One line per room, material and preset; per N: to the reference per pixel / pooled,
    [to the converged mean per pixel, FLIP]."""
    passes = sorted({r["passes"] for r in rows})
    out = ["| room | material | preset | " + " | ".join(f"{n} pass{'es' * (n > 1)}"
                                                      for n in passes) + " |",
           "|---" * (3 + len(passes)) + "|"]
    keys = list(dict.fromkeys((r["room"], r["material"], r["preset"]) for r in rows))
    for key in keys:
        by_n = {r["passes"]: r for r in rows if (r["room"], r["material"], r["preset"]) == key}
        cells = [f"{100 * r['rel_rmse']:.2f} / {100 * r['rel_rmse_4x4']:.2f}% "
                 f"[{100 * r['to_converged']:.2f}%, {r['flip_to_converged']:.3f}]"
                 if (r := by_n.get(n)) else "-" for n in passes]
        out.append(f"| {' | '.join(key)} | " + " | ".join(cells) + " |")
    return "\n".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rooms", default=",".join(T.ROOMS))
    ap.add_argument("--presets", default="balanced,preview")
    ap.add_argument("--materials", default="diffuse,rough_metal,clearcoat,glossy,near_mirror")
    ap.add_argument("--passes", default="1,2,3,4,8")
    ap.add_argument("--json", type=Path)
    a = ap.parse_args()
    passes = [int(n) for n in a.passes.split(",")]
    rows = []
    for room in a.rooms.split(","):
        rows += measure(room, a.materials.split(","), a.presets.split(","), passes)
    print(markdown(rows))
    if a.json:
        a.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
