"""Component and runtime behaviour that upstream recipes rely on (issue 26), one process, memory transport.

Each test names the upstream behaviour it keeps; the failure mapping follows upstream's
``model_component.py`` and its ``model_client_fallback`` recipe: a model setup that fails at
configure is a COMPONENT_FAILURE, an inference that fails at run time (the server unreachable
included, issue 37) an ALGORITHM_FAILURE, no model at all a COMPONENT_FAILURE.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import pytest

from agents_core import Launcher, Topic
from agents_core.actions import Action, component_action
from agents_core.clients import OllamaClient
from agents_core.components import LLM, MLLM, Component, ModelComponent
from agents_core.config import LLMConfig
from agents_core.errors import ConfigError, LifecycleError, WiringError
from agents_core.messages import PoseMsg
from agents_core.models import OllamaModel
from agents_core.status import HealthStatus, LifecycleState
from agents_core.supported_types import Image
from agents_core.testing.helpers import free_tcp_port, wait_for

from ..components.scripted_client import ScriptedChatClient
from ..servers.ollama_server import Fault, OllamaTestServer

QUESTION, ANSWER = Topic("question", "String"), Topic("answer", "String")
GOAL = Topic("goal_point", "PoseStamped")


@contextmanager
def running(*components: Any) -> Iterator[Launcher]:
    launcher = Launcher("memory")
    launcher.add_pkg(components=list(components))
    with launcher:
        yield launcher


def _collect(launcher: Launcher, topic: Topic) -> list[Any]:
    got: list[Any] = []
    launcher.transport.create_subscription(topic, got.append)
    return got


def _ollama(port: int) -> OllamaClient:
    return OllamaClient(OllamaModel(name="llama", checkpoint="llama3.2:1b"), port=port, inference_timeout=5)


class Echo(Component):
    """Publishes each text it gets."""

    def _execution_step(self, **kwargs: Any) -> None:
        self.publishers_dict["echo_out"].publish(self.trig_callbacks["echo_in"].get_output())


# -- 1. a pre-processor that returns None: nothing to publish ---------------------------------------


def test_a_preprocessor_returning_none_publishes_nothing_counts_it_and_keeps_the_component_healthy() -> None:
    source, out = Topic("echo_in", "String"), Topic("echo_out", "String")
    echo = Echo(inputs=[source], outputs=[out], trigger=source, component_name="echo")
    echo.add_publisher_preprocessor(out, lambda text: None if text.startswith("skip") else text.upper())
    with running(echo) as launcher:
        got = _collect(launcher, out)
        pub = launcher.transport.create_publisher(source)
        for text in ("skip me", "hello", "skip too", "bye"):
            pub.publish(text)
        assert wait_for(lambda: len(got) == 2 and echo.worker_statistics().executed >= 4)
        assert got == ["HELLO", "BYE"]
        assert echo.skipped_outputs == 2 and echo.failed_steps == 0
        assert echo.health_status == HealthStatus.HEALTHY


# -- 2. an LLM whose output is not text, with a pre-processor that converts it ----------------------


def _to_pose(text: str) -> PoseMsg | None:
    found = re.search(r"\(([-\d.]+), ([-\d.]+), ([-\d.]+)\)", text)
    if found is None:
        return None
    return PoseMsg(position=[float(v) for v in found.groups()], orientation=[0, 0, 0, 1])


def test_an_llm_with_a_pose_output_and_a_converting_preprocessor_publishes_poses() -> None:
    client = ScriptedChatClient(["Location: (1.5, -2.0, 0.0)", "I do not know that place."])
    goto = LLM(inputs=[QUESTION], outputs=[GOAL], model_client=client, trigger=QUESTION, component_name="goto")
    goto.add_publisher_preprocessor(GOAL, _to_pose)
    with running(goto) as launcher:
        poses = _collect(launcher, GOAL)
        pub = launcher.transport.create_publisher(QUESTION)
        pub.publish("go to the kitchen")
        assert wait_for(lambda: bool(poses))
        assert list(poses[0].position) == [1.5, -2.0, 0.0]
        pub.publish("go to narnia")
        assert wait_for(lambda: goto.skipped_outputs == 1)
        assert goto.health_status == HealthStatus.HEALTHY and len(poses) == 1


def test_an_llm_with_a_pose_output_and_no_preprocessor_is_refused_at_configure_naming_the_topic() -> None:
    goto = LLM(inputs=[QUESTION], outputs=[GOAL], model_client=ScriptedChatClient(), trigger=QUESTION,
               component_name="goto")
    launcher = Launcher("memory")
    launcher.add_pkg(components=[goto])
    with pytest.raises(WiringError, match=r"'goal_point'.*add_publisher_preprocessor"):
        launcher.start()
    launcher.stop()


def test_an_mllm_accepts_a_pose_output_at_construction() -> None:
    image = Topic("camera", "Image")
    vlm = MLLM(inputs=[QUESTION, image], outputs=[GOAL], model_client=ScriptedChatClient(), trigger=QUESTION)
    assert [t.name for t in vlm.outputs] == ["goal_point"]


# -- 3. a client that fails at configure: fallbacks, then configure again ----------------------------


def test_a_client_down_at_configure_runs_the_fallback_and_the_component_answers_with_the_backup() -> None:
    with OllamaTestServer(models=["llama3.2:1b"]) as backup_server:
        primary, backup = _ollama(free_tcp_port()), _ollama(backup_server.port)
        llm = LLM(inputs=[QUESTION], outputs=[ANSWER], model_client=primary, trigger=QUESTION,
                  component_name="brain", config=LLMConfig(warmup=False))
        llm.additional_model_clients = {"local_backup_client": backup}
        llm.on_component_fail(Action(llm.change_model_client, args=("local_backup_client",)), max_retries=3)
        with running(llm) as launcher:
            assert llm.lifecycle_state == LifecycleState.ACTIVE
            assert llm.model_client is backup and llm.health_status == HealthStatus.HEALTHY
            answers = _collect(launcher, ANSWER)
            launcher.transport.create_publisher(QUESTION).publish("hello")
            assert wait_for(lambda: bool(answers))
            assert answers[0] == "You said: hello"


def test_a_client_down_at_configure_without_a_fallback_comes_up_unhealthy_and_says_so(
        caplog: pytest.LogCaptureFixture) -> None:
    llm = LLM(inputs=[QUESTION], outputs=[ANSWER], model_client=_ollama(free_tcp_port()), trigger=QUESTION,
              component_name="brain")
    with caplog.at_level(logging.INFO), running(llm):
        assert llm.lifecycle_state == LifecycleState.ACTIVE
        assert llm.health_status == HealthStatus.COMPONENT_FAILURE
        assert "ClientConnectionError" in llm.health_message
    lines = [r for r in caplog.records if r.levelno == logging.WARNING and "comes up unhealthy" in r.getMessage()]
    assert len(lines) == 1 and "'brain'" in lines[0].getMessage()


def test_a_client_back_after_a_failed_configure_is_set_up_by_the_next_step() -> None:
    port = free_tcp_port()
    llm = LLM(inputs=[QUESTION], outputs=[ANSWER], model_client=_ollama(port), trigger=QUESTION,
              component_name="brain", config=LLMConfig(warmup=False))
    with running(llm) as launcher:
        assert llm.health_status == HealthStatus.COMPONENT_FAILURE
        with OllamaTestServer(models=["llama3.2:1b"]) as server:
            llm.model_client = _ollama(server.port)
            answers = _collect(launcher, ANSWER)
            launcher.transport.create_publisher(QUESTION).publish("again")
            assert wait_for(lambda: bool(answers))
            assert wait_for(lambda: llm.health_status == HealthStatus.HEALTHY)


def test_a_connection_pool_reopened_by_a_late_step_is_closed_at_shutdown() -> None:
    """A step still running when the component deactivates can reconnect after the release closed the pool
    (a client reconnects on next use); shutdown closes it again, so no socket is left to the collector."""
    with OllamaTestServer(models=["llama3.2:1b"]) as server:
        llm = LLM(inputs=[QUESTION], outputs=[ANSWER], model_client=_ollama(server.port), trigger=QUESTION,
                  component_name="brain", config=LLMConfig(warmup=False))
        client = llm.model_client
        with running(llm) as launcher:
            answers = _collect(launcher, ANSWER)
            launcher.transport.create_publisher(QUESTION).publish("hello")
            assert wait_for(lambda: bool(answers))
            llm.deactivate()
            assert client._http is None  # released: the pool is closed
            client.inference({"query": [{"role": "user", "content": "late"}]})  # the late step's request
            assert client._http is not None  # reopened
        assert client._http is None


def test_a_vla_whose_policy_server_is_down_at_start_comes_up_unhealthy_and_aborts_goals() -> None:
    from ..components.test_vla import rig  # noqa: PLC0415  (its rig needs the grpc extra)

    with rig(free_tcp_port(), inference_timeout=0.5) as r:
        assert r.vla.lifecycle_state == LifecycleState.ACTIVE
        assert r.vla.health_status == HealthStatus.COMPONENT_FAILURE
        _status, result = r.send(max_steps=5).result(timeout=20)
        assert result["success"] is False and "policy server failed" in result["message"]


def test_a_bad_config_at_configure_still_fails_start_with_a_lifecycle_or_config_error() -> None:
    class Broken(Echo):
        def custom_on_configure(self) -> None:
            raise ConfigError("a real programming error")

    source = Topic("echo_in", "String")
    launcher = Launcher("memory")
    launcher.add_pkg(components=[Broken(inputs=[source], outputs=[Topic("echo_out", "String")], trigger=source)])
    with pytest.raises((LifecycleError, ConfigError)):
        launcher.start()
    launcher.stop()


# -- 4. which failure is which ---------------------------------------------------------------------


def test_an_inference_error_answer_is_algorithm_failure_and_fires_on_algorithm_fail() -> None:
    fired: list[str] = []
    with OllamaTestServer(models=["llama3.2:1b"]) as server:
        server.add_fault(Fault(path="/api/chat", kind="status", status=500, message="model crashed"))
        llm = LLM(inputs=[QUESTION], outputs=[ANSWER], model_client=_ollama(server.port), trigger=QUESTION,
                  config=LLMConfig(warmup=False))
        llm.on_algorithm_fail(Action(lambda: fired.append("algorithm")))
        llm.on_component_fail(Action(lambda: fired.append("component")))
        with running(llm) as launcher:
            launcher.transport.create_publisher(QUESTION).publish("hi")
            assert wait_for(lambda: bool(fired))
            assert llm.health_status == HealthStatus.ALGORITHM_FAILURE and fired == ["algorithm"]


def test_a_server_that_cannot_be_reached_in_a_step_is_an_algorithm_failure() -> None:
    # As upstream's _call_inference: any failed inference at run time (issue 37).
    fired: list[str] = []
    llm = LLM(inputs=[QUESTION], outputs=[ANSWER], model_client=ScriptedChatClient(fail=True), trigger=QUESTION)
    llm.on_algorithm_fail(Action(lambda: fired.append("algorithm")))
    llm.on_component_fail(Action(lambda: fired.append("component")))
    with running(llm) as launcher:
        launcher.transport.create_publisher(QUESTION).publish("hi")
        assert wait_for(lambda: bool(fired))
        assert llm.health_status == HealthStatus.ALGORITHM_FAILURE and fired == ["algorithm"]


# -- 5. upstream names: restart, stop, broadcast_status, on_giveup, Action(description) -------------


def _echo() -> Echo:
    source = Topic("echo_in", "String")
    return Echo(inputs=[source], outputs=[Topic("echo_out", "String")], trigger=source, component_name="echo")


class FailsActivateOnce(Echo):
    """Its next activate fails once (``fail_next``), leaving it in the error state."""

    fail_next = False

    def custom_on_activate(self) -> None:
        if self.fail_next:
            self.fail_next = False
            raise RuntimeError("activate failed once")


def test_restart_stop_and_broadcast_status() -> None:
    source = Topic("echo_in", "String")
    echo = FailsActivateOnce(inputs=[source], outputs=[Topic("echo_out", "String")], trigger=source,
                             component_name="echo")
    with running(echo) as launcher:
        statuses = _collect(launcher, echo.status_topic)
        echo.broadcast_status()
        assert wait_for(lambda: any(s.lifecycle_state == "active" for s in statuses))
        echo.stop()
        assert echo.lifecycle_state == LifecycleState.INACTIVE
        echo.stop()  # nothing to do: already stopped
        echo.restart()
        assert echo.lifecycle_state == LifecycleState.ACTIVE
        echo.restart()  # from active: deactivate, activate
        assert echo.lifecycle_state == LifecycleState.ACTIVE
        echo.stop()
        echo.fail_next = True
        with pytest.raises(LifecycleError):
            echo.activate()
        assert echo.lifecycle_state == LifecycleState.ERROR
        echo.restart()  # from error: clean up, configure, activate
        assert echo.lifecycle_state == LifecycleState.ACTIVE


def test_on_giveup_accepts_max_retries_and_retries_a_raising_giveup_action() -> None:
    tries: list[int] = []

    def flaky() -> None:
        tries.append(1)
        raise RuntimeError("not yet")

    llm = LLM(inputs=[QUESTION], outputs=[ANSWER], model_client=ScriptedChatClient(fail=True), trigger=QUESTION)
    llm.on_algorithm_fail(Action(lambda: None), max_retries=1)
    llm.on_giveup(Action(flaky), max_retries=3)
    with running(llm) as launcher:
        pub = launcher.transport.create_publisher(QUESTION)
        pub.publish("one")
        pub.publish("two")
        assert wait_for(lambda: len(tries) == 3)


def test_action_description_is_accepted_and_exposed() -> None:
    action = Action(print, args=("hi",), description="say hi")
    assert action.description == "say hi" and Action(print).description is None
    with pytest.raises(ConfigError):
        Action(print, description=3)  # type: ignore[arg-type]


def test_component_description_names_the_action_type_of_an_action_server() -> None:
    class Server(Component):
        _action_type = "VisionLanguageAction"

    served = Server(inputs=[], outputs=[], trigger=None, run_type="ActionServer", component_name="served")
    assert served.component_description()["action_type"] == "VisionLanguageAction"
    assert "action_type" not in _echo().component_description()


# -- 6. a ModelComponent without a client (upstream's SecurityCamera) --------------------------------


class SecurityCamera(ModelComponent):
    """Upstream's example (docs/development/component_actions.md), with only the rename."""

    def __init__(self, **kwargs: Any) -> None:
        self._armed = False
        self.allowed_inputs = {"Required": [Image]}
        self.handled_outputs = []
        self.steps = 0
        super().__init__(**kwargs)

    @component_action
    def arm(self) -> bool:
        """Start monitoring."""
        self._armed = True
        return True

    def _execution_step(self, **kwargs: Any) -> None:
        if not self._armed:
            return
        self.steps += 1


