"""A ROS 2 peer that shares none of our code (zenoh-python + rosbags + xxhash, ``raw_ros_peer.py``) and our
rmw_zenoh transport talk both ways: topics, services (seq and GID echoed), lifecycle, the graph."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

from agents_core.status import HealthStatus, LifecycleState
from agents_core.supported_types import get_type
from agents_core.topics import Topic
from agents_core.transport.namespace import namespaced

from .conftest import rmw_options

pytest.importorskip("rosbags", reason="needs the rmw_zenoh extra")

from agents_core.testing.recipes import RecipeProcess, recipe_environment
from agents_zenoh.rmw.transport import RmwZenohTransport

pytestmark = pytest.mark.zenoh

PEER = Path(__file__).parent / "raw_ros_peer.py"


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}


@contextmanager
def _transport(router: str) -> Iterator[Any]:
    transport = RmwZenohTransport(**rmw_options(router))
    try:
        yield transport
    finally:
        transport.close()


def _run_peer(router: str, *args: str, timeout: float = 60) -> str:
    done = subprocess.run([sys.executable, str(PEER), router, "21", *args], capture_output=True, text=True,
                          timeout=timeout, env=_env(), check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


@contextmanager
def _peer(router: str, *args: str) -> Iterator[subprocess.Popen[str]]:
    proc = subprocess.Popen([sys.executable, str(PEER), router, "21", *args], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True, env=_env())
    try:
        assert proc.stdout is not None
        assert proc.stdout.readline().strip() == "ready"
        yield proc
    finally:
        assert proc.stdin is not None
        proc.stdin.close()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        if proc.stdout is not None:
            proc.stdout.close()


def test_raw_publisher_reaches_our_subscriber_and_graph(router: str) -> None:
    with _transport(router) as transport:
        got: list[str] = []
        sub = transport.create_subscription(Topic("raw_chatter", get_type("String")), got.append)
        proc = subprocess.Popen([sys.executable, str(PEER), router, "21", "talk", "/raw_chatter"], env=_env(),
                                stdout=subprocess.DEVNULL)
        try:
            deadline = time.monotonic() + 20
            seen = None
            while time.monotonic() < deadline and (not got or seen is None):
                info = transport.discover(1.0).topic("raw_chatter")
                if info is not None and info.publishers:
                    seen = info
                time.sleep(0.1)
            assert proc.wait(timeout=30) == 0
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        assert got and all(v.startswith("raw ") for v in got)
        assert seen is not None and seen.msg_type == "String" and seen.subscribers >= 1
        assert sub.statistics().decode_errors == 0


def test_our_publisher_reaches_raw_subscriber(router: str) -> None:
    with _transport(router) as transport, _peer(router, "listen", "/to_raw") as proc:
        pub = transport.create_publisher(Topic("to_raw", get_type("String")))
        lines: list[dict[str, Any]] = []
        assert proc.stdout is not None
        for i in range(3):
            pub.publish(f"ours {i}")
        while len(lines) < 3:
            lines.append(json.loads(proc.stdout.readline()))
        assert [line["data"] for line in lines] == ["ours 0", "ours 1", "ours 2"]
        assert [line["seq"] for line in lines] == [1, 2, 3]
        assert all(line["gid_of_a_publisher_token"] for line in lines)


def test_raw_client_calls_our_service_and_lifecycle(router: str) -> None:
    with _transport(router) as transport:
        transport.create_service("raw_echo", lambda request: {"echo": request})
        presence = transport.declare_component("arm", on_transition=lambda _t: True)
        presence.update(LifecycleState.ACTIVE, HealthStatus.HEALTHY)
        answer = json.loads(_run_peer(router, "call", "/raw_echo"))
        assert answer == {"replies": 1, "seq_echoed": True, "gid_echoed": True, "reply": {"echo": {"from": "raw"}},
                          "success": True}
        state = json.loads(_run_peer(router, "get_state", "arm"))
        assert state["reply"] == "active" and state["seq_echoed"] and state["gid_echoed"]


def test_a_namespaced_component_is_its_node_in_the_namespace(router: str) -> None:
    """``Launcher(namespace="robot1")``'s component ``arm`` is node ``arm`` in namespace ``/robot1`` (as on ROS 2),
    read from its tokens by the raw peer, which also drives its lifecycle; our graph lists it as ``robot1/arm``."""
    with _transport(router) as transport:
        view = namespaced(transport, "robot1")
        presence = view.declare_component("arm", on_transition=lambda _t: True)
        presence.update(LifecycleState.ACTIVE, HealthStatus.HEALTHY)
        view.create_publisher(Topic("joints", get_type("String")), owner="arm")
        node = json.loads(_run_peer(router, "node", "arm"))
        assert node["namespace"] == "/robot1" and node["node"] == "arm", node
        assert {"/robot1/arm/change_state", "/robot1/arm/get_state", "/robot1/joints"} <= set(node["owned"]), node
        assert node["others_named_like_it"] == []  # no flattened "robot1_arm" node beside it
        state = json.loads(_run_peer(router, "get_state", "robot1/arm"))
        assert state["reply"] == "active" and state["gid_echoed"]
        assert "robot1/arm" in transport.discover(1.0).components


def test_our_request_reaches_raw_server(router: str) -> None:
    with _transport(router) as transport, _peer(router, "serve", "/raw_server"):
        reply: dict[str, Any] = {}
        deadline = time.monotonic() + 10
        while not reply and time.monotonic() < deadline:
            try:
                reply = transport.request("raw_server", {"n": 42}, timeout=2.0)
            except Exception:  # the server's queryable may not have reached us yet
                time.sleep(0.2)
        assert reply["raw_got"]["n"] == 42  # the core adds the caller's deadline (_timeout_s)


def test_agentsctl_components_and_call_on_a_recipe(router: str, tmp_path: Path) -> None:
    env = recipe_environment(ROS_DOMAIN_ID="21", PYTHONPATH=os.pathsep.join(sys.path),
                             ZENOH_CONFIG_OVERRIDE=f'connect/endpoints=["{router}"];listen/endpoints=["tcp/127.0.0.1:0"]')
    recipe = RecipeProcess(str(Path(__file__).with_name("recipe.py")), [], tmp_path / "recipe.log", env=env)
    try:
        recipe.wait_ready(90)

        def cli(*args: str) -> Any:
            done = subprocess.run([sys.executable, "-m", "agents_core.cli", *args, "--transport", "rmw_zenoh",
                                   "--connect", router, "--json"], capture_output=True, text=True, timeout=120,
                                  env=env, check=False)
            assert done.returncode == 0, done.stdout + done.stderr[-2000:]
            return json.loads(done.stdout)

        listed = cli("components", "list")
        rows = listed if isinstance(listed, list) else listed.get("components", listed)
        assert any(r["name"] == "relay" and r["state"] == "active" for r in rows), listed
        assert cli("call", "relay", "shout", "hey")["result"] == "HEY!"
        # And a raw ROS peer drives it: its String reaches the relay, the relay's answer reaches our asker.
        with _transport(router) as asker:
            got: list[str] = []
            asker.create_subscription(Topic("relay_out", get_type("String")), got.append)
            _run_peer(router, "talk", "/relay_in")
            assert got and got[0].startswith("RAW ")
    finally:
        recipe.stop()
