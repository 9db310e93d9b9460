"""The one job runner (pickplan.core.runner): job order kept, failures recorded, the same results in
this process and in a pool of two spawned workers, completion order, and the progress bar."""

import io
import math
import os
import time

import pytest

from pickplan.core.runner import JobFailure, OnError, Order, Runner, progress_bar, run_jobs


def _root_or_fail(x):
    """Module level, so spawned workers can import it; math.sqrt raises on negative numbers."""
    return (x, math.sqrt(x), os.getpid())


def _wait_for_marker(job):
    """Job "first" finishes only once the caller has received job "second" (it leaves a marker)."""
    name, marker = job
    deadline = time.monotonic() + 120.0
    while name == "first" and not os.path.exists(marker):
        if time.monotonic() > deadline:
            raise TimeoutError("the caller never received the second job")
        time.sleep(0.01)
    return name


JOBS = [4.0, 9.0, -1.0, 2.25, 0.0, 16.0, -4.0]


def _check_results(pairs):
    assert [job for job, _ in pairs] == JOBS  # order kept
    for job, out in pairs:
        if job < 0:
            assert isinstance(out, JobFailure) and out.error == "ValueError: math domain error"
        else:
            assert out[:2] == (job, math.sqrt(job))


def test_in_process_keeps_order_and_records_failures():
    with Runner(workers=1) as runner:
        pairs = list(runner.map(_root_or_fail, JOBS, errors=OnError.RECORD))
    _check_results(pairs)
    assert {out[2] for _, out in pairs if not isinstance(out, JobFailure)} == {os.getpid()}


@pytest.mark.parametrize("chunksize", [1, 3])
def test_pool_of_two_gives_the_in_process_results(chunksize):
    serial = run_jobs(_root_or_fail, JOBS, workers=1, errors=OnError.RECORD)
    with Runner(workers=2) as runner:
        pairs = list(runner.map(_root_or_fail, JOBS, errors=OnError.RECORD, chunksize=chunksize))
        again = list(runner.map(_root_or_fail, JOBS[:2]))  # the pool is reused for a second map
    _check_results(pairs)
    strip = lambda out: out if isinstance(out, JobFailure) else out[:2]  # noqa: E731
    assert [strip(out) for _, out in pairs] == [strip(out) for out in serial]
    assert os.getpid() not in {out[2] for _, out in pairs if not isinstance(out, JobFailure)}
    assert [out[:2] for _, out in again] == [(4.0, 2.0), (9.0, 3.0)]


@pytest.mark.parametrize("workers", [1, 2])
def test_a_raising_job_stops_the_map_by_default(workers):
    with pytest.raises(ValueError, match="math domain error"):
        run_jobs(_root_or_fail, [1.0, -1.0, 4.0], workers=workers)


def test_completion_order_yields_what_finished_first(tmp_path):
    marker = str(tmp_path / "caller-has-second")
    received = []
    with Runner(workers=2) as runner:
        for _, out in runner.map(_wait_for_marker, [("first", marker), ("second", marker)], Order.COMPLETION):
            received.append(out)
            open(marker, "w").close()
    assert received == ["second", "first"]  # job order would wait for "first" forever (until its timeout)


def test_progress_bar_counts_jobs_and_stays_quiet_when_asked():
    shown = io.StringIO()
    list(Runner().map(abs, [-1, 2, -3], progress=True, label="demo", stream=shown, done=2, total=5))
    assert "demo" in shown.getvalue() and "5/5" in shown.getvalue()
    for enabled in (False, None):  # None: only on a terminal, and a StringIO is not one
        quiet = io.StringIO()
        list(Runner().map(abs, [-1, 2], progress=enabled, stream=quiet))
        assert quiet.getvalue() == ""
    with progress_bar(4, "left", True, shown) as bar:
        bar.update(4)
    assert "4/4" in shown.getvalue() and "<00:00" in shown.getvalue()  # the time left is shown
    late = io.StringIO()  # a delayed bar: work done sooner shows nothing
    with progress_bar(4, "late", True, late, delay=60.0) as bar:
        bar.update(4)
    assert late.getvalue() == ""


def test_bad_arguments_are_clear():
    with pytest.raises(ValueError, match="chunksize"):
        list(Runner().map(abs, [1], chunksize=0))
    with pytest.raises(TypeError, match="Order and OnError"):
        list(Runner().map(abs, [1], order="jobs"))
    with pytest.raises(ValueError, match="workers"):
        Runner(workers=1.5)
    with pytest.raises(ValueError, match="ray"):
        Runner(ray="")
    assert run_jobs(abs, []) == []
