"""ReusedThreads: goals borrow threads, each job alone on its thread, idle threads end, close ends them."""

from __future__ import annotations

import threading
from typing import Any

from agents_core.transport import MemoryTransport
from agents_core.transport.goal_threads import ReusedThreads
from agents_core.transport.goals import GoalHandle, GoalStatus
from tests.conftest import wait_for


def _run_and_wait(pool: ReusedThreads, job: Any, name: str) -> threading.Thread:
    done = threading.Event()

    def wrapped() -> None:
        try:
            job()
        finally:
            done.set()

    thread = pool.run(wrapped, name)
    assert done.wait(5.0)
    return thread


def test_an_idle_thread_is_reused_under_the_job_name_and_renamed_between_jobs() -> None:
    pool = ReusedThreads("idle-name", idle_s=5.0)
    names: list[str] = []
    first = _run_and_wait(pool, lambda: names.append(threading.current_thread().name), "job:one")
    assert wait_for(lambda: pool.idle_count() == 1)
    assert first.name == "idle-name"
    second = _run_and_wait(pool, lambda: names.append(threading.current_thread().name), "job:two")
    assert second is first  # no new thread was started
    assert names == ["job:one", "job:two"]
    pool.close()
    first.join(5.0)
    assert not first.is_alive()


def test_jobs_that_overlap_get_threads_of_their_own() -> None:
    pool = ReusedThreads("overlap", idle_s=5.0)
    gate = threading.Event()
    seen: set[int] = set()
    started = threading.Semaphore(0)

    def job() -> None:
        seen.add(threading.get_ident())
        started.release()
        gate.wait(5.0)

    threads = [pool.run(job, f"job:{i}") for i in range(3)]
    for _ in range(3):
        assert started.acquire(timeout=5.0)
    assert len(seen) == 3 and pool.busy == 3
    gate.set()
    assert wait_for(lambda: pool.busy == 0 and pool.idle_count() == 3)
    pool.close()
    for thread in threads:
        thread.join(5.0)
        assert not thread.is_alive()


def test_an_idle_thread_ends_after_its_idle_time() -> None:
    pool = ReusedThreads("short", idle_s=0.05)
    thread = _run_and_wait(pool, lambda: None, "job")
    thread.join(5.0)
    assert not thread.is_alive()
    assert pool.idle_count() == 0
    again = _run_and_wait(pool, lambda: None, "job")  # a fresh thread takes the next job
    assert again is not thread
    pool.close()


def test_then_runs_next_on_the_same_thread_and_a_raising_job_keeps_the_thread() -> None:
    pool = ReusedThreads("then", idle_s=5.0)
    order: list[tuple[str, int]] = []
    done = threading.Event()

    def second() -> None:
        order.append((threading.current_thread().name, threading.get_ident()))
        done.set()

    def first() -> None:
        order.append((threading.current_thread().name, threading.get_ident()))
        assert pool.then(second, "job:second") is threading.current_thread()
        raise RuntimeError("the first job fails")  # logged; the queued job still runs

    pool.run(first, "job:first")
    assert done.wait(5.0)
    assert [name for name, _ in order] == ["job:first", "job:second"]
    assert order[0][1] == order[1][1]
    assert pool.then(second, "x") is None  # not on one of its threads
    assert wait_for(lambda: pool.busy == 0)
    pool.close()


def test_close_ends_idle_threads_and_refuses_jobs() -> None:
    pool = ReusedThreads("closing", idle_s=30.0)
    thread = _run_and_wait(pool, lambda: None, "job")
    assert wait_for(lambda: pool.idle_count() == 1)
    pool.close()
    thread.join(5.0)
    assert not thread.is_alive()
    try:
        pool.run(lambda: None, "late")
    except RuntimeError:
        pass
    else:
        raise AssertionError("a closed pool ran a job")


def test_goals_one_after_another_run_on_one_reused_thread_and_close_leaves_none() -> None:
    idents: list[int] = []

    def execute(handle: GoalHandle) -> dict[str, Any]:
        idents.append(threading.get_ident())
        assert threading.current_thread().name.startswith("arm:goal:")
        return {"success": True}

    before = {t.ident for t in threading.enumerate()}
    with MemoryTransport() as t:
        server = t.create_action_server("arm", "VisionLanguageAction", execute)
        for _ in range(5):
            assert t.send_goal("arm", "VisionLanguageAction", {"task": "x"}).result(5.0)[0] == GoalStatus.SUCCEEDED
            # The goal's thread goes back to the server's idle threads (renamed) before the next goal.
            assert wait_for(lambda: any(th.ident == idents[-1] and th.name == "arm:goal-idle"
                                        for th in threading.enumerate()))
        assert len(set(idents)) == 1
        server.close()
        assert wait_for(lambda: not [th for th in threading.enumerate()
                                     if th.ident not in before and th.name.startswith("arm:")], timeout=5.0)
