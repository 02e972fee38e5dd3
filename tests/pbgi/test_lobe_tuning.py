"""The lobe walk's two tunings (app/pbgi/lobe.py: LobeWalkTuning): llvmpipe keeps a per-receiver
ray table, a long accepted-node list with each node's rectangle and ray-cast record in a table of
its own, and the receiver's row in its own memory; a GPU computes each ray where it is cast,
each rectangle whole in the walk, and ray casts every 128 accepted nodes into the image. They are
two ways to compute the same micro-buffers: both run here, on llvmpipe, and must give the same
image and the same walk."""

from __future__ import annotations

import numpy as np
import pytest

from app.material import Material
from app.pbgi.lobe import (GPU_TUNING, LOBE_TUNINGS, SOFTWARE_TUNING, lobe_walk_tuning,
                           tuning_name)
from app.pbgi.renderer import RenderParams
from app.render.context import is_software_renderer


@pytest.mark.parametrize("renderer,software", [
    ("llvmpipe (LLVM 15.0.6, 256 bits)", True),           # this machine, CI
    ("softpipe", True),
    ("Software Rasterizer", True),                         # Mesa's old swrast
    ("NVIDIA H100 80GB HBM3/PCIe/SSE2", False),            # the lent GPU (README)
    ("AMD Radeon RX 7900 XTX (radeonsi, navi31, LLVM 17.0.6, DRM 3.54, 6.5.0)", False),
    ("Mesa Intel(R) UHD Graphics 630 (CFL GT2)", False),
])
def test_renderer_names(renderer, software):
    """A GPU whose driver names LLVM (radeonsi compiles with it) is still a GPU."""
    assert is_software_renderer(renderer) is software
    assert lobe_walk_tuning(renderer) == (SOFTWARE_TUNING if software else GPU_TUNING)


def test_tunings_differ_where_they_should():
    assert SOFTWARE_TUNING.ray_table and not GPU_TUNING.ray_table
    assert SOFTWARE_TUNING.accepted_table and not GPU_TUNING.accepted_table
    assert GPU_TUNING.list_cap < SOFTWARE_TUNING.list_cap
    assert {tuning_name(t) for t in LOBE_TUNINGS.values()} == set(LOBE_TUNINGS)


MATERIALS = {
    "gold 0.25": Material(base_color=(1.0, 0.78, 0.34), metallic=1.0, roughness=0.25),
    "silver 0.05": Material(base_color=(0.95, 0.95, 0.95), metallic=1.0, roughness=0.05),
    "clearcoat": Material(base_color=(0.2, 0.3, 0.8), roughness=0.4, clearcoat=1.0,
                          clearcoat_gloss=0.9),
    # the stretched mapping: the walk's rings-only rectangle is lobe_rect_stretched whole
    "brushed 0.2": Material(base_color=(0.9, 0.9, 0.9), metallic=1.0, roughness=0.2,
                            anisotropic=0.8),
}


def _render(r, mat, tuning):
    from app.demo.room import default_views
    r.lobe_tuning = tuning
    r.forget_microbuffers()
    cam = default_views(32, 32)["closeup"]
    return r.render(cam, [mat], RenderParams(mode="classic", microbuffer=16))


@pytest.mark.parametrize("name", sorted(MATERIALS))
def test_gpu_tuning_gives_the_same_image(demo_relighter, name):
    """Gold, a near mirror, a clearcoat (two lobes in one buffer) and a brushed metal: the GPU
    tuning on llvmpipe walks the same nodes, makes the same ray tests and gives the same image
    as the software tuning (its rays are computed by the same function, only not kept; its
    rectangles in the walk, not in a loop over the accepted nodes), while its shorter list
    takes more dispatches. A wrong cell index, a lost resume, a rectangle or record that is not
    the walk's own, or a row not stored would change one of the three."""
    r = demo_relighter
    mat = MATERIALS[name]
    try:
        soft = _render(r, mat, SOFTWARE_TUNING)
        assert r.lobe_buffers.tuning == SOFTWARE_TUNING
        gpu = _render(r, mat, GPU_TUNING)
        assert r.lobe_buffers.tuning == GPU_TUNING      # the setter dropped the other buffers
    finally:
        r.lobe_tuning = None                             # back to the renderer's own
    for res in (soft, gpu):
        assert res.stats.completed and res.stats.lobe_receivers and not res.stats.lobe_incomplete
    assert gpu.stats.lobe_visited == pytest.approx(soft.stats.lobe_visited, rel=1e-6)
    assert gpu.stats.lobe_tests == pytest.approx(soft.stats.lobe_tests, rel=1e-6)
    a, b = soft.image[..., :3], gpu.image[..., :3]
    scale = float(a[soft.image[..., 3] > 0].mean())
    assert scale > 0
    assert np.abs(a - b).max() <= 1e-4 * scale
