"""A scan georeferenced far from the origin renders the image it renders at the origin
(positions are float64 until each renderer subtracts its origin); float32 files that far away
are read with a warning about their precision."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tests.support import scenes as S
from app.cli import main
from app.cloud import PointCloud
from app.io.exr import read_exr
from app.io.pointcloud import load_cloud, save_cloud


def _render_at(d, offset: float) -> np.ndarray:
    base = S.box_room(0.08)
    off = np.array([offset, 0.0, offset])
    tag = f"{offset:g}"
    save_cloud(PointCloud(base.positions + off, base.normals, base.colors, hdr=True),
               d / f"room{tag}.ply")
    (d / f"obj{tag}.json").write_text(json.dumps({"mesh": "sphere", "scale": 0.6,
                                                  "translate": list(off + [0, 0.8, 0])}))
    (d / f"cam{tag}.json").write_text(json.dumps({
        "position": list(off + [0.3, 1.0, 0.9]), "look_at": list(off + [0, 0.8, 0]),
        "fov_y_deg": 40, "width": 24, "height": 18}))
    assert main(["render", "--cloud", str(d / f"room{tag}.ply"), "--object",
                 str(d / f"obj{tag}.json"), "--camera", str(d / f"cam{tag}.json"), "--out",
                 str(d / f"o{tag}.exr"), "--mode", "classic", "--microbuffer", "8"]) == 0
    return read_exr(d / f"o{tag}.exr").rgb


def test_a_scene_a_million_or_ten_million_metres_away_renders_the_same(tmp_path):
    """Before: 14% off with a faceted sphere at 1e6 m, an all-zero image at 1e7 m (the asset's
    vertices were rounded to float32 in world space)."""
    ref = _render_at(tmp_path, 0.0)
    assert ref.mean() > 0.01
    for offset in (1e6, 1e7):
        img = _render_at(tmp_path, offset)
        assert np.abs(img - ref).mean() / ref.mean() < 1e-5, offset


def test_float32_positions_far_away_are_read_with_a_warning(tmp_path, caplog):
    pts = np.array([[2e5, 0.0, 0.0], [2e5, 1.0, 0.0], [2e5, 0.0, 1.0]] * 6)
    rec = np.zeros(len(pts), dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4")])
    rec["x"], rec["y"], rec["z"] = pts.T
    p = tmp_path / "far.ply"
    head = ("ply\nformat binary_little_endian 1.0\nelement vertex 18\nproperty float x\n"
            "property float y\nproperty float z\nend_header\n")
    p.write_bytes(head.encode() + rec.tobytes())
    cloud = load_cloud(p)
    text = " ".join(cloud.report.get("warnings", [])) + caplog.text
    assert "32-bit floats" in text and "double" in text
    near = tmp_path / "near.ply"
    rec["x"] -= 2e5
    near.write_bytes(head.encode() + rec.tobytes())
    caplog.clear()
    cloud = load_cloud(near)
    assert "32-bit" not in " ".join(cloud.report.get("warnings", [])) + caplog.text


@pytest.mark.parametrize("offset", [1e6])
def test_the_asset_keeps_float64_positions(offset):
    from app.io.mesh import make_sphere_mesh, transform_mesh
    m = np.eye(4)
    m[:3, 3] = offset
    mesh = transform_mesh(make_sphere_mesh(2), m)
    assert mesh.positions.dtype == np.float64
    r = np.linalg.norm(mesh.positions - offset, axis=1)
    assert np.allclose(r, r.mean(), rtol=1e-9)


def _room_at(d, offset: float, tag: str):
    base = S.box_room(0.08)
    off = np.array([offset, 0.0, offset])
    save_cloud(PointCloud(base.positions + off, base.normals, np.clip(base.colors, 0, 1),
                          hdr=False), d / f"{tag}.ply")
    return off


def test_the_expansion_far_from_the_origin_matches_the_one_at_it(tmp_path):
    """Same room, photo and capture position, 1e6 m away: the same expanded colours. The photo
    is a ramp of no room, so registration is off (it would refuse it: another room)."""
    from app.io.exr import write_exr
    ramp = np.geomspace(0.01, 8.0, 32, dtype=np.float32)
    write_exr(tmp_path / "photo.exr", np.repeat(np.tile(ramp, (32, 1))[..., None], 3, axis=-1))
    out = {}
    for offset in (0.0, 1e6):
        off = _room_at(tmp_path, offset, f"ldr{offset:g}")
        (tmp_path / f"cams{offset:g}.json").write_text(json.dumps(
            [{"position": list(off + [0.0, 1.0, 0.0])}]))
        assert main(["expand", "--cloud", str(tmp_path / f"ldr{offset:g}.ply"), "--photo",
                     str(tmp_path / "photo.exr"), "--cameras", str(tmp_path / f"cams{offset:g}.json"),
                     "--face-size", "32", "--worker", "sync", "--registration", "off",
                     "--out", str(tmp_path / f"hdr{offset:g}.ply")]) == 0
        out[offset] = load_cloud(tmp_path / f"hdr{offset:g}.ply").colors
    assert np.allclose(out[1e6], out[0.0], rtol=1e-4, atol=1e-5)


def test_the_viewer_far_from_the_origin_draws_what_it_draws_at_the_origin(tmp_path):
    """The offscreen viewer (room splats, asset G-buffer, GI) with everything 1e7 m away."""
    from app.camera import Camera
    from app.settings import AssetTransform, Session
    from app.ui.app import OffscreenViewer
    images = {}
    for offset in (0.0, 1e7):
        off = _room_at(tmp_path, offset, f"room{offset:g}")
        s = Session(cloud=str(tmp_path / f"room{offset:g}.ply"), photo=None, asset="sphere",
                    transform=AssetTransform(tuple(off + [0, 0.8, 0]), (0.0, 0.0, 0.0), 0.6),
                    camera=Camera(off + [0.3, 1.0, 0.9], off + [0, 0.8, 0], fov_y_deg=40,
                                  width=40, height=30))
        s.settings.update({"pbgi.microbuffer": 8, "pbgi.mode": "classic"})
        s.settings.take_changes()
        v = OffscreenViewer(s, (40, 30))
        v.run(2, str(tmp_path / f"v{offset:g}.png"))
        images[offset] = v.engine.view.read_linear()
    ref = images[0.0]
    assert (ref[..., 3] > 0).sum() > 50
    assert np.abs(images[1e7] - ref).mean() / np.abs(ref).mean() < 1e-3


@pytest.mark.parametrize("stray,dtype", [(1e8, "<f8"), (1e30, "<f4"), (1e300, "<f8")])
def test_a_stray_point_far_out_of_the_scan_is_dropped_not_rendered(tmp_path, caplog, stray,
                                                                   dtype):
    """One stray point 1e8 m out of a 2 m room: every camera's near plane went 10 km out and
    the render came back black in 17 ms, exit 0. At 1e30 m (float32) near and far met (a
    ZeroDivisionError); at 1e300 m (double) float32 made it Inf (a ValueError deep in the near
    field). Now load_cloud drops it with a warning and the image is the room's own."""
    ref = _render_at(tmp_path, 0.0)
    base = S.box_room(0.08)
    pos = base.positions.copy()
    pos[0] = (stray, 0.0, 0.0)
    rec = np.zeros(len(pos), dtype=[(k, dtype) for k in "xyz"]
                   + [(k, "<f4") for k in ("nx", "ny", "nz", "red", "green", "blue")])
    for k, col in zip("xyz", pos.T):
        rec[k] = col
    for k, col in zip(("nx", "ny", "nz"), base.normals.T):
        rec[k] = col
    for k, col in zip(("red", "green", "blue"), base.colors.T):
        rec[k] = col
    kind = "double" if dtype == "<f8" else "float"
    head = ("ply\nformat binary_little_endian 1.0\n" f"element vertex {len(rec)}\n"
            + "".join(f"property {kind} {k}\n" for k in "xyz")
            + "".join(f"property float {k}\n" for k in ("nx", "ny", "nz", "red", "green", "blue"))
            + "end_header\n")
    (tmp_path / "room0.ply").write_bytes(head.encode() + rec.tobytes())
    assert main(["render", "--cloud", str(tmp_path / "room0.ply"), "--object",
                 str(tmp_path / "obj0.json"), "--camera", str(tmp_path / "cam0.json"), "--out",
                 str(tmp_path / "stray.exr"), "--mode", "classic", "--microbuffer", "8"]) == 0
    img = read_exr(tmp_path / "stray.exr").rgb
    # the room less the one point that was dropped: the same image to a fraction of a percent
    assert np.abs(img - ref).mean() / ref.mean() < 0.01
    assert "dropped 1 " in caplog.text
    report = load_cloud(tmp_path / "room0.ply").report
    assert report["points_in_file"] == len(pos)
    assert report["dropped_nonfinite_positions"] + report["dropped_stray_points"] == 1
