"""The expansion on a scene made from a real HDR panorama (../shared/data, see its README)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from app.color import luminance
from app.hdr.evaluate import expansion_errors
from app.bench.panorama_rooms import direction_to_uv, panorama_room, sample_panorama
from app.hdr.pipeline import ExpandParams, run_expansion

DATA = Path(__file__).resolve().parents[3] / "shared" / "data"


@pytest.fixture(scope="module")
def apartment():
    path = DATA / "apartment.exr"
    if not path.is_file():
        pytest.skip(f"{path} not available")
    from app.io.exr import read_exr
    return read_exr(path).rgb


def test_sampling_the_panorama_in_pixel_directions_returns_the_pixels(apartment):
    h, w = apartment.shape[:2]
    i, j = np.mgrid[10:h - 10:17, 0:w:23]
    lon = ((j + 0.5) / w - 0.5) * 2 * np.pi
    lat = (0.5 - (i + 0.5) / h) * np.pi
    d = np.stack([np.cos(lat) * np.sin(lon), np.sin(lat), -np.cos(lat) * np.cos(lon)], -1)
    x, y = direction_to_uv(d.reshape(-1, 3), w, h)
    np.testing.assert_allclose(x, j.ravel(), atol=1e-6)
    np.testing.assert_allclose(y, i.ravel(), atol=1e-6)
    np.testing.assert_allclose(sample_panorama(apartment, d.reshape(-1, 3)),
                               apartment[i, j].reshape(-1, 3), rtol=1e-5, atol=1e-6)


def test_pmatch_beats_ldr_and_itmos_on_the_apartment_panorama(apartment):
    sc = panorama_room(apartment, 40_000)
    over = luminance(sc.ldr.colors) > 0.9
    assert 0.02 < over.mean() < 0.1
    err = {}
    for m in ("pmatch-rgb", "banterle", "landis"):
        r = run_expansion(sc.ldr, sc.photo, sc.capture_positions, m, ExpandParams(face_size=256, registration="off"))
        assert np.all(np.isfinite(r.cloud.colors))
        err[m] = expansion_errors(r.cloud, sc.gt, sc.ldr, exposure=sc.alpha)["rms_overexposed"]
    ldr = expansion_errors(sc.ldr, sc.gt, sc.ldr, exposure=sc.alpha)["rms_overexposed"]
    assert err["pmatch-rgb"] < 0.7 * ldr, (err, ldr)
    assert err["pmatch-rgb"] < min(err["banterle"], err["landis"]), err
