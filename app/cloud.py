"""The point cloud held in memory: one layout shared by I/O, HDR expansion and the hierarchy."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class PointCloud:
    """Points of a scanned room.

    positions: (N, 3) float64 metres (float64 so that scans offset by 1e6 m keep mm precision);
    normals: (N, 3) float32 unit vectors; colors: (N, 3) float32 *linear* RGB radiance.
    ``hdr`` is False while the colours are a clipped LDR scan (sRGB-decoded, in [0, 1]).
    ``attributes``: optional per-point arrays by name, each of length N (e.g. the HDR expansion's
    provenance, app.hdr.result.PROVENANCE_ATTR / SCORE_ATTR); save_cloud writes 1-D uint8, int32
    and float ones as PLY vertex properties. Last field, so positional construction stays as is.
    """

    positions: np.ndarray
    normals: np.ndarray
    colors: np.ndarray
    hdr: bool = False
    source: str | None = None
    report: dict = field(default_factory=dict)  # what the loader fixed (dropped NaN, clamped, ...)
    attributes: dict[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self):
        self.positions = np.ascontiguousarray(self.positions, dtype=np.float64).reshape(-1, 3)
        self.normals = np.ascontiguousarray(self.normals, dtype=np.float32).reshape(-1, 3)
        self.colors = np.ascontiguousarray(self.colors, dtype=np.float32).reshape(-1, 3)
        n = len(self.positions)
        if len(self.normals) != n or len(self.colors) != n:
            raise ValueError("positions, normals and colors must have the same length")
        attrs = {}
        for name, values in dict(self.attributes or {}).items():
            values = np.asarray(values)
            if not isinstance(name, str) or not name:
                raise ValueError(f"point attribute names must be non-empty strings, got {name!r}")
            count = len(values) if values.ndim else 0
            if values.ndim == 0 or count != n:
                raise ValueError(f"point attribute {name!r} has {count} values but the cloud has "
                                 f"{n} points")
            attrs[name] = values
        self.attributes = attrs

    def __len__(self) -> int:
        return len(self.positions)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return self.positions.min(axis=0), self.positions.max(axis=0)

    def subset(self, index) -> "PointCloud":
        return PointCloud(self.positions[index], self.normals[index], self.colors[index],
                          self.hdr, self.source, dict(self.report),
                          {k: v[index] for k, v in self.attributes.items()})
