"""What an expansion returns, in a module light enough to unpickle anywhere.

A process-mode job (app.jobs) sends the Expansion back pickled; keeping its class away from the
pipeline's scipy imports lets the owner unpickle it without a multi-second import on its thread.

Provenance: every point records where its colour came from (``labels``) and how much that source
is worth (``scores``, whose meaning depends on the label, see PROVENANCE). The expanded cloud
carries both as the per-point attributes PROVENANCE_ATTR and SCORE_ATTR (saved as PLY properties
of those names), so the viewer and a later session read them off the file.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from app.cloud import PointCloud

# point labels (Expansion.labels); the numbers are stored in files: never renumber
UNCHANGED, PROJECTED, POISSON, UNRESOLVED, REGISTERED = 0, 1, 2, 3, 4
LABEL_NAMES = {UNCHANGED: "unchanged", PROJECTED: "expanded_by_projection",
               POISSON: "filled_by_poisson", UNRESOLVED: "unresolved",
               REGISTERED: "projected_from_registered_photo"}

# label -> (short name for legends, what the score means); the score is NaN where it has none
PROVENANCE = {
    UNCHANGED: ("kept", "none: the scan's own colour (not overexposed)"),
    REGISTERED: ("photo (registered)", "quality q in [0, 1] of the registered projection"),
    PROJECTED: ("PatchMatch / ITMO", "PatchMatch SSD of the match (lower is better; NaN for ITMOs)"),
    POISSON: ("Poisson fill", "none: solved from the neighbours' values and the scan's gradients"),
    UNRESOLVED: ("unresolved", "none: no expanded neighbour; keeps the clipped scan colour"),
}
PROVENANCE_ATTR = "provenance"
SCORE_ATTR = "provenance_score"


@dataclass
class Expansion:
    cloud: PointCloud | None    # the HDR cloud (None when a job was asked not to return it)
    report: dict                # JSON-able: method, alpha, counts, timings, warnings, ...
    labels: np.ndarray          # (N,) uint8, see LABEL_NAMES
    faces: list = field(default_factory=list)  # the captured renderings (app.hdr.capture.Face)
    scores: np.ndarray | None = None  # (N,) float32, see PROVENANCE (NaN where none)
