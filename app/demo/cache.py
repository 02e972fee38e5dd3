"""The demo scene is generated once per (version, size, seed) and cached on disk."""

from __future__ import annotations

import contextlib
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
    """The demo scene, from the cache when present (a corrupt cache entry is regenerated). The
    cache only saves time: one that cannot be read or written is skipped with a warning."""
    path = cache_dir() / f"demo-v{DEMO_VERSION}-{n_points}-{seed}.npz"
    try:
        with np.load(path) as z:
            return _from_arrays(z)
    except (FileNotFoundError, NotADirectoryError):
        pass                        # not cached yet
    except Exception as exc:        # truncated, stale or unreadable: rebuild
        log.warning("%s: unreadable demo cache (%s); regenerating", path, exc)
    log.info("generating the demo scene (%d points, seed %d)...", n_points, seed)
    scene = room.build_demo(n_points, seed)
    _store(path, positions=scene.gt.positions, normals=scene.gt.normals, gt=scene.gt.colors,
           ldr=scene.ldr.colors, alpha=scene.alpha, photo=scene.photo)
    return scene


def _store(path: Path, **arrays) -> None:
    """Write a cache file beside, then rename: never half a file. A cache folder that cannot
    be written (read-only, a file, a full disk) is skipped with a warning - the work is done
    anyway, so a cache must never fail it - and no temporary is left behind."""
    tmp = path.with_name(f"{path.name}.{os.getpid()}.tmp.npz")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(tmp, **arrays)
        tmp.replace(path)
    except OSError as exc:
        log.warning("%s: cannot write the cache (%s); continuing without it", path,
                    exc.strerror or exc)
    finally:
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)     # after a failure; after the rename it is gone


def _from_arrays(z) -> room.DemoScene:
    gt = PointCloud(z["positions"], z["normals"], z["gt"], hdr=True, source="demo:room")
    ldr = PointCloud(z["positions"], z["normals"], z["ldr"], hdr=False, source="demo:ldr-scan")
    return room.DemoScene(gt, ldr, float(z["alpha"]), z["photo"], room.PHOTO_CAMERA,
                          room.CAPTURE_POSITIONS)


def _expansion_key(request) -> str:
    """What the demo expansion's result depends on: the demo scene, the capture positions, the
    parameters, and the expansion code itself (a hash of app/hdr's sources, so any change to
    the algorithm recomputes instead of showing a stale result)."""
    import dataclasses
    import hashlib
    import json

    h = hashlib.sha256()
    h.update(json.dumps({"demo": DEMO_VERSION, "points": len(request.cloud),
                         "cameras": [list(map(float, p)) for p in request.cameras],
                         "params": dataclasses.asdict(request.params)},
                        sort_keys=True, default=str).encode())
    for src in sorted((Path(__file__).resolve().parents[1] / "hdr").glob("*.py")):
        h.update(src.read_bytes())
    return h.hexdigest()[:20]


def _expansion_path(request) -> Path:
    return cache_dir() / f"demo-hdr-{_expansion_key(request)}.npz"


def load_demo_expansion(request):
    """The cached app.hdr.result.Expansion of the demo ``request`` (an ExpandRequest of the
    demo's LDR cloud and photo), or None when there is none (or it is unreadable). The HDR
    cloud carries the labels and scores as its provenance attributes, as the pipeline's does.
    A file without scores (written before they were stored) is a miss: the expansion reruns
    rather than show a provenance without its scores."""
    import json

    from app.hdr.result import PROVENANCE_ATTR, SCORE_ATTR, Expansion
    path = _expansion_path(request)
    try:
        with np.load(path) as z:
            if "scores" not in z.files:
                log.info("%s: demo expansion cache without scores; recomputing", path)
                return None
            colors, labels, scores = z["colors"], z["labels"], z["scores"]
            report = json.loads(str(z["report"]))
    except (FileNotFoundError, NotADirectoryError):
        return None                 # not computed yet
    except Exception as exc:        # truncated, stale or unreadable: recompute
        log.warning("%s: unreadable demo expansion cache (%s); recomputing", path, exc)
        return None
    ldr = request.cloud
    if (colors.shape != ldr.colors.shape or labels.shape != (len(ldr),)
            or scores.shape != (len(ldr),)):
        return None
    labels, scores = labels.astype(np.uint8), scores.astype(np.float32)
    hdr = PointCloud(ldr.positions, ldr.normals, colors, hdr=True, source="demo:hdr-expanded",
                     attributes={PROVENANCE_ATTR: labels, SCORE_ATTR: scores})
    return Expansion(hdr, report, labels, [], scores)


def store_demo_expansion(request, result) -> None:
    """Keep ``result`` for the next start (``_store``: never half a file, never fatal)."""
    import json

    from app.io.files import jsonable
    n = len(result.cloud)
    scores = (np.full(n, np.nan, np.float32) if result.scores is None
              else np.asarray(result.scores, np.float32))
    _store(_expansion_path(request), colors=np.asarray(result.cloud.colors, np.float32),
           labels=np.asarray(result.labels), scores=scores,
           report=json.dumps(jsonable(result.report)))