def test_a_model_component_that_never_calls_a_model_exists_without_a_client() -> None:
    camera = Topic("camera", "Image")
    cam = SecurityCamera(inputs=[camera], trigger=camera, component_name="security_camera")
    with running(cam):
        assert cam.arm() is True
        assert cam.health_status == HealthStatus.HEALTHY
    assert cam.model_client is None


def test_a_model_component_that_builds_model_inputs_still_needs_a_client() -> None:
    with pytest.raises(WiringError, match="needs a model_client"):
        LLM(inputs=[QUESTION], outputs=[ANSWER], trigger=QUESTION)


# -- 7. positional arguments: a TypeError, as attrs' kw_only promises --------------------------------


def test_a_config_or_model_built_with_positional_arguments_raises_a_type_error() -> None:
    with pytest.raises(TypeError):
        LLMConfig(1)  # type: ignore[misc]
    with pytest.raises(TypeError):
        OllamaModel("llama", "llama3.2:1b")  # type: ignore[misc]
    with pytest.raises(ConfigError):
        LLMConfig(1)  # type: ignore[misc]


# -- 8. the float trigger is a rate here: said at construction and at start --------------------------


def test_a_fast_float_trigger_on_a_model_component_warns_once_at_construction(
        caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level(logging.INFO):
        fast = LLM(inputs=[QUESTION], outputs=[ANSWER], model_client=ScriptedChatClient(), trigger=15.0,
                   component_name="fast")
        LLM(inputs=[QUESTION], outputs=[ANSWER], model_client=ScriptedChatClient(), trigger=0.5,
            component_name="slow")
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 1
    assert "trigger=15 means 15 Hz here" in warnings[0] and "use trigger=1/15" in warnings[0]
    caplog.clear()
    with caplog.at_level(logging.INFO), running(fast):
        pass
    rate_lines = [r.getMessage() for r in caplog.records if "a timer at 15 Hz" in r.getMessage()]
    assert len(rate_lines) == 1


# -- 9. shutdown after an outside deactivate ----------------------------------------------------------


def test_shutdown_after_an_outside_deactivate_is_clean(caplog: pytest.LogCaptureFixture) -> None:
    echo = _echo()
    with caplog.at_level(logging.WARNING), running(echo):
        assert echo.runtime._external_transition("deactivate")
        assert echo.lifecycle_state == LifecycleState.INACTIVE
        echo.stop()  # what a component process does on the launcher's "deactivate" now
    assert echo.lifecycle_state == LifecycleState.FINALIZED
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING], caplog.text
