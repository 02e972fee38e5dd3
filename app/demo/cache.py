"""The demo scene is generated once per (version, size, seed) and cached on disk."""

from __future__ import annotations

import logging
import os
from pathlib import Path

import numpy as np

from app.cloud import PointCloud
from app.demo import room

log = logging.getLogger(__name__)
DEMO_VERSION = 1  # bump when room.py changes what it generates


def cache_dir() -> Path:
    root = os.environ.get("SCANLIGHT_CACHE") or os.path.join(
        os.environ.get("XDG_CACHE_HOME", os.path.expanduser("~/.cache")), "scanlight")
    return Path(root)


def load_demo(n_points: int = 200_000, seed: int = 0) -> room.DemoScene:
    """The demo scene, from the cache when present (a corrupt cache entry is regenerated)."""
    path = cache_dir() / f"demo-v{DEMO_VERSION}-{n_points}-{seed}.npz"
    if path.is_file():
        try:
            with np.load(path) as z:
                return _from_arrays(z)
        except Exception as exc:  # truncated or stale: rebuild
            log.warning("%s: unreadable demo cache (%s); regenerating", path, exc)
    log.info("generating the demo scene (%d points, seed %d)...", n_points, seed)
    scene = room.build_demo(n_points, seed)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + f".{os.getpid()}.tmp.npz")
    np.savez(tmp, positions=scene.gt.positions, normals=scene.gt.normals, gt=scene.gt.colors,
             ldr=scene.ldr.colors, alpha=scene.alpha, photo=scene.photo)
    tmp.replace(path)
    return scene


def _from_arrays(z) -> room.DemoScene:
    gt = PointCloud(z["positions"], z["normals"], z["gt"], hdr=True, source="demo:room")
    ldr = PointCloud(z["positions"], z["normals"], z["ldr"], hdr=False, source="demo:ldr-scan")
    return room.DemoScene(gt, ldr, float(z["alpha"]), z["photo"], room.PHOTO_CAMERA,
                          room.CAPTURE_POSITIONS)
