"""A component's services answered on the caller's thread (memory): what stays guaranteed.

On the memory transport a component's ``execute_method`` / ``set_param`` / ``describe`` run their
handler on the caller's thread (``create_service(inline=True)``, the driver's ``local_requests``),
not on the component's request lane; the action itself still runs on the component's worker.
These tests hold the guarantees the lane gave: an action never overlaps a step and runs on the
worker, a slow action blocks no other service, the caller's deadline holds, a shutdown while a
call waits answers it, and a request made while serving a request still goes through the lane.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest

from agents_core import Launcher, Topic
from agents_core.actions import component_action
from agents_core.components import Component
from agents_core.config import BaseComponentConfig
from agents_core.errors import RemoteError, RequestTimeoutError, ServiceUnavailableError
from agents_core.ros import QoSConfig, String
from agents_core.transport import MemoryTransport
from tests.conftest import wait_for

_NO_PARAMS = {"type": "object", "properties": {}}


class _Stepper(Component):
    """Steps that take a little while and flag themselves; actions that check the flag and may block."""

    def __init__(self, **kwargs: Any) -> None:
        self.allowed_inputs = {"Required": [String]}
        self.allowed_outputs = {"Optional": [String]}
        self.in_step = False
        self.steps = 0
        self.overlaps = 0
        self.action_threads: set[str] = set()
        self.step_threads: set[str] = set()
        self.step_started = threading.Event()
        self.step_release = threading.Event()
        self.step_release.set()
        self.slow_release = threading.Event()
        self.slow_started = threading.Event()
        super().__init__(**kwargs)

    def _execution_step(self, **kwargs: Any) -> None:
        self.in_step = True
        self.step_threads.add(threading.current_thread().name)
        self.step_started.set()
        try:
            self.step_release.wait(10.0)
            time.sleep(0.001)
            self.steps += 1
        finally:
            self.in_step = False

    @component_action(description={"description": "Note whether a step runs now.", "parameters": _NO_PARAMS})
    def probe(self) -> str:
        self.action_threads.add(threading.current_thread().name)
        if self.in_step:
            self.overlaps += 1
        time.sleep(0.0005)  # a step that started now would be seen by the check below
        if self.in_step:
            self.overlaps += 1
        return "ok"

    @component_action(description={"description": "Wait for the test to let go.", "parameters": _NO_PARAMS})
    def slow(self) -> str:
        self.slow_started.set()
        self.slow_release.wait(10.0)
        return "slow done"


def _stepper(name: str) -> _Stepper:
    words = Topic(f"{name}_in", "String", qos_profile=QoSConfig(depth=500))
    return _Stepper(inputs=[words], trigger=words, component_name=name,
                    config=BaseComponentConfig(execution_queue_depth=500, step_finish_timeout=0.5))


@pytest.fixture
def served() -> Iterator[tuple[Launcher, _Stepper, _Stepper]]:
    a, b = _stepper("a"), _stepper("b")
    launcher = Launcher(transport="memory")
    launcher.add_pkg(components=[a, b])
    with launcher:
        try:
            yield launcher, a, b
        finally:
            # Whatever a test left blocked, let it end before the launcher stops.
            for c in (a, b):
                c.slow_release.set()
                c.step_release.set()


def test_memory_declares_local_requests() -> None:
    transport = MemoryTransport()
    try:
        assert transport.capabilities.local_requests is True
    finally:
        transport.close()


def test_actions_asked_from_many_threads_never_overlap_a_step(served: tuple[Launcher, _Stepper, _Stepper]) -> None:
    launcher, a, _ = served
    transport = launcher.transport
    publisher = transport.create_publisher(Topic("a_in", "String", qos_profile=QoSConfig(depth=500)))
    errors: list[BaseException] = []

    def ask(n: int) -> None:
        for _ in range(n):
            try:
                assert transport.request("a/execute_method", {"method": "probe"}, timeout=10.0) == {"result": "ok"}
            except BaseException as exc:
                errors.append(exc)

    askers = [threading.Thread(target=ask, args=(40,)) for _ in range(4)]
    for t in askers:
        t.start()
    for i in range(200):
        publisher.publish(f"v{i}")
        if i % 20 == 0:
            time.sleep(0.002)
    for t in askers:
        t.join(30.0)
    assert not any(t.is_alive() for t in askers)
    assert errors == []
    assert transport.wait_for_idle(10.0)
    assert a.steps > 0, "steps ran alongside the actions"
    assert a.overlaps == 0, "an action ran while a step of the same component was running"
    # Both on the component's worker, never on a caller's or a transport's thread.
    assert a.action_threads == {"worker:a"}
    assert a.step_threads == {"worker:a"}


def test_a_slow_action_blocks_no_other_service(served: tuple[Launcher, _Stepper, _Stepper]) -> None:
    launcher, a, b = served
    transport = launcher.transport
    replies: list[Any] = []
    slow_caller = threading.Thread(
        target=lambda: replies.append(transport.request("a/execute_method", {"method": "slow"}, timeout=10.0)))
    slow_caller.start()
    try:
        assert a.slow_started.wait(5.0)
        start = time.monotonic()
        # The busy component still says what it is; another component's actions and parameters answer.
        assert transport.request("a/describe", {}, timeout=5.0)["name"] == "a"
        assert transport.request("b/execute_method", {"method": "probe"}, timeout=5.0) == {"result": "ok"}
        assert transport.request("b/set_param", {"name": "log_level", "value": "debug"}, timeout=5.0)["ok"] is True
        took = time.monotonic() - start
        assert took < 2.0, f"other services waited {took:.2f} s behind a slow action"
        assert b.action_threads == {"worker:b"}
        # The busy component's own next action waits its turn on its worker (serial): not reached in 0.3 s.
        with pytest.raises(RequestTimeoutError, match=r"did not get to the request within 0\.3 s"):
            _raise_remote_cause(transport, "a/execute_method", {"method": "probe", "timeout": 0.3})
        assert not replies, "the slow action is still running"
    finally:
        a.slow_release.set()
        slow_caller.join(5.0)
    assert replies == [{"result": "slow done"}]


def _raise_remote_cause(transport: Any, name: str, payload: dict[str, Any]) -> None:
    """Send the request and raise what the handler raised (the caller gets it as a RemoteError)."""
    try:
        transport.request(name, payload, timeout=5.0)
    except RemoteError as exc:
        assert exc.__cause__ is not None
        raise exc.__cause__ from None


def test_the_callers_deadline_holds_for_a_running_action(served: tuple[Launcher, _Stepper, _Stepper]) -> None:
    launcher, a, _ = served
    start = time.monotonic()
    with pytest.raises(RequestTimeoutError, match=r"got no reply within 0.3 s"):
        launcher.transport.request("a/execute_method", {"method": "slow"}, timeout=0.3)
    took = time.monotonic() - start
    assert took < 2.0, f"the caller waited {took:.2f} s for a 0.3 s deadline"
    assert a.slow_started.is_set()
    a.slow_release.set()
    assert wait_for(lambda: a.worker_statistics().pending == 0, timeout=5.0)


def test_an_action_queued_behind_a_step_is_answered_when_the_component_shuts_down(
        served: tuple[Launcher, _Stepper, _Stepper]) -> None:
    launcher, a, _ = served
    transport = launcher.transport
    a.step_release.clear()
    transport.create_publisher(Topic("a_in", "String", qos_profile=QoSConfig(depth=500))).publish("hold")
    assert a.step_started.wait(5.0)
    outcome: list[Any] = []

    def ask() -> None:
        try:
            outcome.append(transport.request("a/execute_method", {"method": "probe"}, timeout=5.0))
        except BaseException as exc:
            outcome.append(exc)

    caller = threading.Thread(target=ask)
    caller.start()
    assert wait_for(lambda: a.worker_statistics().pending == 2, timeout=5.0), "the action waits behind the step"
    stopper = threading.Thread(target=a.shutdown)
    stopper.start()
    time.sleep(0.1)
    a.step_release.set()
    stopper.join(5.0)
    caller.join(5.0)
    assert not stopper.is_alive() and not caller.is_alive()
    # A stopping worker runs the control items already queued before it ends.
    assert outcome == [{"result": "ok"}]
    assert a.overlaps == 0
    # Once shut down, its services are gone: a request is refused at once, not left waiting.
    start = time.monotonic()
    with pytest.raises(ServiceUnavailableError):
        transport.request("a/execute_method", {"method": "probe"}, timeout=2.0)
    assert time.monotonic() - start < 1.5


def test_a_call_waiting_on_a_stuck_worker_at_shutdown_ends_at_its_deadline(
        served: tuple[Launcher, _Stepper, _Stepper]) -> None:
    launcher, a, _ = served
    transport = launcher.transport
    a.step_release.clear()
    transport.create_publisher(Topic("a_in", "String", qos_profile=QoSConfig(depth=500))).publish("hold")
    assert a.step_started.wait(5.0)
    outcome: list[Any] = []

    def ask() -> None:
        try:
            outcome.append(transport.request("a/execute_method", {"method": "probe"}, timeout=1.0))
        except BaseException as exc:
            outcome.append(exc)

    caller = threading.Thread(target=ask)
    caller.start()
    assert wait_for(lambda: a.worker_statistics().pending == 2, timeout=5.0)
    a.runtime.hurry()  # the step never ends: shutdown gives up on it at once
    a.shutdown()
    caller.join(5.0)
    assert not caller.is_alive()
    assert len(outcome) == 1 and isinstance(outcome[0], RequestTimeoutError), outcome
    a.step_release.set()


def test_a_local_request_runs_an_inline_handler_on_the_callers_thread() -> None:
    transport = MemoryTransport()
    seen: dict[str, str] = {}

    def record(key: str) -> Any:
        def handler(request: dict[str, Any]) -> dict[str, Any]:
            seen[key] = threading.current_thread().name
            if key == "outer":
                # A request made while serving one on a lane goes through the lane as before.
                transport.request("inline_svc", {}, timeout=5.0)
            return {}
        return handler

    try:
        transport.create_service("inline_svc", record("inline"), owner="x", inline=True)
        transport.create_service("lane_svc", record("outer"), owner="y")
        transport.request("inline_svc", {}, timeout=5.0)
        assert seen["inline"] == threading.current_thread().name
        transport.request("lane_svc", {}, timeout=5.0)
        assert seen["outer"].startswith("memory-request")
        assert seen["inline"].startswith("memory-request:x")
    finally:
        transport.close()


def test_an_inline_handlers_errors_reach_the_caller_as_a_lanes_would() -> None:
    transport = MemoryTransport()

    def fails(request: dict[str, Any]) -> dict[str, Any]:
        raise ValueError("bad input")

    def late(request: dict[str, Any]) -> dict[str, Any]:
        time.sleep(0.3)
        raise RuntimeError("too late")

    try:
        transport.create_service("fails", fails, inline=True)
        transport.create_service("late", late, inline=True)
        with pytest.raises(RemoteError, match=r"'fails' failed: ValueError: bad input"):
            transport.request("fails", {}, timeout=5.0)
        with pytest.raises(RequestTimeoutError, match=r"request to 'late' got no reply within 0.1 s"):
            transport.request("late", {}, timeout=0.1)
        # The caller's timeout travels as on a lane: the handler does not see the reserved key.
        got: list[dict[str, Any]] = []
        transport.create_service("echo", lambda r: got.append(r) or {"ok": True}, inline=True)
        assert transport.request("echo", {"x": 1}, timeout=5.0) == {"ok": True}
        assert got == [{"x": 1}]
    finally:
        transport.close()
