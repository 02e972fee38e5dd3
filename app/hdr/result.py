"""What an expansion returns, in a module light enough to unpickle anywhere.

A process-mode job (app.jobs) sends the Expansion back pickled; keeping its class away from the
pipeline's scipy imports lets the owner unpickle it without a multi-second import on its thread.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from app.cloud import PointCloud

# point labels (Expansion.labels)
UNCHANGED, PROJECTED, POISSON, UNRESOLVED = 0, 1, 2, 3
LABEL_NAMES = {UNCHANGED: "unchanged", PROJECTED: "expanded_by_projection",
               POISSON: "filled_by_poisson", UNRESOLVED: "unresolved"}


@dataclass
class Expansion:
    cloud: PointCloud | None    # the HDR cloud (None when a job was asked not to return it)
    report: dict                # JSON-able: method, alpha, counts, timings, warnings, ...
    labels: np.ndarray          # (N,) uint8, see LABEL_NAMES
    faces: list = field(default_factory=list)  # the captured renderings (app.hdr.capture.Face)
