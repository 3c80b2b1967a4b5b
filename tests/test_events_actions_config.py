"""Events and conditions, actions and the component services, config loading and validation."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any

import pytest
from attrs import define, field

from agents_core import Event, Launcher, Topic
from agents_core.actions import Action, Fallback, component_action
from agents_core.config import BaseComponentConfig
from agents_core.errors import ConfigError, RemoteError
from agents_core.messages import DetectionsMsg
from agents_core.ros import base_validators
from tests.conftest import wait_for
from tests.recipe_parts import Relay

# -- conditions -----------------------------------------------------------------------------------


def test_condition_operators() -> None:
    level = Topic("level", "Float32")
    det = Topic("det", "Detections")
    name = Topic("name", "String")
    d = DetectionsMsg(boxes=[[0, 0, 1, 1]], labels=["person"], scores=[0.9])
    cases = [
        (level.msg.data == 0.5, {"level": 0.5}, True),
        (level.msg.data != 0.5, {"level": 0.5}, False),
        (level.msg.data < 1, {"level": 0.5}, True),
        (level.msg.data <= 0.5, {"level": 0.5}, True),
        (level.msg.data > 0.5, {"level": 0.5}, False),
        (level.msg.data >= 0.6, {"level": 0.5}, False),
        (name.msg.data.is_in(["stop", "halt"]), {"name": "halt"}, True),
        (det.msg.labels.contains("person"), {"det": d}, True),
        ((level.msg.data > 0.1) & (name.msg.data == "go"), {"level": 0.5, "name": "go"}, True),
        ((level.msg.data > 0.9) | (name.msg.data == "go"), {"level": 0.5, "name": "go"}, True),
        (~(level.msg.data > 0.9), {"level": 0.5}, True),
        (level.msg.data > 0.1, {}, False),  # no message yet
    ]
    for cond, values, expected in cases:
        assert cond.evaluate(values) is expected, cond


def test_conditions_reject_unknown_fields_and_python_booleans() -> None:
    det = Topic("det", "Detections")
    with pytest.raises(ConfigError, match="has no field 'label'"):
        _ = det.msg.label
    with pytest.raises(ConfigError, match=r"use '\.data'"):
        _ = Topic("t", "String").msg.text
    with pytest.raises(ConfigError, match="combine conditions"):
        bool(Topic("x", "Int32").msg.data > 1)


def test_event_options() -> None:
    t = Topic("t", "Int32")
    fired: list[Any] = []
    once = Event(event_condition=t.msg.data > 0, handle_once=True)
    once.add_listener(lambda e, v: fired.append(("once", v["t"])))
    every = Event(event_condition=t)
    every.add_listener(lambda e, v: fired.append(("every", v["t"])))
    changed = Event(event_condition=t, on_change=True)
    changed.add_listener(lambda e, v: fired.append(("changed", v["t"])))
    for value in [1, 1, 2]:
        for e in (once, every, changed):
            e.process("t", value)
    assert [f for f in fired if f[0] == "once"] == [("once", 1)]
    assert [f for f in fired if f[0] == "every"] == [("every", 1), ("every", 1), ("every", 2)]
    assert [f for f in fired if f[0] == "changed"] == [("changed", 1), ("changed", 2)]
    delayed = Event(event_condition=t, keep_event_delay=60.0)
    assert delayed.process("t", 1) is True
    assert delayed.process("t", 2) is False
    manual = Event(name="estimate_depth")
    assert manual.topics == {} and manual.trigger() is True
    with pytest.raises(ConfigError, match="keep_event_delay"):
        Event(event_condition=t, keep_event_delay=-1)


def test_action_takes_arguments_from_the_triggering_message() -> None:
    cmd = Topic("cmd", "String")
    seen: list[Any] = []
    action = Action(lambda text, loud=False: seen.append((text, loud)), args=(cmd.msg.data,), kwargs={"loud": True})
    action({"cmd": "wave"})
    assert seen == [("wave", True)]
    with pytest.raises(ConfigError, match="needs a message from topic 'cmd'"):
        action({})


def test_fallback_sequence() -> None:
    a, b = Action(print), Action(repr)
    seq = Fallback([a, b], max_retries=2)
    assert [seq.next_action() for _ in range(5)] == [a, a, b, b, None]
    seq.reset()
    assert seq.next_action() is a
    forever = Fallback([a, b])
    assert [forever.next_action() for _ in range(4)] == [a, b, b, b]


def test_launcher_events_run_actions_on_the_component_worker() -> None:
    cmd, out = Topic("cmd", "String"), Topic("out", "String")
    relay = Relay(inputs=[cmd], outputs=[out], trigger=cmd, component_name="relay")
    stop = Event(name="stop", event_condition=cmd.msg.data == "stop")
    launcher = Launcher("memory")
    launcher.add_pkg(components=[relay], events_actions={stop: Action(relay.deactivate)})
    with launcher:
        launcher.transport.create_publisher(cmd).publish("stop")
        assert wait_for(lambda: relay.lifecycle_state.value == "inactive")


# -- component actions service ----------------------------------------------------------------------


class Greeter(Relay):
    @component_action(description={"description": "Say hello to someone.",
                                   "parameters": {"type": "object",
                                                  "properties": {"who": {"type": "string"}},
                                                  "required": ["who"]}})
    def greet(self, who: str) -> str:
        return f"hello {who} from {self.component_name}"

    def not_exposed(self) -> str:
        return "secret"


def test_execute_method_serves_only_component_actions() -> None:
    cmd = Topic("cmd", "String")
    greeter = Greeter(inputs=[cmd], trigger=cmd, component_name="greeter")
    actions = greeter.available_actions()
    assert actions["greet"]["function"]["name"] == "greet"
    assert actions["greet"]["function"]["parameters"]["required"] == ["who"]
    assert "not_exposed" not in actions
    launcher = Launcher("memory")
    launcher.add_pkg(components=[greeter])
    with launcher:
        t = launcher.transport
        reply = t.request("greeter/execute_method", {"method": "greet", "kwargs": {"who": "ada"}})
        assert reply == {"result": "hello ada from greeter"}
        with pytest.raises(RemoteError, match="no action 'not_exposed'"):
            t.request("greeter/execute_method", {"method": "not_exposed"})
        with pytest.raises(RemoteError, match="status_rate must be in"):
            t.request("greeter/set_param", {"name": "status_rate", "value": 1000.0})
        assert greeter.config.status_rate == 1.0
        assert t.request("greeter/set_param", {"params": {"status_rate": 2.0}})["ok"] is True
        assert greeter.config.status_rate == 2.0


# -- config -----------------------------------------------------------------------------------------


@define(kw_only=True)
class ArmConfig(BaseComponentConfig):
    speed: float = field(default=0.5, validator=base_validators.in_range(0.0, 1.0))
    mode: str = field(default="safe", validator=base_validators.in_(["safe", "fast"]))


@pytest.mark.parametrize(("suffix", "text"), [
    (".yaml", "arm:\n  speed: 0.9\n  mode: fast\n"),
    (".toml", "[arm]\nspeed = 0.9\nmode = \"fast\"\n"),
    (".json", '{"arm": {"speed": 0.9, "mode": "fast"}}'),
])
def test_config_loads_from_files(tmp_path: Path, suffix: str, text: str) -> None:
    path = tmp_path / f"robot{suffix}"
    path.write_text(text)
    cfg = ArmConfig.from_file(path, section="arm")
    assert (cfg.speed, cfg.mode) == (0.9, "fast")
    relay = Relay(inputs=[Topic("a", "String")], component_name="arm", config=ArmConfig(), config_file=path)
    assert relay.config.mode == "fast"


def test_config_errors_name_the_field(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"ArmConfig.speed must be in \[0.0, 1.0\], got 3"):
        ArmConfig(speed=3)
    with pytest.raises(ConfigError, match="must be one of"):
        ArmConfig(mode="reckless")
    bad = tmp_path / "bad.yaml"
    bad.write_text("speeed: 0.1\n")
    with pytest.raises(ConfigError, match=r"unknown field\(s\) \['speeed'\]"):
        ArmConfig.from_file(bad)
    broken = tmp_path / "broken.json"
    broken.write_text("{nope")
    with pytest.raises(ConfigError, match="not valid JSON"):
        ArmConfig.from_file(broken)
    cfg = ArmConfig()
    with pytest.raises(ConfigError):
        cfg.update(speed=0.2, mode="reckless")
    assert cfg.speed == 0.5, "a failed update changes nothing"


# -- bringup and signals ----------------------------------------------------------------------------


def test_bringup_shuts_down_cleanly_on_sigterm(tmp_path: Path) -> None:
    script = tmp_path / "recipe.py"
    script.write_text(textwrap.dedent("""
        import sys
        from agents_core import Launcher, Topic
        from tests.recipe_parts import Relay

        class Loud(Relay):
            def custom_on_activate(self):
                print("active", flush=True)

            def custom_on_shutdown(self):
                print("shutdown hook ran", flush=True)

        a = Topic("a", "String")
        launcher = Launcher()  # AGENTS_TRANSPORT chooses
        launcher.add_pkg(components=[Loud(inputs=[a], trigger=5.0, component_name="loud")])
        print("transport:", launcher._transport_spec or "env", flush=True)
        launcher.bringup()
        print("bringup returned", launcher.transport.name, flush=True)
    """))
    env = {**os.environ, "AGENTS_TRANSPORT": "memory", "PYTHONPATH": str(Path(__file__).parent.parent)}
    proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True, env=env)
    try:
        assert proc.stdout is not None
        seen = []
        for _ in range(10):  # bounded: "active" is the second line
            line = proc.stdout.readline()
            seen.append(line)
            if line.strip() == "active" or not line:
                break
        assert seen[-1].strip() == "active", seen
        proc.send_signal(signal.SIGTERM)
        out, _ = proc.communicate(timeout=20)
        out = "".join(seen) + out
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(5)
    assert proc.returncode == 0, out
    assert "shutdown hook ran" in out
    assert "bringup returned memory" in out
