"""The HDR expansion as a background task the viewer polls once per frame.

The request is immutable (the LDR cloud, the photo, capture positions, method and parameters are
taken when Run is pressed); the work runs in an app.jobs worker thread (numpy/scipy release the
GIL in their large operations; app.jobs documents the measurement); the viewer polls the job once
per frame and applies the result on the main thread (new splat colours, Relighter.set_cloud), so
GL never leaves the main thread. ``synchronous=True`` runs it inline (tests).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

log = logging.getLogger(__name__)

# settings key -> app.hdr.pipeline.ExpandParams field
PARAM_MAP = {"hdr.threshold_ldr": "tl", "hdr.threshold_ssd": "th", "hdr.neighbours": "k",
             "hdr.bins": "bins", "hdr.iterations": "exposure_iters", "hdr.face_size": "face_size"}


@dataclass(frozen=True)
class ExpansionRequest:
    cloud: object            # app.cloud.PointCloud (LDR)
    photo: object            # (H, W, 3) linear float32
    positions: tuple         # capture positions
    method: str
    params: dict             # ExpandParams fields

    @staticmethod
    def from_settings(cloud, photo, positions, settings) -> "ExpansionRequest":
        params = {field: settings[key] for key, field in PARAM_MAP.items()}
        return ExpansionRequest(cloud, photo, tuple(tuple(map(float, p)) for p in positions),
                                settings["hdr.method"], params)


class ExpansionTask:
    """The viewer's handle on one app.jobs expansion job.

    state: running | done | failed | cancelled; ``snapshot()`` gives (state, fraction, stage)
    as of the last ``poll()`` (the viewer polls once per frame, on the main thread).
    """

    def __init__(self, request: ExpansionRequest, synchronous: bool = False,
                 mode: str = "thread"):
        from app.jobs import ExpandRequest, Job, run_expand_request
        self.request = request
        job_req = ExpandRequest(request.cloud, request.photo, [list(p) for p in request.positions],
                                request.method, dict(request.params))
        self.job = Job(run_expand_request, job_req, "sync" if synchronous else mode)
        self.job.start()
        self.poll()

    def poll(self):
        return self.job.poll()

    @property
    def state(self) -> str:
        return self.job.state.value if self.job.state.value != "pending" else "running"

    @property
    def running(self) -> bool:
        return self.state == "running"

    @property
    def result(self):
        return self.job.result

    @property
    def error(self) -> str | None:
        return None if self.job.error is None else str(self.job.error)

    @property
    def seconds(self) -> float:
        return self.job.status().seconds

    def snapshot(self) -> tuple[str, float, str]:
        return self.state, self.job.fraction, self.job.stage

    def cancel(self) -> None:
        self.job.cancel()

    def wait(self, timeout: float | None = None) -> bool:
        self.job.wait(timeout)
        return not self.running
