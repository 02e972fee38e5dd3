"""Background jobs for long work, shared by the viewer and the CLI.

Generic: it knows nothing of what runs (the HDR expansion's request and work function are in
app/hdr/job.py); it only moves a request in, progress and one result or error out.

A job runs ``work(request, progress, cancel)`` on an immutable request:
- ``progress(fraction, stage)`` reports a non-decreasing fraction in [0, 1] and a stage name;
- ``cancel.is_set()`` is polled by the work between chunks, which raises ``Cancelled``;
- the return value is the result; an exception comes back as a readable one-line error
  (a ScanlightError keeps its file and reason; anything else becomes "internal error: ...").

The owner polls from its own thread (``job.poll()`` once per frame, or ``job.wait()``), so
results, errors and progress callbacks never run on the worker. Modes:
- "thread": a daemon thread. numpy/scipy release the GIL in their large operations, so the
  main thread stays responsive (tests/hdr/test_jobs.py checks its worst gap while an expansion
  runs); but the photo's registration is a long run of small evaluations that need the GIL
  between numpy calls, so an owner that itself holds the GIL a lot (a viewer in GL calls)
  slows the job down many times. The command line uses a thread, the viewer a process;
- "process": a spawned process (safe beside a GL context, unlike fork); nothing shared, so
  even a GIL-bound step cannot stall the UI, and a cancel that the work does not honour within
  ``kill_after`` seconds terminates the process. It runs at a lower priority than its owner
  (PROCESS_NICENESS). Costs an interpreter start-up and the pickling of request and result;
  ``work`` must be a module-level function;
- "sync": runs inside ``start()`` (tests, scripts); cancel only works if set beforehand.
"""

from __future__ import annotations

import enum
import queue
import threading
import time
import traceback
from dataclasses import dataclass, field


class Cancelled(Exception):
    """Raised inside a job's work function when its cancel flag is set."""


class JobState(str, enum.Enum):
    PENDING = "pending"
    RUNNING = "running"
    DONE = "done"
    FAILED = "failed"
    CANCELLED = "cancelled"


FINISHED = (JobState.DONE, JobState.FAILED, JobState.CANCELLED)


@dataclass(frozen=True)
class JobStatus:
    state: JobState
    fraction: float
    stage: str
    error: str | None = None   # one line, when FAILED
    seconds: float = 0.0       # since start


def _describe(exc: BaseException) -> tuple:
    """A picklable description of an exception: ("scanlight", path, reason) or ("internal", text)."""
    from app.errors import ScanlightError

    if isinstance(exc, ScanlightError):
        return ("scanlight", type(exc).__name__, exc.path, exc.reason)
    if isinstance(exc, (OSError, MemoryError)):     # the machine refused: no bug
        from app.errors import refusal
        return ("scanlight", "ScanlightError", None, refusal(exc))
    text = " ".join(f"{type(exc).__name__}: {exc}".split())
    return ("internal", text, traceback.format_exc())


def _rebuild(desc: tuple) -> BaseException:
    from app import errors

    if desc[0] == "scanlight":
        cls = getattr(errors, desc[1], errors.ScanlightError)
        return cls(desc[2], desc[3])
    return RuntimeError(f"internal error: {desc[1]}")


def _worker_main(work, request, messages, cancel, owner: bool = False):
    """Runs in the worker (thread or process); every outcome is one message. ``owner``: run on
    the owner's own thread (mode "sync"), where Ctrl-C and SIGTERM are the owner's to handle:
    they propagate (as a "failed" message they became an internal error, exit 1, not 130)."""

    def progress(fraction, stage):
        messages.put(("progress", float(fraction), str(stage)))

    try:
        result = work(request, progress, cancel)
        messages.put(("done", result))
    except Cancelled:
        messages.put(("cancelled",))
    except (KeyboardInterrupt, SystemExit) as exc:
        if owner:
            raise
        messages.put(("failed", _describe(exc)))
    except BaseException as exc:  # noqa: BLE001 - the owner decides what to do with it
        messages.put(("failed", _describe(exc)))


# A worker process runs below the owner's priority: on a machine with few cores its start-up
# (an interpreter importing numpy and scipy) and its work would otherwise take turns with the
# viewer's frames (a 1.75 s frame on 2 cores with the same priority); the job only waits.
PROCESS_NICENESS = 10


def _process_main(requests, messages, cancel):
    """The worker process's entry: lower its priority, take the work from the queue, then run as
    a thread worker would.

    The work and its request (a whole cloud and photo) come through a queue rather than the
    Process arguments: spawn writes the arguments into the child's pipe from ``start()``, which
    then blocks the owner (a UI frame) until the child has started its interpreter and read
    them; a queue's feeder thread writes them in the background."""
    import os
    try:
        os.nice(PROCESS_NICENESS)
    except (AttributeError, OSError):   # no nice() on this platform: same priority
        pass
    work, request = requests.get()
    _worker_main(work, request, messages, cancel)


