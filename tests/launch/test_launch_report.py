"""The status lines a launcher prints on stderr: transport, components, UI, failures, and quiet."""

from __future__ import annotations

import io
import logging
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from agents_core import Launcher, Topic
from agents_core.components import Component
from agents_core.errors import ComponentError
from agents_core.launch.report import LaunchReport, describe_transport
from agents_core.support.console import quiet_requested, say

ROOT = Path(__file__).resolve().parents[2]


class Idle(Component):
    """Does nothing at each step."""

    def _execution_step(self, **kwargs: Any) -> None:
        return None


class BrokenConfigure(Component):
    """Fails in configure, as a component whose model cannot load does."""

    def custom_on_configure(self) -> None:
        raise ComponentError("the model file is missing")

    def _execution_step(self, **kwargs: Any) -> None:
        return None


def _idle(name: str) -> Idle:
    return Idle(inputs=[], outputs=[Topic(f"{name}_out", "String")], trigger=1.0, component_name=name)


@pytest.fixture
def loud(monkeypatch: pytest.MonkeyPatch) -> None:
    """Status lines on (the suite's conftest sets AGENTS_QUIET=1)."""
    monkeypatch.delenv("AGENTS_QUIET", raising=False)


def test_the_report_lines(loud: None, capsys: pytest.CaptureFixture[str]) -> None:
    launcher = Launcher(transport="memory")
    launcher.add_pkg(components=[_idle("talker"), _idle("listener")])
    with launcher:
        pass
    err = capsys.readouterr().err.splitlines()
    assert err[0] == "agents: transport memory (in this process only)"
    assert err[1].split() == ["✓", "talker", "active", "healthy"]
    assert err[2].split() == ["✓", "listener", "active", "healthy"]
    assert err[3] == "agents: 2 component(s) running; press Ctrl-C to stop"
    assert len(err) == 4


def test_a_failure_names_the_component_and_the_reason(loud: None, capsys: pytest.CaptureFixture[str]) -> None:
    launcher = Launcher(transport="memory")
    broken = BrokenConfigure(inputs=[], outputs=[Topic("x", "String")], trigger=1.0, component_name="vision")
    launcher.add_pkg(components=[_idle("talker"), broken])
    with pytest.raises(ComponentError):
        launcher.start()
    err = capsys.readouterr().err
    line = next(x for x in err.splitlines() if "✗" in x)
    assert "vision" in line and "failed to configure" in line and "the model file is missing" in line
    assert "running" not in err


@pytest.mark.parametrize("how", ["argument", "env", "log level"])
def test_quiet_silences_it(how: str, loud: None, monkeypatch: pytest.MonkeyPatch,
                           capsys: pytest.CaptureFixture[str]) -> None:
    quiet: bool | None = None
    if how == "argument":
        quiet = True
    elif how == "env":
        monkeypatch.setenv("AGENTS_QUIET", "1")
    else:
        core = logging.getLogger("agents_core")
        monkeypatch.setattr(core, "level", logging.WARNING)
    launcher = Launcher(transport="memory", quiet=quiet)
    launcher.add_pkg(components=[_idle("talker")])
    with launcher:
        pass
    assert capsys.readouterr().err == ""


