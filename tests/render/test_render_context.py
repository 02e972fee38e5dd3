"""The shared GL context, the shader loader and point splatting of the demo cloud."""

from __future__ import annotations

import numpy as np
import pytest

from app.demo.room import default_views, render_photo
from app.errors import ScanlightError
from app.render import programs
from app.render.splat import SplatRenderer


def test_context_is_gl43_and_shared(ctx):
    from app.render.context import get_context
    assert ctx.version_code >= 430
    assert get_context() is ctx


def test_include_and_defines_reach_the_shader(ctx, tmp_path, monkeypatch):
    (tmp_path / "lib").mkdir()
    (tmp_path / "lib" / "k.glsl").write_text("const float K = 2.5;\n")
    (tmp_path / "probe.glsl").write_text(
        '#include "lib/k.glsl"\nlayout(local_size_x = 1) in;\n'
        "layout(std430, binding = 0) buffer Out { float v[]; };\n"
        "void main() { v[0] = K * float(SCALE); }\n")
    monkeypatch.setattr(programs, "shaders_dir", lambda: tmp_path)
    cs = programs.load_compute(ctx, "probe.glsl", defines={"SCALE": 3})
    buf = ctx.buffer(reserve=4)
    buf.bind_to_storage_buffer(0)
    cs.run(1)
    assert np.frombuffer(buf.read(), "f4")[0] == pytest.approx(7.5)


def test_compile_error_names_file_and_line(ctx, tmp_path, monkeypatch):
    (tmp_path / "lib").mkdir()
    (tmp_path / "lib" / "bad.glsl").write_text("float f() {\n  return undefined_name;\n}\n")
    (tmp_path / "main.glsl").write_text('layout(local_size_x = 1) in;\n#include "lib/bad.glsl"\n'
                                        "void main() { f(); }\n")
    monkeypatch.setattr(programs, "shaders_dir", lambda: tmp_path)
    with pytest.raises(ScanlightError) as err:
        programs.load_compute(ctx, "main.glsl")
    msg = str(err.value)
    assert "lib/bad.glsl:2:" in msg and "undefined_name" in msg and "\n" not in msg


def test_every_shipped_shader_compiles(ctx):
    """Each program file in shaders/ builds (compute files have a local_size layout)."""
    for path in sorted(programs.shaders_dir().glob("*.glsl")):
        text = path.read_text()
        if "COMPUTE_SHADER" in text or "local_size_x" in text:
            programs.load_compute(ctx, path.name)
        else:
            programs.load_program(ctx, path.name)


def test_splat_matches_ray_cast_photo(demo):
    """The splatted cloud seen from a view equals the exact ray-cast radiance of the same room.

    Tolerance: splats are flat discs of ~2x point spacing, so edges and texture steps blur;
    the mean relative error over covered pixels must stay below 8% (measured ~4%) and 95% of
    pixels must be covered (holes would mean broken sizing or a lost draw).
    """
    cam = default_views(128, 128)["whole"]
    img = SplatRenderer(demo.gt).render(cam)
    ref = render_photo(cam)
    covered = img[..., 3] > 0
    assert covered.mean() > 0.95
    err = np.abs(img[..., :3] - ref)[covered].mean() / ref[covered].mean()
    assert err < 0.08
    assert np.isfinite(img).all()


def test_splat_far_from_origin_keeps_precision(demo):
    """A cloud offset by 1e6 m renders the same image as at the origin (float64 origin shift)."""
    from app.camera import Camera
    from app.cloud import PointCloud
    cam = default_views(64, 64)["closeup"]
    base = SplatRenderer(demo.gt).render(cam)
    off = np.array([1e6, 0.0, -1e6])
    moved = PointCloud(demo.gt.positions + off, demo.gt.normals, demo.gt.colors, hdr=True)
    cam2 = Camera(cam.position + off, cam.look_at + off, cam.up, cam.fov_y_deg, 64, 64)
    img = SplatRenderer(moved).render(cam2)
    assert np.abs(img - base).mean() < 1e-3 * max(1.0, base.mean())
