"""The BSH cache beside the cloud file: round trip, keys, corrupt files, atomic writes."""

from __future__ import annotations

import os

import numpy as np
import pytest

import app.pbgi.bsh_cache as cache
import app.pbgi.hierarchy as hierarchy
from app.cloud import PointCloud
from app.errors import ScanlightError


def _cloud(tmp_path, n=3000, seed=0):
    rng = np.random.default_rng(seed)
    src = tmp_path / "scan.ply"
    src.write_bytes(b"stand-in for the cloud file")
    nrm = rng.normal(size=(n, 3))
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    return PointCloud(rng.random((n, 3)) * 3 + 100.0, nrm, rng.random((n, 3)) * 50, hdr=True,
                      source=str(src))


def _caches(tmp_path):
    return sorted(p.name for p in tmp_path.iterdir() if ".bsh-" in p.name)


def _same(a, b):
    assert a.nodes.tobytes() == b.nodes.tobytes()
    assert np.array_equal(a.origin, b.origin) and a.cell_size == b.cell_size
    assert np.array_equal(a.point_node, b.point_node)
    assert a.nodes.dtype == b.nodes.dtype


def test_miss_then_hit_without_rebuilding(tmp_path, monkeypatch):
    cloud = _cloud(tmp_path)
    first = cache.load_or_build(cloud)
    assert first.stats["cache"] == "miss"
    names = _caches(tmp_path)
    assert len(names) == 1 and names[0].startswith("scan.ply.bsh-") and names[0].endswith(".npz")

    def no_build(*a, **k):
        raise AssertionError("rebuilt although the cache is valid")
    monkeypatch.setattr(hierarchy, "build_bsh", no_build)
    second = cache.load_or_build(cloud)
    assert second.stats["cache"] == "hit"
    _same(first, second)
    assert second.stats["clusters"] == first.stats["clusters"]


def test_key_depends_on_content_and_parameters(tmp_path):
    cloud = _cloud(tmp_path)
    args = (cloud.positions, cloud.normals, cloud.colors)
    k = cache.cache_key(*args)
    assert k == cache.cache_key(*(a.copy() for a in args))
    assert k == cache.cache_key(*args, tc=0.01, tn=0.98)  # defaults filled in
    assert k != cache.cache_key(*args, tc=0.02)
    assert k != cache.cache_key(*args, prune=False)
    colors = cloud.colors.copy()
    colors[7, 1] += 1e-3
    assert k != cache.cache_key(cloud.positions, cloud.normals, colors)
    with pytest.raises(TypeError):
        cache.cache_key(*args, bogus=1)


def test_other_parameters_get_their_own_file(tmp_path):
    cloud = _cloud(tmp_path)
    a = cache.load_or_build(cloud)
    b = cache.load_or_build(cloud, tc=0.5, tn=0.5)
    assert b.stats["cache"] == "miss" and len(_caches(tmp_path)) == 2
    assert len(b.nodes) <= len(a.nodes)


@pytest.mark.parametrize("damage", ["truncate", "garbage", "empty", "swap"])
def test_corrupt_cache_is_rebuilt_not_a_crash(tmp_path, damage):
    cloud = _cloud(tmp_path)
    good = cache.load_or_build(cloud)
    (path,) = [tmp_path / n for n in _caches(tmp_path)]
    data = path.read_bytes()
    if damage == "truncate":
        path.write_bytes(data[: len(data) // 2])
    elif damage == "garbage":
        path.write_bytes(os.urandom(len(data)))
    elif damage == "empty":
        path.write_bytes(b"")
    else:  # a valid cache of another cloud under this name: the key inside does not match
        rng = np.random.default_rng(9)
        h = hierarchy.build_bsh(rng.random((100, 3)), np.tile([0.0, 0, 1], (100, 1)),
                                rng.random((100, 3)))
        cache.save_hierarchy(h, path, key="0" * 24)
    with pytest.raises(ScanlightError):
        cache.load_hierarchy(path, key=cache.cache_key(cloud.positions, cloud.normals,
                                                       cloud.colors), n_points=len(cloud))
    again = cache.load_or_build(cloud)
    assert again.stats["cache"] == "rebuilt"
    _same(good, again)
    assert cache.load_or_build(cloud).stats["cache"] == "hit"  # the rewritten file is good


def test_write_is_atomic(tmp_path, monkeypatch):
    cloud = _cloud(tmp_path)

    def fail_replace(src, dst):
        raise OSError("disk full")
    monkeypatch.setattr(cache.os, "replace", fail_replace)
    h = cache.load_or_build(cloud)
    assert h.stats["cache"] == "unwritable"
    assert _caches(tmp_path) == []  # neither a half-written cache nor a temporary file
    monkeypatch.undo()
    assert cache.load_or_build(cloud).stats["cache"] == "miss"
    assert not [n for n in _caches(tmp_path) if n.endswith(".tmp")]


def test_without_a_file_there_is_no_cache(tmp_path):
    cloud = _cloud(tmp_path)
    cloud.source = "demo:room"
    assert cache.load_or_build(cloud).stats["cache"] == "off"
    assert _caches(tmp_path) == []


def test_a_changed_cloud_file_replaces_its_old_cache(tmp_path):
    cloud = _cloud(tmp_path)
    cache.load_or_build(cloud)
    old = _caches(tmp_path)
    for name in old:  # make the cache older than the (re-written) cloud file
        os.utime(tmp_path / name, (1_000_000, 1_000_000))
    cloud.colors[0] += 1.0
    assert cache.load_or_build(cloud).stats["cache"] == "miss"
    new = _caches(tmp_path)
    assert len(new) == 1 and new != old
