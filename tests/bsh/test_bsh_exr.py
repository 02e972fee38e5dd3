"""BSH over real HDR radiance: each panorama of ../shared/data becomes a box room around its
capture centre (every pixel a wall point with the radiance seen in its direction)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from app.pbgi.hierarchy import build_bsh
from tests.support.bsh import check_invariants

DATA = Path(__file__).resolve().parents[3] / "shared" / "data"
PANORAMAS = sorted(DATA.glob("*.exr"))
ROOM_LO, ROOM_HI = np.array([-2.0, 0.0, -2.0]), np.array([2.0, 2.8, 2.0])
CENTRE = np.array([0.3, 1.5, -0.2])


def read_rgb(path: Path) -> np.ndarray:
    """(H, W, 3) float32 straight from OpenEXR (interleaved "RGB" or separate R, G, B)."""
    import OpenEXR

    ch = OpenEXR.File(str(path)).channels()
    if "RGB" in ch:
        rgb = ch["RGB"].pixels
    else:
        rgb = np.stack([ch[c].pixels for c in "RGB"], axis=-1)
    return np.asarray(rgb, dtype=np.float32)


def panorama_room(path: Path, step: int = 4):
    """Points where the pixel rays of an equirectangular panorama hit a box room."""
    rgb = read_rgb(path)[::step, ::step]
    h, w, _ = rgb.shape
    v, u = np.meshgrid((np.arange(h) + 0.5) / h, (np.arange(w) + 0.5) / w, indexing="ij")
    theta, phi = np.pi * v.ravel(), 2 * np.pi * u.ravel() - np.pi
    d = np.stack([np.sin(theta) * np.sin(phi), np.cos(theta), -np.sin(theta) * np.cos(phi)], 1)
    with np.errstate(divide="ignore"):
        t_wall = np.where(d > 0, (ROOM_HI - CENTRE) / d, (ROOM_LO - CENTRE) / d)
    axis = np.argmin(t_wall, axis=1)
    t = t_wall[np.arange(len(d)), axis]
    pos = CENTRE + t[:, None] * d
    nrm = np.zeros_like(d)
    nrm[np.arange(len(d)), axis] = -np.sign(d[np.arange(len(d)), axis])  # faces the centre
    radiance = np.maximum(rgb.reshape(-1, 3), 0.0)  # negative ringing -> 0
    return pos, nrm.astype(np.float32), radiance


def test_panoramas_are_available():
    assert len(PANORAMAS) >= 4, f"expected the HDR panoramas in {DATA}"


@pytest.mark.parametrize("path", PANORAMAS, ids=lambda p: p.stem)
def test_bsh_over_panorama_room(path):
    pos, nrm, rad = panorama_room(path)
    assert len(pos) <= 50_000
    h = build_bsh(pos, nrm, rad)
    d = check_invariants(h, pos, nrm, rad)
    # the root radiance is the mean of all points; HDR peaks survive (float32, not clipped)
    np.testing.assert_allclose(d["color"][0], rad.mean(axis=0, dtype=np.float64), rtol=1e-5)
    leaf_max = d["color"][d["is_leaf"]].max()
    assert leaf_max <= rad.max() * (1 + 1e-6)
    if rad.max() > 100:
        assert leaf_max > 100
    # six flat walls: every wall's subtree has a tight cone, so some cones are tiny
    assert (d["cone_angle"] < 0.01).sum() > len(h.nodes) // 4
