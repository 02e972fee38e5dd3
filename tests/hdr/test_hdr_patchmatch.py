"""Generalised PatchMatch recovers a known similarity transform between an image and its warp."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter, map_coordinates

from app.hdr.patchmatch import NNField, patchmatch, resize_area


def _texture(size=160, seed=1):
    rng = np.random.default_rng(seed)
    b = np.stack([gaussian_filter(rng.random((size, size)), 3) for _ in range(3)], -1)
    return ((b - b.min()) / (b.max() - b.min())).astype(np.float32)


def _warp(b, angle, scale, centre, size=80):
    """A(p) = B(centre + scale * R(angle) (p - c_A)): the exact answer for every A pixel."""
    yy, xx = np.mgrid[0:size, 0:size].astype(float)
    u, v = xx - size / 2, yy - size / 2
    c, s = np.cos(angle), np.sin(angle)
    bx = centre[0] + scale * (c * u - s * v)
    by = centre[1] + scale * (s * u + c * v)
    a = np.stack([map_coordinates(b[..., k], [by, bx], order=1) for k in range(3)], -1)
    return a.astype(np.float32), bx, by


@pytest.mark.parametrize("angle,scale", [(0.0, 1.0), (0.6, 1.4), (2.5, 0.7), (-1.2, 1.0)])
def test_recovers_translation_rotation_scale(angle, scale):
    b = _texture()
    a, bx, by = _warp(b, angle, scale, (80.0, 80.0))
    f = patchmatch(a, b, iterations=4, levels=3, seed=0)
    inside = (bx > 4) & (bx < 155) & (by > 4) & (by < 155)  # A pixels whose patch lies in B
    err = np.hypot(f.x - bx, f.y - by)[inside]
    assert np.median(err) < 0.6
    assert np.mean(err < 1.5) > 0.8
    d_ang = np.angle(np.exp(1j * (f.angle[inside] - angle)))
    assert abs(np.median(d_ang)) < 0.05
    assert abs(np.log(np.median(f.scale[inside]) / scale)) < 0.05
    assert np.median(f.cost[inside]) < 0.05  # SSD near zero where the match is exact


def test_cost_is_the_ssd_of_the_transformed_patch():
    """The quality field is the 7x7 SSD against B sampled (nearest pixel) along the matched
    similarity transform: recomputed here independently for a few pixels."""
    b = _texture()
    a, _, _ = _warp(b, 0.3, 1.2, (80.0, 80.0))
    f = patchmatch(a, b, iterations=1, levels=1, seed=0, coarse_samples=2, clip_level=None)
    for i, j in [(10, 10), (40, 33), (70, 60), (25, 71)]:
        c, s = np.cos(f.angle[i, j]), np.sin(f.angle[i, j])
        ssd = 0.0
        for v in range(-3, 4):
            for u in range(-3, 4):
                bx = f.x[i, j] + f.scale[i, j] * (c * u - s * v)
                by = f.y[i, j] + f.scale[i, j] * (s * u + c * v)
                bj = int(np.clip(np.floor(np.clip(bx, 0, 159) + 0.5), 0, 159))
                bi = int(np.clip(np.floor(np.clip(by, 0, 159) + 0.5), 0, 159))
                ai, aj = np.clip(i + v, 0, 79), np.clip(j + u, 0, 79)
                ssd += float(np.sum((b[bi, bj] - a[ai, aj]) ** 2))
        assert f.cost[i, j] == pytest.approx(ssd, rel=1e-3, abs=1e-5)


def test_field_map_follows_the_similarity_transform():
    f = NNField(np.full((4, 4), 10.0), np.full((4, 4), 20.0), np.full((4, 4), np.pi / 2),
                np.full((4, 4), 2.0), np.zeros((4, 4)))
    x, y = f.map(np.array([1.3]), np.array([2.0]))  # offset (0.3, 0) from pixel (1, 2)
    assert x[0] == pytest.approx(10.0) and y[0] == pytest.approx(20.6)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_clipped_interior_follows_its_border(seed):
    """A white square, whose inside matches any white region of B perfectly, gets the transform
    its border implies (its own copy), not the other white blob."""
    rng = np.random.default_rng(seed)
    bg = np.stack([gaussian_filter(rng.random((96, 96)), 2.5) for _ in range(3)], -1)
    b = (0.15 + 0.4 * (bg - bg.min()) / (bg.max() - bg.min())).astype(np.float32)
    b[20:40, 20:40] = 1.0                     # the square's copy
    b[60:90, 55:90] = 1.0                     # a bigger white blob elsewhere
    a = b[10:50, 10:50].copy()                # A: the square with its surroundings, scale 1
    f = patchmatch(a, b, seed=seed, scale_range=(0.5, 2.0))
    ii, jj = np.mgrid[13:27, 13:27]           # the square's fully clipped interior in A
    assert f.flat[ii, jj].all()
    hit = np.hypot(f.x[ii, jj] - (jj + 10), f.y[ii, jj] - (ii + 10)) < 2
    assert hit.mean() > 0.9


def test_resize_area_factor_and_mean():
    img = np.arange(16, dtype=np.float32).reshape(4, 4)
    out, f = resize_area(img, 2)
    assert f == 2.0 and out.shape == (2, 2)
    assert out[0, 0] == pytest.approx(np.mean([0, 1, 4, 5]))
