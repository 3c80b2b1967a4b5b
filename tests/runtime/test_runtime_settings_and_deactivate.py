"""Hardening of the component runtime (issue 12): settings, triggers, deactivate, request lanes.

All on the memory transport; the same core paths run on Zenoh and ROS 2.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import MutableMapping
from typing import Any

import pytest
from attrs import define, field

from agents_core import Launcher, Topic
from agents_core.actions import component_action
from agents_core.clients import ModelClient
from agents_core.components import Component
from agents_core.components.model_component import ModelComponent
from agents_core.config import BaseComponentConfig, LLMConfig, ModelComponentConfig
from agents_core.errors import ConfigError, RemoteError, WiringError
from agents_core.models import Model
from agents_core.ros import QoSConfig, String
from agents_core.status import HealthStatus, LifecycleState
from agents_core.transport import MemoryTransport
from tests.conftest import wait_for
from tests.recipe_parts import Relay

# -- settings validated at construction and on set_param -----------------------------------------


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"history_size": 2.5}, r"LLMConfig.history_size must be int, got 2.5"),
    ({"max_tool_rounds": 2.5}, r"LLMConfig.max_tool_rounds must be int"),
    ({"chat_history": "no"}, r"LLMConfig.chat_history must be bool, got 'no'"),
    ({"stream": 1}, r"LLMConfig.stream must be bool"),
    ({"temperature": math.nan}, r"LLMConfig.temperature must be"),
    ({"status_rate": math.inf}, r"LLMConfig.status_rate must be"),
    ({"execution_queue_depth": True}, r"LLMConfig.execution_queue_depth must be"),
    ({"system_prompt": 3}, r"LLMConfig.system_prompt must be"),
    ({"histroy_size": 3}, r"unknown argument\(s\) 'histroy_size' \(did you mean 'history_size'\?\)"),
])
def test_config_fields_are_type_checked_and_misspelt_arguments_named(kwargs: dict[str, Any], message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        LLMConfig(**kwargs)


def test_assignment_is_checked_too_and_leaves_the_old_value() -> None:
    config = LLMConfig(history_size=4)
    with pytest.raises(ConfigError, match="must be int"):
        config.history_size = 2.5  # type: ignore[assignment]
    with pytest.raises(ConfigError, match="must be int"):
        config.update(history_size=6, max_tool_rounds=2.5)
    assert config.history_size == 4
    assert config.max_tool_rounds == 5


def test_user_configs_get_the_same_checks() -> None:
    @define(kw_only=True)
    class CameraConfig(BaseComponentConfig):
        fps: int = field(default=30)
        label: str = "cam"

    with pytest.raises(ConfigError, match=r"CameraConfig\.fps must be int"):
        CameraConfig(fps=29.97)
    with pytest.raises(ConfigError, match=r"CameraConfig\.label must be str"):
        CameraConfig(label=None)
    with pytest.raises(ConfigError, match=r"'fsp' \(did you mean 'fps'\?\)"):
        CameraConfig(fsp=10)
    assert CameraConfig(fps=15).fps == 15


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"depth": 2.5}, r"QoSConfig.depth"),
    ({"depth": 0}, r"QoSConfig.depth"),
    ({"reliability": "fast"}, r"QoSConfig.reliability must be one of"),
    ({"durability": "forever"}, r"QoSConfig.durability must be one of"),
    ({"deph": 3}, r"'deph' \(did you mean 'depth'\?\)"),
])
def test_bad_qos_values_raise_config_errors_naming_the_field(kwargs: dict[str, Any], message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        QoSConfig(**kwargs)


@pytest.mark.parametrize("rate", [math.nan, math.inf, -math.inf, 0, -1, 0.0, 1e6])
def test_absurd_trigger_rates_are_refused(rate: float) -> None:
    with pytest.raises(WiringError, match=r"'ticker': a timed trigger needs a rate > 0 Hz"):
        Relay(inputs=[Topic("a", "String")], trigger=rate, component_name="ticker")


def _serving(*components: Component) -> Launcher:
    launcher = Launcher(transport="memory")
    launcher.add_pkg(components=list(components))
    return launcher


def test_set_param_refuses_bad_types_and_applies_live_settings() -> None:
    words = Topic("words", "String")
    relay = Relay(inputs=[words], trigger=words, component_name="relay")
    with _serving(relay) as launcher:
        transport = launcher.transport
        with pytest.raises(RemoteError, match="execution_queue_depth must be int"):
            transport.request("relay/set_param", {"name": "execution_queue_depth", "value": 2.5})
        assert relay.config.execution_queue_depth == 10
        assert relay.runtime.worker is not None and relay.runtime.worker.depth == 10

        assert transport.request("relay/set_param", {"params": {"execution_queue_depth": 3,
                                                                 "queue_full_policy": "drop_newest",
                                                                 "log_level": "debug",
                                                                 "status_rate": 5.0}})["ok"] is True
        assert relay.runtime.worker.depth == 3
        assert relay.runtime.worker.policy == "drop_newest"
        assert relay.get_logger().level == logging.DEBUG
        assert relay.runtime.status_timer is not None and relay.runtime.status_timer.period == pytest.approx(0.2)
        # The status timer really runs at the new rate: ~5 status messages a second.
        seen: list[Any] = []
        transport.create_subscription(relay.status_topic, seen.append)
        time.sleep(1.1)
        assert len(seen) >= 4


class _EchoClient(ModelClient):
    """Answers with the input text; ``connect_seconds`` makes connecting slow."""

    def __init__(self, model: Any, connect_seconds: float = 0.0, **kwargs: Any) -> None:
        super().__init__(model=model, **kwargs)
        self.connect_seconds = connect_seconds
        self.calls = 0

    def _check_connection(self) -> None:
        time.sleep(self.connect_seconds)

    def _initialize(self) -> None:
        pass

    def _inference(self, inference_input: dict[str, Any]) -> MutableMapping[str, Any] | None:
        self.calls += 1
        return {"output": str(inference_input["query"])}

    def _deinitialize(self) -> None:
        pass


@define(kw_only=True)
class _EchoModel(Model):
    def _get_init_params(self) -> dict[str, Any]:
        return {}


class _Echo(ModelComponent):
    def __init__(self, **kwargs: Any) -> None:
        self.allowed_inputs = {"Required": [String]}
        self.allowed_outputs = {"Optional": [String]}
        super().__init__(**kwargs)

    def _create_input(self, *args: Any, **kwargs: Any) -> dict[str, Any] | None:
        value = next(iter(self.trig_callbacks.values())).get_output()
        return None if value is None else {"query": value}

    def _execution_step(self, **kwargs: Any) -> None:
        query = self._create_input()
        if query is not None:
            self._publish(self._call_inference(query))

    def _warmup(self, *args: Any, **kwargs: Any) -> None:
        pass


def _echo(**kwargs: Any) -> _Echo:
    words = Topic("words", "String")
    return _Echo(inputs=[words], outputs=[Topic("echo", "String")], trigger=words, component_name="echo",
                 model_client=_EchoClient(_EchoModel(name="main", checkpoint="echo")),
                 config=ModelComponentConfig(), **kwargs)


def test_configure_time_settings_are_refused_with_the_reason_while_configured() -> None:
    echo = _echo()
    with _serving(echo) as launcher:
        with pytest.raises(RemoteError, match=r"\['local_model_path'\] apply at configure only; deactivate and "
                                              r"clean up"):
            launcher.transport.request("echo/set_param", {"name": "local_model_path", "value": "/tmp/x.gguf"})
        assert echo.config.local_model_path is None
        echo.deactivate()
        echo.cleanup()
        echo.set_params(local_model_path="/tmp/x.gguf")
        assert echo.config.local_model_path == "/tmp/x.gguf"


def test_change_model_client_does_not_switch_after_its_caller_gave_up() -> None:
    backup = _EchoClient(_EchoModel(name="backup", checkpoint="echo"), connect_seconds=1.0)
    echo = _echo(additional_model_clients={"backup": backup})
    with _serving(echo) as launcher:
        main = echo.model_client
        with pytest.raises(RemoteError, match=r"did not finish within 0.3 s"):
            launcher.transport.request("echo/execute_method", {"method": "change_model_client",
                                                               "args": ["backup"], "timeout": 0.3}, timeout=5.0)
        # The switch was still connecting when its caller gave up; once done, it does not commit.
        assert wait_for(lambda: echo.worker_statistics().pending == 0, timeout=5.0)
        assert echo.model_client is main
        # Given the time, it does switch.
        reply = launcher.transport.request("echo/execute_method", {"method": "change_model_client",
                                                                   "args": ["backup"], "timeout": 5.0}, timeout=8.0)
        assert reply["result"] is True
        assert echo.model_client is backup


@pytest.mark.parametrize("timeout", [0, -1.0, math.nan, math.inf, True, "5"])
def test_request_timeouts_must_be_positive_finite_numbers(memory: MemoryTransport, timeout: Any) -> None:
    memory.create_service("svc", lambda request: {"ok": True})
    with pytest.raises(ConfigError, match=r"request to 'svc': timeout must be a finite number of seconds"):
        memory.request("svc", {}, timeout=timeout)
    with pytest.raises(ConfigError, match="timeout must be"):
        memory.request_transition("nobody", "configure", timeout=timeout)


# -- deactivate during a running step ------------------------------------------------------------


class _Gate(Component):
    """Publishes each input after waiting for ``release`` (bounded); records every step start."""

    def __init__(self, **kwargs: Any) -> None:
        self.allowed_inputs = {"Required": [String]}
        self.allowed_outputs = {"Optional": [String]}
        self.release = threading.Event()
        self.started = threading.Event()
        self.steps = 0
        super().__init__(**kwargs)

    def _execution_step(self, **kwargs: Any) -> None:
        self.steps += 1
        self.started.set()
        self.release.wait(10.0)
        value = next(iter(self.trig_callbacks.values())).get_output()
        for pub in self.publishers_dict.values():
            pub.publish(f"done:{value}")

    @component_action(description={"description": "Count a call.", "parameters": {"type": "object",
                                                                                  "properties": {}}})
    def ping(self) -> str:
        self.pings += 1
        return "pong"

    pings = 0


def _gate(name: str = "gate", finish: float = 5.0) -> _Gate:
    words = Topic(f"{name}_in", "String", qos_profile=QoSConfig(depth=2000))
    gate = _Gate(inputs=[words], outputs=[Topic(f"{name}_out", "String")], trigger=words, component_name=name,
                 config=BaseComponentConfig(step_finish_timeout=finish, execution_queue_depth=2000))
    gate.fallbacks_run: list[str] = []  # type: ignore[attr-defined]
    return gate


def test_deactivate_overtaking_a_step_discards_its_output_without_failing() -> None:
    gate = _gate(finish=0.1)
    gate.on_fail(_record_action(gate))
    with _serving(gate) as launcher:
        out: list[str] = []
        launcher.transport.create_subscription(Topic("gate_out", "String"), out.append)
        launcher.transport.create_publisher(Topic("gate_in", "String", qos_profile=QoSConfig(depth=2000))) \
            .publish("a")
        assert gate.started.wait(5.0)
        gate.deactivate()  # waits 0.1 s, then closes the outputs under the running step
        gate.release.set()
        assert wait_for(lambda: gate.overtaken_steps == 1 or gate.discarded_outputs == 1)
        assert gate.discarded_outputs == 1
        assert gate.health_status == HealthStatus.HEALTHY
        assert gate.failed_steps == 0
        assert gate.fallbacks_run == []  # type: ignore[attr-defined]
        assert out == []
        # Re-activated, it works and is healthy.
        gate.activate()
        launcher.transport.create_publisher(Topic("gate_in", "String", qos_profile=QoSConfig(depth=2000))) \
            .publish("b")
        assert wait_for(lambda: out == ["done:b"])
        assert gate.health_status == HealthStatus.HEALTHY


def _record_action(gate: _Gate) -> Any:
    from agents_core.actions import Action  # noqa: PLC0415  # only this helper needs it

    def record() -> None:
        gate.fallbacks_run.append("ran")  # type: ignore[attr-defined]

    return Action(record)


def test_deactivate_lets_a_running_step_finish_within_its_bound() -> None:
    gate = _gate(finish=5.0)
    with _serving(gate) as launcher:
        out: list[str] = []
        launcher.transport.create_subscription(Topic("gate_out", "String"), out.append)
        launcher.transport.create_publisher(Topic("gate_in", "String", qos_profile=QoSConfig(depth=2000))) \
            .publish("a")
        assert gate.started.wait(5.0)
        threading.Timer(0.2, gate.release.set).start()
        gate.deactivate()  # returns once the step has published
        assert gate.lifecycle_state == LifecycleState.INACTIVE
        assert wait_for(lambda: out == ["done:a"])
        assert gate.discarded_outputs == 0


def test_values_discarded_by_deactivate_are_counted() -> None:
    gate = _gate(finish=0.05)
    words = Topic("gate_in", "String", qos_profile=QoSConfig(depth=2000))
    with _serving(gate) as launcher:
        memory = launcher.transport
        pub = memory.create_publisher(words)
        pub.publish("first")
        assert gate.started.wait(5.0)
        for i in range(1000):
            pub.publish(str(i))
        gate.deactivate()
        gate.release.set()
        assert wait_for(lambda: gate.worker_statistics().pending == 0)
        stats = memory.statistics()["gate_in"]  # type: ignore[attr-defined]
        worker = gate.worker_statistics()
    assert stats.published == 1001
    assert stats.delivered + stats.dropped + stats.callback_errors + stats.discarded == 1001
    assert worker.submitted == stats.delivered
    assert worker.executed + worker.dropped + worker.discarded == worker.submitted
    assert stats.discarded + worker.discarded >= 990, "the queued values were discarded, and counted"
    assert gate.steps == 1


# -- one component's requests never wait for another's -------------------------------------------


def test_a_busy_component_does_not_delay_another_components_requests() -> None:
    busy, idle = _gate("busy"), _gate("idle")
    with _serving(busy, idle) as launcher:
        transport = launcher.transport
        transport.create_publisher(Topic("busy_in", "String", qos_profile=QoSConfig(depth=2000))).publish("x")
        assert busy.started.wait(5.0)
        # Flood the busy one with action requests whose callers give up after 0.3 s.
        failures: list[BaseException] = []

        def ask_busy() -> None:
            try:
                transport.request("busy/execute_method", {"method": "ping"}, timeout=0.3)
            except Exception as exc:
                failures.append(exc)

        askers = [threading.Thread(target=ask_busy) for _ in range(8)]
        for t in askers:
            t.start()
        start = time.monotonic()
        reply = transport.request("idle/execute_method", {"method": "ping"}, timeout=5.0)
        took = time.monotonic() - start
        for t in askers:
            t.join(5.0)
        assert reply == {"result": "pong"}
        assert took < 2.0, f"the idle component's request waited {took:.2f} s behind the busy one"
        assert len(failures) == 8
        # The busy component finishes; the requests whose callers gave up are never executed.
        busy.release.set()
        assert wait_for(lambda: busy.worker_statistics().pending == 0)
        time.sleep(0.3)
        assert busy.pings == 0
        assert idle.pings == 1


def test_input_statistics_are_public() -> None:
    gate = _gate()
    gate.release.set()
    with _serving(gate) as launcher:
        pub = launcher.transport.create_publisher(Topic("gate_in", "String", qos_profile=QoSConfig(depth=2000)))
        for i in range(5):
            pub.publish(str(i))
        assert wait_for(lambda: gate.input_statistics()["gate_in"].delivered == 5)
        assert gate.input_statistics()["gate_in"].dropped == 0


# -- capabilities decide, not names ----------------------------------------------------------------


def test_multiprocessing_is_refused_on_a_transport_that_lives_in_one_process() -> None:
    relay = Relay(inputs=[Topic("words", "String")], trigger=Topic("words", "String"), component_name="relay")
    launcher = Launcher(transport="memory")
    launcher.add_pkg(components=[relay], multiprocessing=True)
    with pytest.raises(ConfigError, match=r"multiprocessing=True needs a transport whose capabilities say "
                                          r"cross_process \(zenoh, ros2, rmw_zenoh\); 'memory' lives in one process"):
        launcher.start()


def test_an_action_server_needs_a_transport_with_actions() -> None:
    class Server(Component):
        @classmethod
        def _server_capable(cls) -> bool:
            return True

    from agents_core.transport.core import DriverTransport  # noqa: PLC0415
    from agents_core.transport.driver import DriverBase  # noqa: PLC0415
    from agents_core.transport.memory import MemoryDriver  # noqa: PLC0415

    class NoGoalsDriver(MemoryDriver):
        """A driver without the goal primitives (as a third party's may be): the base's defaults."""

        name = "nogoals"
        serve_goals = DriverBase.serve_goals
        send_goal = DriverBase.send_goal

    server = Server(trigger=None, run_type="ActionServer", component_name="mover")
    transport = DriverTransport(NoGoalsDriver())
    launcher = Launcher(transport=transport)
    launcher.add_pkg(components=[server])
    try:
        with pytest.raises(WiringError, match=r"'mover' runs as an action server, but the 'nogoals' transport has "
                                              r"no long-running goals"):
            launcher.start()
    finally:
        transport.close()


def test_add_pkg_refuses_unknown_arguments() -> None:
    relay = Relay(inputs=[Topic("words", "String")], trigger=Topic("words", "String"), component_name="relay")
    with pytest.raises(TypeError, match="multiprocesing"):
        Launcher(transport="memory").add_pkg(components=[relay], multiprocesing=True)  # type: ignore[call-arg]
