"""The background job API: progress, results, errors, cancel, and the three worker modes."""

from __future__ import annotations

import time

import numpy as np
import pytest

from app.errors import ScanlightError
from app.hdr.job import ExpandRequest, run_expand_request
from app.hdr.pipeline import ExpandParams
from app.jobs import Cancelled, Job, JobState, start_job


def _counting_work(request, progress, cancel):
    n = request["steps"]
    for i in range(n):
        if cancel.is_set():
            raise Cancelled()
        time.sleep(request.get("sleep", 0.0))
        progress((i + 1) / n, f"step {i}")
    return request["steps"] * 2


def _failing_work(request, progress, cancel):
    progress(0.3, "half")
    if request == "bad input":
        raise ScanlightError("some/file.ply", "has no points")
    raise ValueError("boom\nsecond line")


def _stubborn_work(request, progress, cancel):
    progress(0.1, "sleeping")
    time.sleep(30)  # never looks at cancel
    return "late"


def test_sync_mode_runs_inside_start():
    job = Job(_counting_work, {"steps": 5}, "sync").start()
    assert job.state is JobState.DONE and job.result == 10
    fr = [f for f, _ in job.history]
    assert fr == [0.2, 0.4, 0.6, 0.8, 1.0]


def test_thread_mode_delivers_result_and_monotone_progress():
    job = start_job(_counting_work, {"steps": 20, "sleep": 0.005}, "thread")
    st = job.wait(timeout=10)
    assert st.state is JobState.DONE and job.result == 40 and st.fraction == 1.0
    fr = [f for f, _ in job.history]
    assert len(fr) == 20 and np.all(np.diff(fr) >= 0)


def test_progress_never_goes_back():
    def wobbly(req, progress, cancel):
        for f in (0.1, 0.5, 0.3, 0.6):
            progress(f, "x")
        return 1
    job = Job(wobbly, None, "sync").start()
    assert [f for f, _ in job.history] == [0.1, 0.5, 0.5, 0.6]


@pytest.mark.parametrize("mode", ["sync", "thread"])
def test_errors_come_back_readable(mode):
    job = start_job(_failing_work, "bad input", mode)
    st = job.wait(timeout=10)
    assert st.state is JobState.FAILED and isinstance(job.error, ScanlightError)
    assert job.error.path == "some/file.ply" and st.error == "some/file.ply: has no points"
    job = start_job(_failing_work, "bug", mode)
    st = job.wait(timeout=10)
    assert st.state is JobState.FAILED and st.error == "internal error: ValueError: boom second line"
    assert "Traceback" in job.traceback and "boom" in job.traceback


def test_cancel_within_a_second_in_a_thread():
    job = start_job(_counting_work, {"steps": 1000, "sleep": 0.01}, "thread")
    time.sleep(0.1)
    t0 = time.perf_counter()
    job.cancel()
    st = job.wait(timeout=5)
    assert st.state is JobState.CANCELLED and time.perf_counter() - t0 < 1.0
    assert job.result is None


def _niceness_work(request, progress, cancel):
    import os
    return os.nice(0)


def test_a_worker_process_runs_below_its_owner():
    """The viewer's frames keep the cores: the worker process is PROCESS_NICENESS nicer."""
    import os

    from app.jobs import PROCESS_NICENESS
    job = start_job(_niceness_work, None, "process")
    assert job.wait(timeout=60).state is JobState.DONE
    assert job.result == min(os.nice(0) + PROCESS_NICENESS, 19)


def test_process_mode_result_error_and_forced_cancel():
    job = start_job(_counting_work, {"steps": 3}, "process")
    st = job.wait(timeout=60)
    assert st.state is JobState.DONE and job.result == 6
    job = start_job(_failing_work, "bad input", "process")
    assert job.wait(timeout=60).state is JobState.FAILED
    assert isinstance(job.error, ScanlightError) and job.error.reason == "has no points"
    # a work function that never checks its cancel flag is terminated after kill_after
    job = Job(_stubborn_work, None, "process", kill_after=0.5).start()
    while job.poll().fraction < 0.1:
        time.sleep(0.05)
    t0 = time.perf_counter()
    job.cancel()
    st = job.wait(timeout=10)
    assert st.state is JobState.CANCELLED and time.perf_counter() - t0 < 2.0


