"""``agentsctl router --connect``: two routers joined into a mesh, a robot behind one, an operator behind the other.

Router A listens on one loopback port; router B listens on another and joins A (``--connect``).
A robot (a namespaced launcher, a Zenoh client of A only) and an operator (a client of B only)
reach each other through the two routers; each router reports the other among its peers (its
``--json`` peers lines), with the link's endpoints. Multicast scouting is off everywhere and every
endpoint is explicit.
"""

from __future__ import annotations

import json
import threading
from pathlib import Path
from typing import Any

import pytest

from agents_core import Launcher, Topic
from agents_core.testing.pairs import missing_requirement
from agents_core.transport.registry import resolve_transport
from tests.cli.helpers import cli, cli_env, start, stop, wait_until
from tests.conftest import free_tcp_port
from tests.launch.test_namespace import BATTERY, MAP, Battery

pytestmark = [pytest.mark.zenoh,
              pytest.mark.skipif(missing_requirement("zenoh") is not None, reason=str(missing_requirement("zenoh")))]


def _docs(log: Path) -> list[dict[str, Any]]:
    docs = []
    for line in log.read_text(errors="replace").splitlines():
        if line.startswith("{"):
            try:
                docs.append(json.loads(line))
            except json.JSONDecodeError:
                continue
    return docs


def _peers(log: Path) -> list[dict[str, Any]]:
    found = [d["peers"] for d in _docs(log) if "peers" in d]
    return found[-1] if found else []


def _zid(log: Path) -> str | None:
    return next((str(d["router"]) for d in _docs(log) if "router" in d), None)


def test_two_routers_form_a_mesh_and_report_each_other(tmp_path: Path) -> None:
    a, b = f"tcp/127.0.0.1:{free_tcp_port()}", f"tcp/127.0.0.1:{free_tcp_port()}"
    log_a, log_b = tmp_path / "a.log", tmp_path / "b.log"
    router_a = start("router", "--listen", a, "--json", env=cli_env(), log=log_a)
    router_b = None
    try:
        assert wait_until(lambda: _zid(log_a) is not None, 30.0), log_a.read_text()
        router_b = start("router", "--listen", b, "--connect", a, "--json", env=cli_env(), log=log_b)
        assert wait_until(lambda: _zid(log_b) is not None, 30.0), log_b.read_text()
        ready = next(d for d in _docs(log_b) if "router" in d)
        assert ready["connect"] == [a] and ready["listen"] == [b]

        # Each router reports the other, as a router, with the link between them.
        assert wait_until(lambda: [p["zid"] for p in _peers(log_b) if p["kind"] == "router"] == [_zid(log_a)],
                          15.0, 0.1), _docs(log_b)
        assert wait_until(lambda: [p["zid"] for p in _peers(log_a) if p["kind"] == "router"] == [_zid(log_b)],
                          15.0, 0.1), _docs(log_a)
        link = next(p for p in _peers(log_b) if p["kind"] == "router")["links"]
        assert any(entry.endswith(a.removeprefix("tcp/")) for entry in link), link

        client = {"mode": "client", "multicast_scouting": False}
        robot = Launcher(transport="zenoh", transport_options={**client, "connect": [a]}, namespace="robot1",
                         quiet=True)
        robot.add_pkg(components=[Battery(inputs=[], outputs=[BATTERY, MAP], trigger=20.0,
                                          component_name="battery")])
        with robot:
            operator = resolve_transport("zenoh", **client, connect=[b])
            try:
                got = threading.Event()
                operator.create_subscription(Topic("robot1/battery", "Float32"), lambda _v: got.set())
                assert got.wait(20.0), "nothing from the robot behind the other router"
                assert wait_until(lambda: "robot1/battery" in operator.discover(0.5).components, 10.0, 0.2)
                reply = operator.request("robot1/battery/execute_method",
                                         {"method": "recharge", "args": [10], "kwargs": {}}, timeout=10.0)
                assert reply["result"] == "? charged to 10"
                # agentsctl behind router B addresses the robot behind router A, by its namespace.
                via_b = ["--transport", "zenoh", "--connect", b, "--json"]
                done = cli("components", "list", "--namespace", "robot1", *via_b)
                assert done.returncode == 0, done.stderr
                assert [c["name"] for c in json.loads(done.stdout)] == ["robot1/battery"]
                done = cli("components", "status", "battery", "--namespace", "robot1", *via_b)
                assert done.returncode == 0, done.stderr
                assert [t["name"] for t in json.loads(done.stdout)["outputs"]] == ["robot1/battery", "map"]
                done = cli("call", "battery", "recharge", "20", "--namespace", "robot1", *via_b)
                assert done.returncode == 0, done.stderr
                assert json.loads(done.stdout)["result"] == "? charged to 20"
                assert wait_until(lambda: sum(p["kind"] == "client" for p in _peers(log_b)) == 1, 10.0, 0.1)
                assert wait_until(lambda: sum(p["kind"] == "client" for p in _peers(log_a)) == 1, 10.0, 0.1)
            finally:
                operator.close()
    finally:
        for process in (router_b, router_a):
            if process is not None:
                stop(process)


def test_router_without_json_says_its_peers_in_words(tmp_path: Path) -> None:
    a = f"tcp/127.0.0.1:{free_tcp_port()}"
    log = tmp_path / "router.log"
    router = start("router", "--listen", a, env=cli_env(), log=log)
    try:
        assert wait_until(lambda: "peers: none" in log.read_text(errors="replace"), 30.0, 0.2), log.read_text()
        observer = resolve_transport("zenoh", mode="client", connect=[a], multicast_scouting=False)
        try:
            assert wait_until(lambda: "peers: client " in log.read_text(errors="replace"), 10.0, 0.1), \
                log.read_text()
        finally:
            observer.close()
    finally:
        stop(router)
    assert router.returncode == 0, log.read_text()  # a clean exit on SIGINT


@pytest.mark.parametrize("command", [["call", "arm", "home"], ["topics", "echo", "camera"],
                                     ["run", "tests/fleet/fleet_recipe.py"]])
def test_an_invalid_namespace_on_the_command_line_is_one_line_naming_the_option(command: list[str]) -> None:
    done = cli(*command, "--namespace", "robot-1")
    assert done.returncode != 0
    assert "--namespace 'robot-1' is not a namespace" in done.stderr and "Traceback" not in done.stderr, done.stderr
