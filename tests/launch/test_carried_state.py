"""What a recipe sets on a component after building it reaches the component's own process.

In this process: the spec carries setup calls (``register_tool``, prompts, processors), attributes
assigned after construction (``additional_model_clients``) and an Event trigger; a lambda is refused
at ``add_pkg`` naming the component, the call and the function; the launcher's upstream forms
(``on_fail(action_name=...)``, ``fallback_rate``, ``Launcher()`` with ``multiprocessing=True``).
With real processes on Zenoh (loopback, no multicast): ``carried_recipe.py``, upstream's
``model_client_fallback.py`` shape with a class from a module next to it, started from another
directory, and an Event-triggered component in its own process.
"""

from __future__ import annotations

import json
import logging
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from agents_core import Topic
from agents_core.actions import Action
from agents_core.clients.ollama import OllamaClient
from agents_core.components.llm import LLM
from agents_core.errors import ConfigError
from agents_core.launch import launcher as launcher_module
from agents_core.launch.launcher import Launcher
from agents_core.launch.spec import ComponentSpec, check_rebuild
from agents_core.models import OllamaModel
from agents_core.testing.helpers import free_tcp_port
from agents_core.testing.pairs import skip_unless_installed

from .carried_components import lookup, tag_answer
from .helpers import alive, child_pids, wait_for
from .mp_recipe import Shout

HERE = Path(__file__).resolve().parent


def _client(port: int = 9, name: str = "m") -> OllamaClient:
    return OllamaClient(OllamaModel(name=name, checkpoint="llama3.2:1b"), port=port)


def _brain() -> LLM:
    query = Topic("q", "String")
    return LLM(inputs=[query], outputs=[Topic("answer", "String")], model_client=_client(),
               trigger=query, component_name="brain")


def _round_trip(component: Any) -> Any:
    spec = ComponentSpec.from_component(component, "zenoh", {}, os.getpid())
    check_rebuild(component, spec)
    return ComponentSpec.from_dict(json.loads(json.dumps(spec.to_dict()))).build()


def test_state_set_after_construction_is_rebuilt_in_the_spec() -> None:
    brain = _brain()
    backup = _client(11434, "backup")
    brain.additional_model_clients = {"local_backup_client": backup}
    brain.set_topic_prompt(Topic("q", "String"), "Q: {{ q }}")
    brain.set_component_prompt("all: {{ q }}")
    brain.add_publisher_preprocessor("answer", tag_answer)
    brain.add_callback_postprocessor("q", str.strip)
    brain.register_tool(lookup, {"name": "lookup", "description": "d"}, send_tool_response_to_model=True)
    brain.on_fail(Action(brain.change_model_client, args=("local_backup_client",)))
    rebuilt = _round_trip(brain)
    assert rebuilt.additional_model_clients == {"local_backup_client": backup}
    assert rebuilt._topic_templates["q"].render(q="x") == "Q: x"
    assert rebuilt._component_template.render(q="x") == "all: x"
    assert rebuilt.publishers_dict["answer"]._preprocessors == [tag_answer]
    assert rebuilt.trig_callbacks["q"]._postprocessors == [str.strip]
    assert rebuilt._tools["lookup"].func is lookup and rebuilt._tools["lookup"].send_back is True
    rebuilt.change_model_client  # noqa: B018  # the fallback's method exists there
    assert list(rebuilt.runtime.health.fallbacks) == ["any"]


def test_constructor_calls_are_not_replayed_twice() -> None:
    component = Shout("in_t", "out_t", "shout")
    component.add_publisher_preprocessor("out_t", tag_answer)
    rebuilt = _round_trip(component)
    assert rebuilt.publishers_dict["out_t"]._preprocessors == [tag_answer]


def test_a_public_attribute_set_after_construction_is_carried_or_refused_by_name() -> None:
    component = Shout("in_t", "out_t", "shout")
    component.fallback_rate = 0.1  # upstream recipes set this on components
    assert _round_trip(component).fallback_rate == 0.1
    component.helper = object()
    with pytest.raises(ConfigError, match=r"component 'shout': attribute 'helper' \(set after construction\)"):
        check_rebuild(component, ComponentSpec.from_component(component, "zenoh", {}, os.getpid()))


