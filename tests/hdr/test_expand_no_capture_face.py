"""`expand` when no capture face sees an overexposed point.

The capture renders only the faces that can see an overexposed point (pipeline._capture_faces);
single-view capture cameras that all look away from the scan's clipped points leave none, and
matching then had nothing to concatenate (an internal error, exit 1). Those points are now left
to Poisson editing, as the points a cube map's faces do not see always were: exit 0, a finite
cloud, a warning, and a report that says nothing was matched.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from app.cli import main
from app.cloud import PointCloud
from app.color import luminance
from app.hdr.pipeline import ExpandParams

TL = ExpandParams().threshold_ldr


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """A 2 x 2 m floor (y = 0) of 3,600 points, textured grey, with a clipped white patch
    (x > 0.5); one 64 x 64 capture camera half a metre above it looking straight up, so every
    point lies behind it; a 48 x 48 HDR photo with range above 1."""
    from app.io.exr import write_exr
    from app.io.pointcloud import save_cloud

    root = tmp_path_factory.mktemp("noface")
    rng = np.random.default_rng(7)
    g = np.linspace(-1.0, 1.0, 60)
    x, z = (a.ravel() for a in np.meshgrid(g, g))
    pos = np.stack([x, np.zeros_like(x), z], axis=1)
    nrm = np.tile([0.0, 1.0, 0.0], (len(pos), 1))
    col = np.repeat(rng.uniform(0.05, 0.5, (len(pos), 1)), 3, axis=1)
    col[x > 0.5] = 1.0
    save_cloud(PointCloud(pos, nrm, col.astype(np.float32), False, "floor"), root / "ldr.ply")
    photo = rng.uniform(0.05, 0.6, (48, 48, 3)).astype(np.float32)
    photo[:, 30:] *= 8.0
    write_exr(root / "photo.exr", photo)
    (root / "cams.json").write_text(json.dumps([{
        "position": [0.0, 0.5, 0.0], "look_at": [0.0, 2.0, 0.0], "up": [0.0, 0.0, -1.0],
        "fov_y_deg": 45.0, "width": 64, "height": 64}]))
    return root


@pytest.mark.parametrize("extra", [[], ["--registration", "off"], ["--method", "pmatch-lum"],
                                   ["--method", "landis"]],
                         ids=["default", "registration-off", "pmatch-lum", "landis"])
def test_expand_leaves_unseen_points_to_poisson_when_no_face_sees_one(scene, tmp_path, extra,
                                                                      capsys):
    from app.io.pointcloud import load_cloud

    out, rep_path = tmp_path / "hdr.ply", tmp_path / "rep.json"
    rc = main(["expand", "--cloud", str(scene / "ldr.ply"), "--photo", str(scene / "photo.exr"),
               "--cameras", str(scene / "cams.json"), "--out", str(out),
               "--report", str(rep_path), *extra])
    err = capsys.readouterr().err
    assert rc == 0, err
    assert "internal error" not in err
    assert "no capture camera sees an overexposed point" in err

    ldr = load_cloud(scene / "ldr.ply")
    over = luminance(ldr.colors) > TL
    assert over.sum() > 100                      # the case is what it claims to be
    hdr = load_cloud(out)
    assert hdr.hdr and len(hdr) == len(ldr)
    assert np.all(np.isfinite(hdr.colors)) and np.all(hdr.colors >= 0)
    # untouched where the scan measured; never darker than the clipped measurement
    np.testing.assert_allclose(hdr.colors[~over], ldr.colors[~over], atol=1e-6)
    assert np.all(luminance(hdr.colors[over]) >= luminance(ldr.colors[over]) * (1 - 1e-5))

    rep = json.loads(rep_path.read_text())
    c = rep["counts"]
    # the report says what happened: nothing rendered, matched or projected; Poisson filled all
    assert rep["capture"]["faces_rendered"] == 0
    assert rep["path"] == "matching"
    assert c["expanded_by_projection"] == 0 and c["projected_from_registered_photo"] == 0
    assert c["filled_by_poisson"] + c["unresolved"] == c["overexposed"] == over.sum()
    assert rep["provenance"]["filled_by_poisson"]["points"] == c["filled_by_poisson"]
    assert rep["projection"]["overexposed_seen_by_captures"] == 0
    if "match" in rep:                           # the PatchMatch methods
        assert rep["match"]["faces"] == 0 and rep["match"]["close_match_fraction"] is None
    assert any("no capture camera sees an overexposed point" in w for w in rep["warnings"])


def test_match_faces_without_faces_reports_no_evidence():
    """No faces: no matches, and a close-match fraction of None rather than 0.0, which the
    pipeline would read as "a photo of another scene"."""
    from app.hdr.matching import match_faces

    report = {}
    out = match_faces([], np.full((16, 16, 3), 0.5, np.float32), ExpandParams(),
                      lambda: None, lambda f: None, report)
    assert out == []
    assert report["match"]["faces"] == 0 and report["match"]["close_match_fraction"] is None
