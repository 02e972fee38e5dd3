"""The HDR expansion as a background task the viewer polls once per frame.

The request is app.hdr.job.ExpandRequest, the one the command line builds too: immutable, taken
when Run is pressed (the LDR cloud, the photo, the capture positions and ExpandParams from the
viewer's settings, ``ExpandRequest.from_settings``). The work runs in an app.jobs worker
*process*, not a thread: the photo's registration is thousands of small cost evaluations whose
Python between numpy calls needs the GIL, and a viewer that renders frames holds the GIL through
its GL calls, so in a thread the two starve each other (the job took 10x longer beside an
orbiting viewer; tests/ui/test_ui_engine.py runs exactly that). The viewer polls the job once per
frame and applies the result on the main thread (new splat colours, Relighter.set_cloud), so GL
never leaves the main thread, and a cancel the work does not honour in time ends the process.
``synchronous=True`` runs it inline (tests).
"""

from __future__ import annotations

import logging

from app.hdr.job import ExpandRequest, run_expand_request
from app.jobs import Job

log = logging.getLogger(__name__)


class ExpansionTask:
    """The viewer's handle on one app.jobs expansion job.

    state: running | done | failed | cancelled; ``snapshot()`` gives (state, fraction, stage)
    as of the last ``poll()`` (the viewer polls once per frame, on the main thread).
    """

    def __init__(self, request: ExpandRequest, synchronous: bool = False,
                 mode: str = "process"):
        self.request = request
        self.job = Job(run_expand_request, request, "sync" if synchronous else mode)
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