def test_lambda_and_closure_are_refused_at_add_pkg_naming_component_topic_and_function() -> None:
    brain = _brain()
    brain.add_publisher_preprocessor("answer", lambda text: text)
    with pytest.raises(ConfigError, match=r"component 'brain': add_publisher_preprocessor\('answer', \.\.\.\): "
                                          r".*<lambda> is a lambda: .*top level of a module or of the recipe"):
        Launcher(transport="zenoh").add_pkg(components=[brain], multiprocessing=True)

    def shout(text: str) -> str:
        return text.upper()

    brain = _brain()
    brain.register_tool(shout, {"name": "shout", "description": "d"})
    with pytest.raises(ConfigError, match=r"component 'brain': register_tool\(\.\.\.\): .*shout is a function "
                                          "defined inside another function"):
        Launcher(transport="zenoh").add_pkg(components=[brain], multiprocessing=True)
    Launcher(transport="memory").add_pkg(components=[brain])  # one process: fine


def test_launcher_on_fail_gives_each_component_the_named_method_and_refuses_a_missing_one() -> None:
    a, b = Shout("in_a", "out_a", "a"), Shout("in_b", "out_b", "b")
    launcher = Launcher(transport="memory")
    launcher.add_pkg(components=[a, b])
    launcher.on_fail(action_name="set_suffix", max_retries=2)
    launcher.fallback_rate = 1 / 10
    with launcher:
        for c in (a, b):
            fallback = c.runtime.health.fallbacks["any"]
            assert [act.name for act in fallback.actions] == ["set_suffix"] and fallback.max_retries == 2
    launcher = Launcher(transport="memory")
    launcher.add_pkg(components=[Shout("in_c", "out_c", "c")])
    launcher.on_fail(action_name="no_such_method")
    with pytest.raises(ConfigError, match="component 'c' \\(Shout\\) has no method 'no_such_method'"):
        launcher.start()
    with pytest.raises(ConfigError, match="fallback_rate must be a rate in Hz > 0"):
        launcher.fallback_rate = 0


def test_fallback_rate_is_said_to_be_no_polling_rate(caplog: pytest.LogCaptureFixture) -> None:
    launcher = Launcher(transport="memory")
    launcher.add_pkg(components=[Shout("in_d", "out_d", "d")])
    launcher.fallback_rate = 0.1
    with caplog.at_level(logging.WARNING, logger="agents_core.launch.launcher"), launcher:
        pass
    assert "fallback_rate=0.1 Hz is not a polling rate here" in caplog.text


def test_default_launcher_with_multiprocessing_runs_in_one_process_without_a_cross_process_transport(
        monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture) -> None:
    monkeypatch.delenv("AGENTS_TRANSPORT", raising=False)
    monkeypatch.setattr(launcher_module, "cross_process_transports", list)
    component = Shout("in_e", "out_e", "e")
    launcher = Launcher()
    launcher.add_pkg(components=[component], multiprocessing=True)
    with caplog.at_level(logging.WARNING, logger="agents_core.launch.launcher"), launcher:
        assert launcher.supervisor is None and launcher.transport.name == "memory" and launcher.all_active()
    assert "running every component in this one process" in caplog.text


def test_default_launcher_with_multiprocessing_picks_zenoh_and_says_so(
        monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture) -> None:
    monkeypatch.delenv("AGENTS_TRANSPORT", raising=False)
    monkeypatch.setattr(launcher_module, "cross_process_transports", lambda: ["zenoh"])
    launcher = Launcher()
    launcher.add_pkg(components=[Shout("in_f", "out_f", "f")], multiprocessing=True)
    with caplog.at_level(logging.INFO, logger="agents_core.launch.launcher"):
        launcher._choose_default_transport()
    assert launcher._transport_spec == "zenoh"
    assert "no transport named: running the component processes on 'zenoh'" in caplog.text


# --- real processes on Zenoh ---------------------------------------------------------------------


