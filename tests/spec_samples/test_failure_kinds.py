"""Failure kinds as upstream (issue 37): a model server that dies mid-run is an ALGORITHM_FAILURE.

Upstream's ``_call_inference`` marks any failed inference at run time as an algorithm failure, and
its developer docs (advanced_component.md: "If the remote server goes down, switch to local
inference") attach the switch to ``on_algorithm_fail``. Here a real RoboML server runs in its own
process and is killed (SIGKILL, by PID) between two questions: the recipe's ``on_algorithm_fail``
chain must then switch to the backup client (a second real server) or to the local model, and the
next question must be answered. A server unreachable at configure stays a COMPONENT_FAILURE.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from agents_core import Launcher, Topic
from agents_core.actions import Action
from agents_core.clients import RoboMLHTTPClient, RoboMLWSClient
from agents_core.components import LLM
from agents_core.config import LLMConfig
from agents_core.models import TransformersLLM
from agents_core.status import HealthStatus

from ..conftest import wait_for
from ..servers.roboml_server import RoboMLTestServer

REPO = Path(__file__).resolve().parents[2]
QUESTION, ANSWER = Topic("question", "String"), Topic("answer", "String")


@contextlib.contextmanager
def roboml_process() -> Iterator[tuple[subprocess.Popen[str], int]]:
    """The RoboML double in a child process: (process, port); killed by PID on exit."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO / "src"), str(REPO)])}
    proc = subprocess.Popen([sys.executable, "-m", "tests.spec_samples.serve_roboml", "120"], cwd=REPO, env=env,
                            stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()  # bounded: the child exits after 120 s at the latest
        assert line.startswith("port "), f"the server did not start: {line!r}"
        yield proc, int(line.split()[1])
    finally:
        if proc.poll() is None:
            os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
        if proc.stdout is not None:
            proc.stdout.close()


def _kill(proc: subprocess.Popen[str]) -> None:
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(timeout=10)


def _model() -> TransformersLLM:
    return TransformersLLM(name="brain_model", checkpoint="some/llm")


def _ask(launcher: Launcher, answers: list[Any], text: str, timeout: float = 30.0) -> bool:
    before = len(answers)
    launcher.transport.create_publisher(QUESTION).publish(text)
    return wait_for(lambda: len(answers) > before, timeout=timeout)


@pytest.mark.parametrize("client_class", [RoboMLHTTPClient, RoboMLWSClient])
def test_a_server_killed_mid_run_runs_the_algorithm_fallback_to_the_backup_client(client_class: Any) -> None:
    with roboml_process() as (proc, port), RoboMLTestServer() as backup_server:
        primary = client_class(_model(), port=port, inference_timeout=5)
        backup = client_class(_model(), port=backup_server.port, inference_timeout=5)
        brain = LLM(inputs=[QUESTION], outputs=[ANSWER], model_client=primary, trigger=QUESTION,
                    component_name="brain", config=LLMConfig())
        brain.additional_model_clients = {"backup": backup}
        brain.on_algorithm_fail(Action(brain.change_model_client, args=("backup",)), max_retries=3)
        launcher = Launcher("memory")
        launcher.add_pkg(components=[brain])
        with launcher:
            answers: list[Any] = []
            launcher.transport.create_subscription(ANSWER, answers.append)
            assert _ask(launcher, answers, "first question")
            assert answers[-1] == "echo: first question" and brain.model_client is primary
            _kill(proc)
            launcher.transport.create_publisher(QUESTION).publish("asked while the server is dead")
            assert wait_for(lambda: brain.model_client is backup, timeout=30), brain.health_message
            assert _ask(launcher, answers, "after the switch")
            assert answers[-1] == "echo: after the switch"
            assert any(c.op == "inference" for c in backup_server.calls), "the backup server answered"
            assert wait_for(lambda: brain.health_status == HealthStatus.HEALTHY)


class _LLMWithSmallLocal(LLM):
    """An LLM whose built-in local model is a small in-process one (the real LocalLLM needs llama.cpp)."""

    def _deploy_local_model(self) -> None:
        def answer(inference_input: dict[str, Any]) -> dict[str, Any]:
            return {"output": "local: " + inference_input["query"][-1]["content"]}

        self.local_model = answer


def test_a_server_killed_mid_run_falls_back_to_the_local_model() -> None:
    with roboml_process() as (proc, port):
        primary = RoboMLHTTPClient(_model(), port=port, inference_timeout=5)
        brain = _LLMWithSmallLocal(inputs=[QUESTION], outputs=[ANSWER], model_client=primary, trigger=QUESTION,
                                   component_name="brain")
        brain.on_algorithm_fail(Action(brain.fallback_to_local), max_retries=1)
        launcher = Launcher("memory")
        launcher.add_pkg(components=[brain])
        with launcher:
            answers: list[Any] = []
            launcher.transport.create_subscription(ANSWER, answers.append)
            assert _ask(launcher, answers, "hello")
            _kill(proc)
            launcher.transport.create_publisher(QUESTION).publish("anyone there?")
            assert wait_for(lambda: brain.model_client is None and brain.local_model is not None, timeout=30)
            assert _ask(launcher, answers, "and now?")
            assert answers[-1] == "local: and now?"


def test_fallback_to_local_deinitializes_the_old_client() -> None:
    with RoboMLTestServer() as server:
        primary = RoboMLHTTPClient(_model(), port=server.port)
        brain = _LLMWithSmallLocal(inputs=[QUESTION], outputs=[ANSWER], model_client=primary, trigger=QUESTION)
        brain.configure()
        try:
            assert primary.initialized
            brain.fallback_to_local()
            assert not primary.initialized
            assert server.calls_of("remove_node"), "the remote model was unloaded from its server"
        finally:
            brain.shutdown()


def test_a_server_unreachable_at_configure_stays_a_component_failure() -> None:
    with roboml_process() as (proc, port):
        _kill(proc)
        brain = LLM(inputs=[QUESTION], outputs=[ANSWER], trigger=QUESTION,
                    model_client=RoboMLHTTPClient(_model(), port=port))
        fired: list[str] = []
        brain.on_component_fail(Action(lambda: fired.append("component")))
        brain.on_algorithm_fail(Action(lambda: fired.append("algorithm")))
        brain.configure()
        try:
            assert brain.health_status == HealthStatus.COMPONENT_FAILURE and fired[:1] == ["component"]
        finally:
            brain.shutdown()


@pytest.mark.parametrize("fault", ["die", "hang"])
def test_a_websocket_reply_missing_runs_the_algorithm_fallback(fault: str) -> None:
    # The WebSocket server takes the request and drops the connection mid-reply, or never answers.
    with RoboMLTestServer() as primary_server, RoboMLTestServer() as backup_server:
        primary = RoboMLWSClient(_model(), port=primary_server.port, inference_timeout=3)
        backup = RoboMLWSClient(_model(), port=backup_server.port, inference_timeout=5)
        brain = LLM(inputs=[QUESTION], outputs=[ANSWER], model_client=primary, trigger=QUESTION,
                    component_name="brain", config=LLMConfig(stream=True))
        brain.additional_model_clients = {"backup": backup}
        component_failures: list[str] = []
        brain.on_component_fail(Action(lambda: component_failures.append("component")))
        brain.on_algorithm_fail(Action(brain.change_model_client, args=("backup",)), max_retries=3)
        launcher = Launcher("memory")
        launcher.add_pkg(components=[brain])
        with launcher:
            answers: list[Any] = []
            launcher.transport.create_subscription(ANSWER, answers.append)
            primary_server.set_fault(fault, after=1, seconds=30.0)
            launcher.transport.create_publisher(QUESTION).publish("is anyone there")
            assert wait_for(lambda: brain.model_client is backup, timeout=30), brain.health_message
            assert _ask(launcher, answers, "after the switch")
            assert answers[-1] == "echo: after the switch"
            assert not component_failures


def test_the_spec_s_websocket_queue_flow_reports_a_server_killed_mid_run_as_an_algorithm_failure() -> None:
    from .streaming_chat import StreamingChat  # noqa: PLC0415 - a component written from architecture.md's text

    with roboml_process() as (proc, port):
        chat = StreamingChat(inputs=[QUESTION], outputs=[Topic("tokens", "StreamingString")], trigger=QUESTION,
                             model_client=RoboMLWSClient(_model(), port=port, inference_timeout=5),
                             component_name="chat")
        fired: list[str] = []
        chat.on_algorithm_fail(Action(lambda: fired.append("algorithm")))
        chat.on_component_fail(Action(lambda: fired.append("component")))
        launcher = Launcher("memory")
        launcher.add_pkg(components=[chat])
        with launcher:
            done: list[Any] = []
            launcher.transport.create_subscription(Topic("tokens", "StreamingString"),
                                                   lambda m: done.append(m) if m.done else None)
            launcher.transport.create_publisher(QUESTION).publish("first")
            assert wait_for(lambda: bool(done), timeout=20), chat.health_message
            _kill(proc)
            launcher.transport.create_publisher(QUESTION).publish("asked while the server is dead")
            assert wait_for(lambda: bool(fired), timeout=30), chat.health_message
            assert fired[0] == "algorithm" and "component" not in fired
            assert chat.health_status == HealthStatus.ALGORITHM_FAILURE