def test_an_explicit_info_level_keeps_it_on(loud: None, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(logging.getLogger("agents_core"), "level", logging.INFO)
    assert not quiet_requested()
    assert quiet_requested(True)
    assert not quiet_requested(False)


def test_say_survives_a_closed_stream(loud: None) -> None:
    stream = io.StringIO()
    stream.close()
    say("hello", stream=stream)  # no exception


def test_plain_text_when_not_a_terminal(loud: None) -> None:
    stream = io.StringIO()
    report = LaunchReport(stream=stream)
    report.failed("cam[0]", "activate", ValueError())
    assert stream.getvalue() == "  ✗ cam[0]       failed to activate: ValueError\n"


class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_rich_on_a_terminal(loud: None) -> None:
    pytest.importorskip("rich")
    stream = _Tty()
    report = LaunchReport(stream=stream)
    report.ui("http://127.0.0.1:5001/")
    report.component("a[b]", "active", "healthy")
    out = stream.getvalue()
    assert "web UI at" in out and "http://127.0.0.1:5001/" in out
    assert "a[b]" in out  # markup in a name is shown, not interpreted


def test_zenoh_endpoints_are_described() -> None:
    config = pytest.importorskip("agents_zenoh.config")

    class Driver:
        def __init__(self, **kw: Any) -> None:
            self.config = config.ZenohConfig(**kw)

    class T:
        name = "zenoh"

        def __init__(self, **kw: Any) -> None:
            self.driver = Driver(**kw)

    assert describe_transport(T()) == ("zenoh (peer; loopback rendezvous tcp/127.0.0.1:7447; "
                                       "multicast scouting off)")
    text = describe_transport(T(mode="client", connect=["tcp/10.0.0.2:7447"]))
    assert text == "zenoh (client; connect tcp/10.0.0.2:7447; multicast scouting off)"
    text = describe_transport(T(listen=["tcp/127.0.0.1:7500"], multicast_scouting=True, namespace="robot1"))
    assert "listen tcp/127.0.0.1:7500" in text and "multicast scouting on" in text and "namespace robot1" in text


def test_ros2_domain_and_range_without_rclpy(monkeypatch: pytest.MonkeyPatch) -> None:
    class T:
        name = "ros2"
        driver = None

    monkeypatch.setenv("ROS_DOMAIN_ID", "42")
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    assert describe_transport(T()) == "ros2 (domain 42; discovery range LOCALHOST)"
    monkeypatch.delenv("ROS_AUTOMATIC_DISCOVERY_RANGE")
    monkeypatch.delenv("ROS_LOCALHOST_ONLY", raising=False)
    assert describe_transport(T()).endswith("discovery range SUBNET)")


def test_python_recipe_py_says_what_it_does_and_how_it_stopped(tmp_path: Path) -> None:
    """A recipe run as a script, stderr not a terminal, no logging configured: a few plain lines."""
    recipe = tmp_path / "recipe.py"
    recipe.write_text(
        "from agents_core import Launcher, Topic\n"
        "from agents_core.components import Component\n"
        "class Idle(Component):\n"
        "    def _execution_step(self, **kw):\n"
        "        pass\n"
        "launcher = Launcher(transport='memory')\n"
        "launcher.add_pkg(components=[Idle(inputs=[], outputs=[Topic('o', 'String')], trigger=1.0,"
        " component_name='idle')])\n"
        "launcher.bringup()\n")
    env = {k: v for k, v in os.environ.items() if k != "AGENTS_QUIET"}
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "src"), env.get("PYTHONPATH", "")])
    proc = subprocess.Popen([sys.executable, str(recipe)], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    assert proc.stderr is not None
    lines = []
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        line = proc.stderr.readline()
        lines.append(line.rstrip("\n"))
        if "press Ctrl-C to stop" in line or not line:
            break
    proc.send_signal(signal.SIGINT)
    _out, rest = proc.communicate(timeout=30)
    lines += rest.splitlines()
    assert proc.returncode == 0, lines
    assert lines == ["agents: transport memory (in this process only)",
                     "  ✓ idle         active   healthy",
                     "agents: 1 component(s) running; press Ctrl-C to stop",
                     "agents: stopping (Ctrl-C again to hurry)",
                     "agents: stopped"]


def test_a_change_after_start_gets_a_new_row(loud: None, capsys: pytest.CaptureFixture[str]) -> None:
    """Deactivating a running component prints its new row within a few polls (the live status thread)."""
    from agents_core.testing.helpers import wait_for  # noqa: PLC0415

    launcher = Launcher(transport="memory")
    talker, listener = _idle("talker"), _idle("listener")
    launcher.add_pkg(components=[talker, listener])
    with launcher:
        capsys.readouterr()
        listener.deactivate()
        seen: list[str] = []
        assert wait_for(lambda: bool(seen.extend(capsys.readouterr().err.splitlines()) or
                                     any("listener" in x and "inactive" in x for x in seen)), timeout=10)
    rows = [x for x in seen if x.startswith("  ")]
    assert [x.split()[:3] for x in rows] == [["•", "listener", "inactive"]]  # talker did not change: no row


def test_live_status_reports_only_changes_and_stops() -> None:
    from agents_core.launch.live_status import LiveStatus  # noqa: PLC0415

    stream = io.StringIO()
    rows = [("a", "active", "healthy", ""), ("b", "active", "healthy", "")]
    live = LiveStatus(LaunchReport(quiet=False, stream=stream), lambda: list(rows), interval=60.0)
    live.start()
    assert live.poll() == []
    rows[1] = ("b", "active", "algorithm_failure", "")
    assert live.poll() == [rows[1]]
    assert live.poll() == []
    live.stop()
    assert stream.getvalue().split() == ["•", "b", "active", "algorithm_failure"]


def test_child_rows_say_the_restart_count_and_giving_up() -> None:
    from agents_core.launch.live_status import child_rows  # noqa: PLC0415

    described = [{"name": "vision", "pid": 11, "state": "active", "restarts": 0, "gave_up": False},
                 {"name": "llm", "pid": 12, "state": "active", "restarts": 2, "gave_up": False},
                 {"name": "tts", "pid": 13, "state": "failed", "restarts": 3, "gave_up": True}]
    assert child_rows(lambda: described, 3) == [
        ("vision", "active", "-", "own process, pid 11"),
        ("llm", "active", "-", "own process, pid 12, restart 2/3"),
        ("tts", "failed", "-", "gave up after 3 restart(s)")]
