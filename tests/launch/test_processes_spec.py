"""The component spec, the launcher's refusals and its config file, in this process (no middleware)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from agents_core import Topic
from agents_core.actions import Action
from agents_core.clients.generic import GenericHTTPClient
from agents_core.config import BaseComponentConfig
from agents_core.errors import ConfigError, WiringError
from agents_core.events import Event
from agents_core.launch.launcher import Launcher
from agents_core.launch.spec import (
    SPEC_VERSION,
    ComponentSpec,
    LauncherEvent,
    check_rebuild,
    decode_value,
    encode_value,
)
from agents_core.models import GenericLLM
from agents_core.topics import FixedInput, QoSConfig

from .carried_components import Ticker
from .mp_recipe import Shout

KEY = "sk-unit-31337-secret"


def _shout(**kwargs: Any) -> Shout:
    client = GenericHTTPClient(GenericLLM(name="m", checkpoint="c"), host="127.0.0.1", port=9, api_key=KEY)
    return Shout("in_t", "out_t", "shout", suffix="?", client=client, **kwargs)


def test_spec_round_trip_rebuilds_an_equal_component_with_its_client() -> None:
    component = _shout()
    component.config.update(status_rate=4.0)  # changed after construction: the spec carries it
    spec = ComponentSpec.from_component(component, "zenoh", {"mode": "peer"}, os.getpid())
    wire = json.loads(json.dumps(spec.to_dict()))  # what crosses the pipe is plain JSON
    rebuilt = ComponentSpec.from_dict(wire).build()
    assert type(rebuilt) is Shout and rebuilt.component_name == "shout"
    assert rebuilt.suffix == "?" and rebuilt.config.status_rate == 4.0
    assert rebuilt.inputs == component.inputs and rebuilt.outputs == component.outputs
    assert rebuilt.client == component.client and rebuilt.client.api_key == KEY
    # The key travels in the spec (on the pipe), never in its repr.
    assert KEY in json.dumps(wire) and KEY not in repr(spec)


def test_values_round_trip_through_the_codecs() -> None:
    values = [Topic("a", "String", qos_profile=QoSConfig(depth=3, reliability="best_effort")),
              FixedInput("p", "String", fixed="hi"), BaseComponentConfig(log_level="debug"),
              (1, "x"), Path("/tmp/x"), {"k": [1, 2.5, None, True]}]
    for value in values:
        assert decode_value(json.loads(json.dumps(encode_value(value)))) == value


def test_a_value_no_codec_knows_is_refused_naming_the_component() -> None:
    class Opaque:
        pass

    component = Shout("in_t", "out_t", "opaque", suffix=Opaque())  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match=r"component 'opaque': argument 'suffix': a Opaque cannot be sent"):
        ComponentSpec.from_component(component, "zenoh", {}, os.getpid())


def test_state_added_after_construction_is_refused_not_dropped() -> None:
    component = _shout()
    # Past the component's methods (which are recorded and replayed: tests/launch/test_carried_state.py).
    component.publishers_dict["out_t"].add_preprocessor(str.strip)
    spec = ComponentSpec.from_component(component, "zenoh", {}, os.getpid())
    with pytest.raises(ConfigError, match="component 'shout': publisher pre-processors added after construction"):
        check_rebuild(component, spec)


def test_event_triggered_component_gets_a_stand_in_the_launcher_fires() -> None:
    event = Event("go", Topic("go_t", "Bool").msg.data == True)  # noqa: E712  # builds a condition
    component = Ticker(outputs=[Topic("o", "String")], trigger=event, component_name="triggered")
    spec = ComponentSpec.from_component(component, "zenoh", {}, os.getpid())
    check_rebuild(component, spec)
    rebuilt = ComponentSpec.from_dict(json.loads(json.dumps(spec.to_dict()))).build()
    assert isinstance(rebuilt.trigger, LauncherEvent) and rebuilt.trigger.name == "go"
    assert rebuilt.trigger.event_condition is None  # evaluated by the launcher, which forwards each firing


def test_spec_of_another_version_is_refused() -> None:
    data = ComponentSpec.from_component(_shout(), "zenoh", {}, os.getpid()).to_dict()
    data["version"] = SPEC_VERSION + 1
    with pytest.raises(ConfigError, match="different releases"):
        ComponentSpec.from_dict(data)
    data["version"] = SPEC_VERSION
    data["surprise"] = 1
    with pytest.raises(ConfigError, match="unknown field"):
        ComponentSpec.from_dict(data)


def test_child_refuses_a_spec_of_another_version_and_reports_why() -> None:
    data = ComponentSpec.from_component(_shout(), "memory", {}, os.getpid()).to_dict()
    data["version"] = 99
    read_fd, write_fd = os.pipe()
    proc = subprocess.Popen([sys.executable, "-m", "agents_core.launch.child", "--report-fd", str(write_fd)],
                            stdin=subprocess.PIPE, stderr=subprocess.PIPE, pass_fds=(write_fd,))
    os.close(write_fd)
    _, err = proc.communicate(json.dumps(data).encode() + b"\n", timeout=30)
    with os.fdopen(read_fd) as reports:
        lines = [json.loads(line) for line in reports]
    assert proc.returncode == 1
    assert any("version 99" in r.get("error", "") for r in lines), lines
    assert KEY.encode() not in err


def test_memory_transport_refuses_multiprocessing_naming_the_transports_that_can() -> None:
    launcher = Launcher(transport="memory")
    launcher.add_pkg(components=[_shout()], multiprocessing=True)
    with pytest.raises(ConfigError, match=r"cross_process \(.*zenoh.*\); 'memory' lives in one process"):
        launcher.start()


def test_action_on_a_component_process_must_be_a_component_action() -> None:
    component = _shout()
    launcher = Launcher(transport="memory")
    launcher.add_pkg(components=[component], events_actions={Event("e"): Action(component.get_logger)})
    from agents_core.launch.preflight import check_remote_action  # noqa: PLC0415

    with pytest.raises(WiringError, match="mark the method @component_action"):
        check_remote_action(Event("e2"), Action(component.get_logger))
    check_remote_action(Event("e3"), Action(component.set_suffix, args=("x",)))  # allowed
    check_remote_action(Event("e4"), Action(component.deactivate))  # lifecycle: allowed


@pytest.mark.parametrize("suffix", [".yaml", ".toml"])
def test_config_file_sections_apply_to_components_in_this_process(tmp_path: Path, suffix: str) -> None:
    path = tmp_path / f"robot{suffix}"
    if suffix == ".yaml":
        path.write_text("transport:\n  name: memory\nshout:\n  status_rate: 7.0\n  log_level: warning\n")
    else:
        path.write_text('[transport]\nname = "memory"\n\n[shout]\nstatus_rate = 7.0\nlog_level = "warning"\n')
    component = _shout()
    launcher = Launcher(config_file=path)
    launcher.add_pkg(components=[component])
    with launcher:
        assert launcher.transport.name == "memory"
        assert component.config.status_rate == 7.0 and component.config.log_level == "warning"

def test_config_file_errors_name_the_section(tmp_path: Path) -> None:
    path = tmp_path / "robot.yaml"
    path.write_text("transport:\n  name: memory\nshuot:\n  status_rate: 2.0\n")
    launcher = Launcher(config_file=path)
    launcher.add_pkg(components=[_shout()])
    with pytest.raises(ConfigError, match=r"section 'shuot' names no component.*did you mean 'shout'"):
        launcher.start()
    path.write_text("shout:\n  status_rate: -1\n")
    launcher = Launcher(transport="memory", config_file=path)
    launcher.add_pkg(components=[_shout()])
    with pytest.raises(ConfigError, match="section 'shout'"):
        launcher.start()
    path.write_text("transport: zenoh\n")
    with pytest.raises(ConfigError, match="'transport' must be a section"):
        Launcher(config_file=path)


def _run_child(stdin: bytes) -> tuple[int, list[dict[str, Any]]]:
    read_fd, write_fd = os.pipe()
    proc = subprocess.Popen([sys.executable, "-m", "agents_core.launch.child", "--report-fd", str(write_fd)],
                            stdin=subprocess.PIPE, stderr=subprocess.DEVNULL, pass_fds=(write_fd,))
    os.close(write_fd)
    proc.communicate(stdin, timeout=30)
    with os.fdopen(read_fd) as reports:
        return proc.returncode, [json.loads(line) for line in reports]


@pytest.mark.parametrize(("stdin", "status", "error"), [
    (b"", 2, "no complete component spec"),
    (b'{"version": 1', 2, "no complete component spec"),  # no newline: the launcher died while writing
    (b"not json\n", 1, "JSONDecodeError"),
    (b"[1, 2]\n", 1, "must be a mapping"),
])
def test_child_refuses_bad_input_on_its_pipe(stdin: bytes, status: int, error: str) -> None:
    code, reports = _run_child(stdin)
    assert code == status
    assert any(error in r.get("error", "") for r in reports), reports


def test_child_exits_when_its_launcher_pid_is_not_its_parent() -> None:
    data = ComponentSpec.from_component(_shout(), "memory", {}, parent_pid=1).to_dict()
    code, reports = _run_child(json.dumps(data).encode() + b"\n")
    assert code == 1 and reports == []


def test_fallbacks_on_the_components_own_methods_are_carried() -> None:
    component = _shout()
    component.on_component_fail(Action(component.set_suffix, args=("!!",), description="louder"), max_retries=2)
    component.on_giveup(Action(component.deactivate), max_retries=3)
    spec = ComponentSpec.from_component(component, "zenoh", {}, os.getpid())
    check_rebuild(component, spec)
    rebuilt = ComponentSpec.from_dict(json.loads(json.dumps(spec.to_dict()))).build()
    fallback = rebuilt.runtime.health.fallbacks["COMPONENT_FAILURE"]
    assert fallback.max_retries == 2
    assert fallback.actions[0].method.__self__ is rebuilt and fallback.actions[0].args == ("!!",)
    assert fallback.actions[0].description == "louder"
    assert rebuilt.runtime.health.giveup_actions[0].name == "deactivate"
    assert rebuilt.runtime.health.giveup_retries == 3


def test_a_fallback_on_another_object_is_refused() -> None:
    component = _shout()
    other = _shout()
    component.on_any_fail(Action(other.set_suffix, args=("x",)))
    with pytest.raises(ConfigError, match="fallback action 'set_suffix' is not a method of the component"):
        ComponentSpec.from_component(component, "zenoh", {}, os.getpid())