@pytest.fixture(scope="module")
def demo():
    from app.demo.cache import load_demo
    return load_demo(50_000)


def test_expansion_job_keeps_the_main_thread_responsive(demo):
    """While the expansion runs in a thread the owner's loop keeps ticking: numpy and scipy
    release the GIL in their large operations and the pipeline has no long pure-Python loop."""
    req = ExpandRequest(demo.ldr, demo.photo, demo.capture_positions,
                        ExpandParams(face_size=256))
    job = start_job(run_expand_request, req, "thread")
    gaps, last = [], time.perf_counter()
    while not job.done:
        job.poll()
        time.sleep(0.005)
        now = time.perf_counter()
        gaps.append(now - last)
        last = now
    assert job.state is JobState.DONE, job.error
    assert job.result.cloud is not None and len(job.result.cloud) == len(demo.ldr)
    assert max(gaps) < 0.25, max(gaps)
    fr = [f for f, _ in job.history]
    assert np.all(np.diff(fr) >= 0) and fr[-1] == 1.0


def test_cancelled_expansion_job_writes_nothing(demo, tmp_path):
    out = tmp_path / "hdr.ply"
    req = ExpandRequest(demo.ldr, demo.photo, demo.capture_positions,
                        ExpandParams(face_size=256), out_path=str(out),
                        report_path=str(tmp_path / "r.json"))
    job = start_job(run_expand_request, req, "thread")
    while job.poll().stage not in ("expand", "project", "poisson") and not job.done:
        time.sleep(0.01)
    t0 = time.perf_counter()
    job.cancel()
    st = job.wait(timeout=5)
    assert st.state is JobState.CANCELLED and time.perf_counter() - t0 < 1.0
    assert list(tmp_path.iterdir()) == []


def test_request_is_immutable(demo):
    req = ExpandRequest(demo.ldr, demo.photo, list(demo.capture_positions))
    assert isinstance(req.cameras, tuple) and req.method == req.params.method == "pmatch-rgb"
    with pytest.raises(AttributeError):
        req.params = ExpandParams(method="landis")
    with pytest.raises(TypeError, match="ExpandParams"):
        ExpandRequest(demo.ldr, demo.photo, demo.capture_positions, {"face_size": 256})


def test_request_from_the_viewers_settings():
    """The viewer's request takes every hdr.* setting (no hand-written settings-to-field map)."""
    from app.settings import Settings
    s = Settings()
    s.set("hdr.threshold_ldr", 0.8)
    s.set("hdr.method", "landis")
    s.set("hdr.face_size", 64)
    req = ExpandRequest.from_settings(None, None, [np.array([0.0, 1.0, 2.0])], s)
    assert req.params == ExpandParams(threshold_ldr=0.8, method="landis", face_size=64)
    assert req.cameras == ((0.0, 1.0, 2.0),)


def test_expansion_job_in_a_process(demo):
    """The request and its ExpandParams pickle: the process worker runs the same job."""
    import pickle
    from app.cloud import PointCloud
    small = PointCloud(demo.ldr.positions[::10], demo.ldr.normals[::10],
                       demo.ldr.colors[::10], False)
    req = ExpandRequest(small, demo.photo, demo.capture_positions,
                        ExpandParams(method="landis-pc"), return_cloud=False)
    assert pickle.loads(pickle.dumps(req)).params == req.params
    job = start_job(run_expand_request, req, "process")
    st = job.wait(timeout=120)
    assert st.state is JobState.DONE, st.error
    assert job.result.cloud is None and job.result.report["method"] == "landis-pc"
