"""What the session's files hold, loaded: the scan (LDR, and HDR once expanded), the photo, the
asset mesh with its own materials. No GL and no UI here; loading errors are ScanlightErrors that
the viewer shows as messages.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from app.cloud import PointCloud
from app.color import luminance
from app.errors import ScanlightError
from app.io.formats import BUILTIN_MESHES, builtin_mesh
from app.material import Material
from app.settings import AssetTransform, Session

log = logging.getLogger(__name__)

DIFF_STOPS = 6.0  # the difference map's colour ramp spans 0 .. 6 stops of added light


def difference_colors(ldr: np.ndarray, hdr: np.ndarray) -> np.ndarray:
    """False colour of log2(Y_hdr / Y_ldr) per point (paper Fig. 1): black where expansion added
    nothing, through blue, green, yellow to white at DIFF_STOPS stops."""
    eps = 1e-4
    return difference_ramp(np.log2((luminance(hdr) + eps) / (luminance(ldr) + eps)))


def difference_ramp(stops_added) -> np.ndarray:
    """The difference map's colour (linear, shown raw) of ``stops_added`` stops."""
    t = np.clip(np.asarray(stops_added, np.float64) / DIFF_STOPS, 0.0, 1.0)
    stops = np.array([0.0, 0.25, 0.5, 0.75, 1.0])
    ramp = np.array([[0.01, 0.01, 0.02], [0.05, 0.15, 0.8], [0.1, 0.7, 0.2],
                     [0.95, 0.85, 0.1], [1.0, 1.0, 1.0]])
    return np.stack([np.interp(t, stops, ramp[:, c]) for c in range(3)], axis=-1).astype(np.float32)


def difference_legend() -> list[tuple[str, tuple[float, float, float]]]:
    """(text, display sRGB colour) at each whole stop 0 .. DIFF_STOPS, for the viewer's legend:
    the colours as the viewport shows them (raw colours, sRGB-encoded)."""
    from app.render.tonemap import srgb_encode
    ks = np.arange(int(DIFF_STOPS) + 1)
    rgb = srgb_encode(difference_ramp(ks))
    return [(f"+{k} EV" + (" or more" if k == DIFF_STOPS else ""), tuple(map(float, c)))
            for k, c in zip(ks, rgb)]


@dataclass
class Cloud:
    ldr: PointCloud
    hdr: PointCloud | None = None

    def colors(self, which: str) -> np.ndarray:
        if which == "hdr" and self.hdr is not None:
            return self.hdr.colors
        if which == "difference" and self.hdr is not None:
            return difference_colors(self.ldr.colors, self.hdr.colors)
        if which == "provenance":   # of the cloud that lights: grey when it has none
            from app.ui.provenance import provenance_colors
            return provenance_colors(self.lighting(which))
        return self.ldr.colors

    def false_colour(self, which: str) -> bool:
        """True when ``colors(which)`` is a false-colour map, shown raw (no exposure or tone
        mapping) and not darkened by the asset's shadow."""
        return which == "provenance" or (which == "difference" and self.hdr is not None)

    def lighting(self, which: str) -> PointCloud:
        """The cloud the asset is lit by: the HDR one once it exists, unless 'ldr' is shown."""
        if self.hdr is not None and which != "ldr":
            return self.hdr
        return self.ldr


def load_cloud_files(session: Session) -> tuple[Cloud, np.ndarray | None]:
    """(cloud, photo as linear (H, W, 3) or None)."""
    photo = None
    if session.cloud == "demo":
        from app.demo.cache import load_demo
        demo = load_demo()
        cloud = Cloud(demo.ldr)
        if session.photo == "demo":
            photo = demo.photo
    else:
        from app.io.pointcloud import load_cloud
        loaded = load_cloud(session.cloud)
        cloud = Cloud(loaded, loaded if loaded.hdr else None)
    if session.hdr_cloud:
        from app.io.pointcloud import load_cloud
        hdr = load_cloud(session.hdr_cloud)
        if len(hdr) != len(cloud.ldr):
            raise ScanlightError(session.hdr_cloud, f"HDR cloud has {len(hdr)} points but the scan "
                                                    f"has {len(cloud.ldr)}; expand this scan again")
        cloud.hdr = hdr
    if session.photo and session.photo != "demo":
        photo = load_photo(session.photo)
    return cloud, photo


def load_photo(path) -> np.ndarray:
    from app.io.exr import read_image
    return read_image(path).rgb


class Asset:
    """The normalised mesh (largest extent 1, centred), placed on demand by the transform."""

    def __init__(self, name: str):
        from app.io import mesh as meshes
        self.name = name
        if name in BUILTIN_MESHES:
            self.base = builtin_mesh(name)
        else:
            self.base = meshes.load_mesh(name, normalize=True)
        self.materials: list[Material] = [m for m in self.base.materials] or [Material()]

    def placed(self, transform: AssetTransform):
        from app.io.mesh import transform_mesh
        return transform_mesh(self.base, transform.matrix())

    @property
    def label(self) -> str:
        return self.name if self.name in BUILTIN_MESHES else Path(self.name).name


def copy_materials(mats: list[Material]) -> list[Material]:
    return [m.updated({}) for m in mats]
