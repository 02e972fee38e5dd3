"""The HDR expansion pipeline on the demo scene (ground truth known) and on bad input."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from app.camera import Camera
from app.cloud import PointCloud
from app.color import luminance
from app.errors import ScanlightError
from app.hdr.evaluate import expansion_errors
from app.hdr.pipeline import (LABEL_NAMES, POISSON, PROJECTED, UNCHANGED, ExpandParams,
                              expand_cloud, run_expansion)
from app.jobs import Cancelled

# the paper's matching path; the registered path is tested in test_registration.py
FAST = ExpandParams(face_size=128, registration="off")


@pytest.fixture(scope="module")
def demo():
    from app.demo.cache import load_demo
    return load_demo(50_000)


@pytest.fixture(scope="module")
def runs(demo):
    """One run per method compared in the test below (the slow part, shared)."""
    out = {}
    for m in ("pmatch-rgb", "pmatch-lum", "landis", "banterle", "landis-pc", "banterle-pc"):
        out[m] = run_expansion(demo.ldr, demo.photo, demo.capture_positions, m, FAST)
    return out


def _rms_over(cloud, demo):
    return expansion_errors(cloud, demo.gt, demo.ldr, exposure=demo.alpha)["rms_overexposed"]


def test_pmatch_rgb_beats_ldr_and_both_itmos_on_overexposed_points(demo, runs):
    err = {m: _rms_over(r.cloud, demo) for m, r in runs.items()}
    ldr = expansion_errors(demo.ldr, demo.gt, demo.ldr, exposure=demo.alpha)["rms_overexposed"]
    for m in ("landis", "banterle", "landis-pc", "banterle-pc"):
        assert err["pmatch-rgb"] < 0.5 * err[m], err
    assert err["pmatch-rgb"] < 0.4 * ldr, (err, ldr)
    assert err["pmatch-lum"] < 0.5 * ldr, (err, ldr)


def test_exposure_found_within_ten_percent(demo, runs):
    for r in runs.values():
        assert r.report["alpha"] == pytest.approx(demo.alpha, rel=0.10)


def test_only_overexposed_points_change_and_labels_add_up(demo, runs):
    over = luminance(demo.ldr.colors) > FAST.threshold_ldr
    for m, r in runs.items():
        c = r.cloud.colors
        assert r.cloud.hdr and np.all(np.isfinite(c)) and np.all(c >= 0)
        np.testing.assert_array_equal(c[~over], demo.ldr.colors[~over])
        assert np.all(r.labels[~over] == UNCHANGED) and np.all(r.labels[over] != UNCHANGED)
        counts = r.report["counts"]
        assert counts["overexposed"] == over.sum()
        assert sum(counts[LABEL_NAMES[k]] for k in LABEL_NAMES) == len(c)
        # an expanded point is never darker than its clipped measurement
        assert np.all(luminance(c[over]) >= luminance(demo.ldr.colors[over]) * (1 - 1e-5))
    rep = runs["pmatch-rgb"].report
    assert rep["counts"]["expanded_by_projection"] > 0.6 * over.sum()
    assert set(rep["timings"]) >= {f"seconds_{s}" for s in
                                   ("linearise", "capture", "exposure", "expand", "project",
                                    "poisson", "total")}
    assert (runs["pmatch-rgb"].labels == POISSON).sum() == rep["counts"]["filled_by_poisson"]
    assert not rep["warnings"], rep["warnings"]


def test_pmatch_rgb_transfers_the_lamps_own_radiance(demo, runs):
    """The ceiling lamp (36 in luminance) and the window (11) both clip to white; the lamp's
    points must get the lamp's radiance, not the window's."""
    gt_y = luminance(demo.gt.colors)
    lamp = (luminance(demo.ldr.colors) > 0.9) & (gt_y > 30)
    r = runs["pmatch-rgb"]
    y = luminance(r.cloud.colors[lamp & (r.labels == PROJECTED)]) / demo.alpha
    assert np.median(y) == pytest.approx(np.median(gt_y[lamp]), rel=0.15)


def test_progress_is_monotone_and_complete(demo):
    seen = []
    run_expansion(demo.ldr, demo.photo, demo.capture_positions, "landis", FAST,
                  progress=lambda f, s: seen.append((f, s)))
    fr = [f for f, _ in seen]
    assert fr[0] <= 0.05 and fr[-1] == 1.0 and np.all(np.diff(fr) >= 0)
    stages = list(dict.fromkeys(s for _, s in seen))
    assert stages == ["linearise", "capture", "exposure", "expand", "project", "poisson", "done"]


def test_cancel_stops_within_a_second(demo):
    cancel = threading.Event()
    t_cancel = []

    def progress(f, stage):
        if stage == "expand" and not cancel.is_set():
            cancel.set()
            t_cancel.append(time.perf_counter())

    with pytest.raises(Cancelled):
        run_expansion(demo.ldr, demo.photo, demo.capture_positions, "pmatch-rgb",
                      ExpandParams(face_size=256), progress=progress, cancel=cancel)
    assert time.perf_counter() - t_cancel[0] < 1.0


def test_no_overexposed_points_output_is_input(demo):
    dim = PointCloud(demo.ldr.positions, demo.ldr.normals, demo.ldr.colors * 0.5, False)
    cloud, rep = expand_cloud(dim, demo.photo, demo.capture_positions, "pmatch-rgb", FAST)
    np.testing.assert_array_equal(cloud.colors, dim.colors)
    assert rep["nothing_to_do"] and rep["counts"]["overexposed"] == 0
    assert "nothing to expand" in rep["warnings"][0]


@pytest.mark.parametrize("value,what", [(0.0, "all black"), (1.0, "uniform"), (7.5, "uniform")])
def test_black_or_constant_photo_is_refused(demo, value, what):
    photo = np.full((64, 96, 3), value, np.float32)
    with pytest.raises(ScanlightError, match=what) as exc:
        expand_cloud(demo.ldr, photo, demo.capture_positions, "pmatch-rgb", FAST,
                     names={"photo": "p.exr"})
    assert str(exc.value).startswith("p.exr:") and "\n" not in str(exc.value)


def test_nan_and_negative_photo_pixels_are_repaired_and_reported(demo):
    photo = demo.photo.copy()
    photo[:5, :5] = np.nan
    photo[10, 10] = -3.0
    cloud, rep = expand_cloud(demo.ldr, photo, demo.capture_positions, "landis", FAST)
    assert np.all(np.isfinite(cloud.colors))
    assert any("NaN" in w and "negative" in w for w in rep["warnings"])


def _panorama_photo(name="apartment"):
    from app.bench.panorama_rooms import sample_panorama
    from app.io.exr import read_exr
    pano = read_exr(f"../shared/data/{name}.exr").rgb
    cam = Camera((0, 0, 0), (0, 0.1, -1), fov_y_deg=70, width=256, height=192)
    _, rays = cam.pixel_rays()
    return sample_panorama(pano, rays.reshape(-1, 3)).reshape(192, 256, 3)


def test_photo_of_another_scene_finishes_with_a_warning(demo):
    """A crop of a real apartment panorama is not a photo of the demo room: the run completes,
    says the match quality is low and leaves most points to Poisson editing."""
    r = run_expansion(demo.ldr, _panorama_photo(), demo.capture_positions, "pmatch-rgb", FAST)
    rep = r.report
    assert rep.get("low_match_quality") and any("another scene" in w for w in rep["warnings"])
    assert rep["match"]["close_match_fraction"] < 0.02
    assert np.all(np.isfinite(r.cloud.colors))
    over = rep["counts"]["overexposed"]
    assert rep["counts"]["filled_by_poisson"] > 0.5 * over


def test_the_right_photo_is_not_flagged(runs):
    rep = runs["pmatch-rgb"].report
    assert not rep.get("low_match_quality") and rep["match"]["close_match_fraction"] > 0.05


@pytest.mark.parametrize("position,phrase", [((5.0, 1.4, 0.0), "outside the cloud's bounding box"),
                                             ((1.3, 0.5, 1.2), "sees surfaces from behind")])
def test_capture_camera_outside_the_room_or_inside_an_object_warns(demo, position, phrase):
    cloud, rep = expand_cloud(demo.ldr, demo.photo, [position], "landis", FAST)
    assert any(phrase in w for w in rep["warnings"]), rep["warnings"]
    assert np.all(np.isfinite(cloud.colors))
    assert rep["counts"]["unresolved"] + rep["counts"]["filled_by_poisson"] > 0


def test_camera_objects_and_several_positions(demo):
    cams = [Camera(demo.capture_positions[0], (0, 2.8, 0), fov_y_deg=100, width=128, height=128),
            (-1.0, 1.4, 0.5)]
    cloud, rep = expand_cloud(demo.ldr, demo.photo, cams, "landis", FAST)
    assert len(rep["capture"]["cameras"]) == 2 and rep["capture"]["faces_rendered"] >= 2
    assert rep["counts"]["expanded_by_projection"] > 0


@pytest.mark.parametrize("cams", [[], [(np.nan, 0, 0)], [(1, 2)]])
def test_bad_camera_lists_are_refused(demo, cams):
    with pytest.raises(ScanlightError, match="camera"):
        expand_cloud(demo.ldr, demo.photo, cams, "landis", FAST)


def test_bad_method_and_parameters_are_refused(demo):
    with pytest.raises(ScanlightError, match="'method' must be one of pmatch-rgb"):
        expand_cloud(demo.ldr, demo.photo, demo.capture_positions, "eiler", FAST)
    with pytest.raises(ScanlightError, match="threshold_ldr"):
        expand_cloud(demo.ldr, demo.photo, demo.capture_positions, "landis",
                     ExpandParams(threshold_ldr=1.5))
    with pytest.raises(ScanlightError, match="unknown ExpandParams field 'bogus'"):
        ExpandParams.from_dict({"face_size": 64, "bogus": 1})
    with pytest.raises(ScanlightError, match="pm_scale_min.*below"):
        ExpandParams(pm_scale_min=4.0, pm_scale_max=2.0).validated()


def test_params_are_the_tables_hdr_rows():
    """ExpandParams is generated from the parameter table: its fields, defaults and methods."""
    from app.params import BY_KEY, EXPAND_KEYS
    from app.hdr.pipeline import METHODS
    p = ExpandParams()
    assert ExpandParams.KEYS == EXPAND_KEYS
    assert p.to_settings() == {k: BY_KEY[k].default for k in EXPAND_KEYS}
    assert p.face_size == 512 and p.pm_scale_range == (p.pm_scale_min, p.pm_scale_max)
    assert METHODS == BY_KEY["hdr.method"].choices
    assert ExpandParams.from_dict({"hdr.neighbours": 8, "seed": 3}) == \
        ExpandParams(neighbours=8, seed=3)


def test_method_comes_from_the_params_unless_given(demo):
    dim = PointCloud(demo.ldr.positions, demo.ldr.normals, demo.ldr.colors * 0.5, False)
    _, rep = expand_cloud(dim, demo.photo, demo.capture_positions,
                          params=ExpandParams(method="landis", face_size=64))
    assert rep["method"] == "landis" and rep["params"]["method"] == "landis"
    _, rep = expand_cloud(dim, demo.photo, demo.capture_positions, "banterle",
                          ExpandParams(method="landis", face_size=64))
    assert rep["method"] == "banterle"


def test_given_exposure_skips_the_search(demo):
    _, rep = expand_cloud(demo.ldr, demo.photo, demo.capture_positions, "landis-pc",
                          ExpandParams(alpha=0.5))
    assert rep["alpha"] == 0.5 and rep["exposure"]["source"] == "given"