@dataclass
class Job:
    """One run of ``work`` on ``request``; see the module docstring."""

    work: object
    request: object
    mode: str = "thread"
    kill_after: float = 2.0
    state: JobState = JobState.PENDING
    fraction: float = 0.0
    stage: str = "pending"
    result: object = None
    error: BaseException | None = None
    traceback: str | None = None
    history: list = field(default_factory=list)  # every (fraction, stage) received

    def __post_init__(self):
        if self.mode not in ("thread", "process", "sync"):
            raise ValueError(f"job mode must be thread, process or sync, not {self.mode!r}")
        self._started = None
        self._finished = None
        self._cancel_time = None
        if self.mode == "process":
            import multiprocessing as mp

            self._ctx = mp.get_context("spawn")
            self._messages = self._ctx.Queue()
            self._cancel = self._ctx.Event()
        else:
            self._messages = queue.Queue()
            self._cancel = threading.Event()
        self._worker = None

    # -- control ---------------------------------------------------------------------------------
    def start(self) -> "Job":
        if self.state is not JobState.PENDING:
            raise RuntimeError("a job starts once")
        self._started = time.perf_counter()
        self.state, self.stage = JobState.RUNNING, "starting"
        if self.mode == "sync":
            _worker_main(self.work, self.request, self._messages, self._cancel, owner=True)
            self.poll()
        elif self.mode == "thread":
            self._worker = threading.Thread(target=_worker_main, name="scanlight-job", daemon=True,
                                            args=(self.work, self.request, self._messages,
                                                  self._cancel))
            self._worker.start()
        else:
            self._requests = self._ctx.Queue()     # kept: the child rebuilds it from its name
            self._worker = self._ctx.Process(target=_process_main, name="scanlight-job", daemon=True,
                                             args=(self._requests, self._messages, self._cancel))
            self._worker.start()
            self._requests.put((self.work, self.request))   # written by its feeder thread
        return self

    def cancel(self) -> None:
        """Ask the work to stop; poll() reports CANCELLED once it has."""
        if self._cancel_time is None:
            self._cancel_time = time.perf_counter()
        self._cancel.set()

    # -- observation -----------------------------------------------------------------------------
    def poll(self) -> JobStatus:
        """Apply every message received so far (non-blocking) and return the status."""
        while True:
            try:
                msg = self._messages.get_nowait()
            except queue.Empty:
                break
            except (EOFError, OSError):  # the process died mid-message
                break
            self._apply(msg)
        if self.state is JobState.RUNNING and self.mode == "process":
            self._check_process()
        return self.status()

    def status(self) -> JobStatus:
        err = None if self.error is None else str(self.error)
        end = self._finished or time.perf_counter()
        return JobStatus(self.state, self.fraction, self.stage, err,
                         0.0 if self._started is None else end - self._started)

    def wait(self, timeout: float | None = None, interval: float = 0.02) -> JobStatus:
        """Poll until finished (or ``timeout`` seconds); returns the status."""
        deadline = None if timeout is None else time.perf_counter() + timeout
        while True:
            st = self.poll()
            if st.state in FINISHED or st.state is JobState.PENDING:
                return st
            if deadline is not None and time.perf_counter() >= deadline:
                return st
            time.sleep(interval)

    @property
    def done(self) -> bool:
        return self.state in FINISHED

    # -- internals -------------------------------------------------------------------------------
    def _apply(self, msg) -> None:
        kind = msg[0]
        if self.state in FINISHED:
            return
        if kind == "progress":
            f = max(self.fraction, min(max(msg[1], 0.0), 1.0))  # never goes back
            self.fraction, self.stage = f, msg[2]
            self.history.append((f, msg[2]))
            return
        self._finished = time.perf_counter()
        if kind == "done":
            self.state, self.result, self.fraction, self.stage = JobState.DONE, msg[1], 1.0, "done"
        elif kind == "cancelled":
            self.state, self.stage = JobState.CANCELLED, "cancelled"
        else:
            self.state, self.stage = JobState.FAILED, "failed"
            self.error = _rebuild(msg[1])
            self.traceback = msg[1][2] if msg[1][0] == "internal" else None
        self._join()

    def _check_process(self) -> None:
        p = self._worker
        if p is None:
            return
        if not p.is_alive():
            # exited without a final message (killed, crashed in C code): drain once more
            time.sleep(0.05)
            try:
                while True:
                    self._apply(self._messages.get_nowait())
            except (queue.Empty, EOFError, OSError):
                pass
            if self.state is JobState.RUNNING:
                self._finished = time.perf_counter()
                if self._cancel.is_set():
                    self.state, self.stage = JobState.CANCELLED, "cancelled"
                else:
                    self.state, self.stage = JobState.FAILED, "failed"
                    self.error = RuntimeError(f"internal error: the worker process exited "
                                              f"with code {p.exitcode}")
        elif self._cancel_time is not None and \
                time.perf_counter() - self._cancel_time > self.kill_after:
            p.terminate()  # the work did not reach a cancel check in time
            p.join(1.0)
            self._finished = time.perf_counter()
            self.state, self.stage = JobState.CANCELLED, "cancelled"

    def _join(self) -> None:
        """Reap a finished worker process without blocking the owner: a process that held a
        large cloud is slow to exit, and waiting for it would freeze a UI frame."""
        if self._worker is not None and self.mode == "process":
            threading.Thread(target=self._worker.join, args=(10.0,), daemon=True).start()


def start_job(work, request, mode: str = "thread", **kw) -> Job:
    return Job(work, request, mode, **kw).start()