@pytest.fixture
def observer_factory() -> Iterator[Any]:
    skip_unless_installed("zenoh")
    opened = []

    def make(port: int) -> Any:
        from agents_zenoh.transport import ZenohTransport  # noqa: PLC0415  # needs the zenoh extra

        t = ZenohTransport(mode="peer", listen=["tcp/127.0.0.1:0"], connect=[f"tcp/127.0.0.1:{port}"],
                           multicast_scouting=False, zenoh_options={"scouting/delay": 50})
        opened.append(t)
        return t

    yield make
    for t in opened:
        t.close()


def _stop(proc: subprocess.Popen[bytes]) -> None:
    kids = child_pids(proc.pid)
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout=20.0)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=5.0)
    for pid in kids:
        if alive(pid):
            os.kill(pid, 9)


def _published(observer: Any, topic: str, trigger: Any, match: Any, timeout: float, what: str) -> str:
    """Call ``trigger()`` every half second until a value on ``topic`` satisfies ``match``."""
    got: list[str] = []
    sub = observer.create_subscription(Topic(topic, "String"), got.append)
    try:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            trigger()
            until = time.monotonic() + 0.5
            while time.monotonic() < until:
                for value in list(got):
                    if match(value):
                        return value
                time.sleep(0.02)
        raise AssertionError(f"timed out waiting for {what} (got {got})")
    finally:
        sub.close()


@pytest.mark.slow
@pytest.mark.zenoh
def test_upstream_fallback_recipe_and_event_trigger_run_in_processes_from_another_directory(
        tmp_path: Path, observer_factory: Any) -> None:
    from tests.servers.ollama_server import OllamaTestServer  # noqa: PLC0415

    port = free_tcp_port()
    with OllamaTestServer(models=["llama3.2:1b"]) as primary, OllamaTestServer(models=["llama3.2:1b"]) as backup:
        err = (tmp_path / "launcher.err").open("wb")
        env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
        env["PYTHONPATH"] = str(HERE.parents[1] / "src")  # the package under test; not the recipe's directory
        proc = subprocess.Popen([sys.executable, str(HERE / "carried_recipe.py"), "--port", str(port),
                                 "--primary", str(primary.port), "--backup", str(backup.port)],
                                cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=err, env=env)
        try:
            observer = observer_factory(port)

            def log() -> str:
                err.flush()
                return (tmp_path / "launcher.err").read_text(errors="replace")[-4000:]

            def both_active() -> bool:
                if proc.poll() is not None:
                    raise AssertionError(f"the launcher exited with {proc.returncode}:\n{log()}")
                states = [observer.get_component_state(n, timeout=0.5) for n in ("brain", "ticker")]
                return all(s is not None and s.lifecycle_state == "active" for s in states)

            wait_for(both_active, timeout=60.0, what="brain and ticker active")
            children = set(child_pids(proc.pid))
            ask = observer.create_publisher(Topic("carry/query", "String"))
            answer = _published(observer, "carry/answer", lambda: ask.publish("hello"),
                                lambda v: "hello" in v, 20.0, "the primary's answer")
            # The topic prompt and the pre-processor, set after construction, ran in brain's process.
            assert answer.startswith("You said: Q: hello <tagged by ")
            assert int(answer.rsplit(" ", 1)[1].rstrip(">")) in children
            assert primary.requests_to("/api/chat") and not backup.requests_to("/api/chat")
            tools = primary.requests_to("/api/chat")[0].json.get("tools")
            assert tools and tools[0]["function"]["name"] == "lookup"
            primary.stop()  # the primary's server goes down: the fallback switches to the backup client
            answer = _published(observer, "carry/answer", lambda: ask.publish("again"),
                                lambda v: "again" in v, 30.0, "the backup's answer")
            assert answer.startswith("You said: Q: again <tagged by ") and backup.requests_to("/api/chat")
            assert "now using model client 'local_backup_client'" in log()
            # The event is evaluated in the launcher; the ticker steps in its own process.
            go = observer.create_publisher(Topic("carry/go", "String"))
            tick = _published(observer, "carry/tick", lambda: go.publish("go"), lambda v: True, 20.0, "a tick")
            assert tick.startswith("tick:go_event[") and int(tick.split("[")[1].rstrip("]")) in children
            assert int(tick.split("[")[1].rstrip("]")) != proc.pid
        finally:
            _stop(proc)
            err.close()
        assert proc.returncode == 0, log()
