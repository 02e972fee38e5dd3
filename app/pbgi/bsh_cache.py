"""The built BSH saved next to its cloud, so reopening a scene does not rebuild it.

``room.ply`` -> ``room.ply.bsh-<key>.npz``. The key is a SHA-256 over the cloud's content
(positions, normals, colours as stored in memory), the build parameters with their defaults
filled in, and the record layout and file format versions: a changed cloud or parameter gives a
different file name, so a stale cache is never read. Hashing is linear in the points and small next to a build.

Writes go to a temporary file in the same folder, then ``os.replace`` (atomic): a crash never
leaves a half-written cache under the final name. A cache that cannot be read (truncated,
corrupt, another version, inconsistent) is rebuilt and overwritten, never a crash; a folder that
cannot be written only costs the cache (logged). Caches of the same cloud file that are older
than the file and carry another key are removed when a new one is written (the cloud changed).
"""

from __future__ import annotations

import hashlib
import inspect
import json
import logging
import os
import tempfile
from pathlib import Path

import numpy as np

from app.errors import ScanlightError
from app.pbgi import layout
from app.pbgi.hierarchy import Hierarchy, build_bsh

FORMAT_VERSION = 1
log = logging.getLogger(__name__)


def build_params(**params) -> dict:
    """build_bsh's keyword parameters with the defaults filled in (unknown names rejected)."""
    sig = inspect.signature(build_bsh)
    full = {k: v.default for k, v in sig.parameters.items()
            if v.default is not inspect.Parameter.empty}
    unknown = set(params) - set(full)
    if unknown:
        raise TypeError(f"unknown BSH build parameters: {sorted(unknown)}")
    full.update(params)
    return full


def cache_key(positions, normals, colors, **params) -> str:
    """Hex key of a cloud's content + build parameters + format versions (24 hex digits)."""
    h = hashlib.sha256()
    h.update(json.dumps({"format": FORMAT_VERSION, "layout": layout.LAYOUT_VERSION,
                         "params": build_params(**params)}, sort_keys=True).encode())
    for a in (positions, normals, colors):
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(memoryview(a).cast("B"))
    return h.hexdigest()[:24]


def cache_path(cloud_path, key: str) -> Path:
    p = Path(cloud_path)
    return p.with_name(f"{p.name}.bsh-{key}.npz")


def save_hierarchy(h: Hierarchy, path, key: str = "") -> None:
    """Write ``h`` to ``path`` atomically (temporary file in the same folder, then rename)."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name + ".", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            words = h.nodes.view(np.uint32).reshape(-1, layout.NODE_WORDS)
            np.savez(f, format=np.int64(FORMAT_VERSION), layout=np.int64(layout.LAYOUT_VERSION),
                     key=np.array(key), words=words,
                     origin=h.origin, cell_size=np.float64(h.cell_size), point_node=h.point_node,
                     params=np.array(json.dumps(h.params)), stats=np.array(json.dumps(h.stats)))
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def load_hierarchy(path, key: str | None = None, n_points: int | None = None) -> Hierarchy:
    """Read a saved BSH; ScanlightError(path, why) when it is unreadable or inconsistent."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            if int(z["format"]) != FORMAT_VERSION or int(z["layout"]) != layout.LAYOUT_VERSION:
                raise ValueError("written by another version")
            if key is not None and str(z["key"]) != key:
                raise ValueError("key does not match the cloud")
            words = np.ascontiguousarray(z["words"], dtype=np.uint32)
            origin = np.asarray(z["origin"], dtype=np.float64)
            cell_size = float(z["cell_size"])
            point_node = np.asarray(z["point_node"], dtype=np.int32)
            params = json.loads(str(z["params"]))
            stats = json.loads(str(z["stats"]))
    except ScanlightError:
        raise
    except Exception as exc:  # zip/npz/JSON errors of every kind: the file is not usable
        raise ScanlightError(path, f"unreadable BSH cache ({type(exc).__name__}: {exc})") from None
    if words.ndim != 2 or words.shape[1] != layout.NODE_WORDS or len(words) == 0:
        raise ScanlightError(path, f"BSH cache has records of shape {words.shape}")
    nodes = words.view(layout.NODE_DTYPE).reshape(-1)
    m = len(nodes)
    skip = nodes["skip"].astype(np.int64)
    idx = np.arange(m)
    if (skip[0] != m or (skip <= idx).any() or (skip > m).any() or origin.shape != (3,)
            or (n_points is not None and len(point_node) != n_points)
            or (len(point_node) and (point_node.min() < 0 or point_node.max() >= m))):
        raise ScanlightError(path, "BSH cache is inconsistent (bad skip links or point map)")
    stats["cache"] = "hit"
    return Hierarchy(nodes=nodes, origin=origin, cell_size=cell_size, point_node=point_node,
                     params=params, stats=stats)


def _remove_stale(cloud_path: Path, keep: Path) -> None:
    try:
        cloud_mtime = cloud_path.stat().st_mtime
        for old in cloud_path.parent.glob(f"{cloud_path.name}.bsh-*.npz"):
            if old != keep and old.stat().st_mtime < cloud_mtime:
                old.unlink()
    except OSError:
        pass


def load_or_build(cloud, path=None, **params) -> Hierarchy:
    """The BSH of ``cloud`` (app.cloud.PointCloud) from the cache beside ``path``, else built.

    ``path`` defaults to ``cloud.source`` when that is an existing file; without a file there is
    no cache. ``stats["cache"]`` says what happened: "hit", "miss" (built and saved), "rebuilt"
    (the cache was unreadable), "unwritable" (built, not saved) or "off" (no file).
    """
    from app.pbgi.hierarchy import build_bsh_from_cloud

    src = path if path is not None else cloud.source
    cloud_path = Path(src) if src and Path(src).is_file() else None
    if cloud_path is None:
        h = build_bsh_from_cloud(cloud, **params)
        h.stats["cache"] = "off"
        return h
    key = cache_key(cloud.positions, cloud.normals, cloud.colors, **params)
    target = cache_path(cloud_path, key)
    status = "miss"
    if target.exists():
        try:
            return load_hierarchy(target, key=key, n_points=len(cloud))
        except ScanlightError as exc:
            log.warning("%s; rebuilding it", exc)
            status = "rebuilt"
    h = build_bsh_from_cloud(cloud, **params)
    try:
        save_hierarchy(h, target, key)
        _remove_stale(cloud_path, target)
    except OSError as exc:
        log.warning("cannot write the BSH cache %s (%s); continuing without it", target, exc)
        status = "unwritable"
    h.stats["cache"] = status
    return h
