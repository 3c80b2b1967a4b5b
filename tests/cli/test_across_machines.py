"""Recipes across machines: a router and two recipe processes that reach each other only through it.

``agentsctl router --listen tcp/127.0.0.1:R`` runs the router; ``agentsctl run cli_recipe.py
--transport zenoh --connect tcp/127.0.0.1:R talker`` and ``... listener`` run as Zenoh clients of
it (no listen endpoint, so no peer link between them is possible, checked in /proc). The
listener upper-cases what the talker says; the CLI, a third client of the router, sees the whole
graph and the listener's output. When the router is restarted on the same port, the clients
reconnect by themselves and the data flows again.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from agents_core.testing.helpers import free_tcp_port
from agents_core.testing.pairs import missing_requirement
from tests.cli.helpers import RECIPE, cli, cli_env, cli_json, listening_tcp_ports, start, stop, wait_until

pytestmark = [pytest.mark.zenoh, pytest.mark.slow,
              pytest.mark.skipif(missing_requirement("zenoh") is not None, reason=str(missing_requirement("zenoh")))]


def _router_ready(log: Path) -> bool:
    return "listening on" in log.read_text(errors="replace")


def test_two_recipes_talk_only_through_a_router(tmp_path: Path) -> None:
    port = free_tcp_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    via_router = ["--transport", "zenoh", "--connect", endpoint]
    router = start("router", "--listen", endpoint, env=cli_env(), log=tmp_path / "router.log")
    talker = listener = None
    try:
        assert wait_until(lambda: _router_ready(tmp_path / "router.log"), timeout=30.0), \
            (tmp_path / "router.log").read_text()
        talker = start("run", RECIPE, *via_router, "talker", env=cli_env(), log=tmp_path / "talker.log")
        listener = start("run", RECIPE, *via_router, "listener", env=cli_env(), log=tmp_path / "listener.log")

        def both_active() -> bool:
            for process, log in ((talker, "talker.log"), (listener, "listener.log")):
                assert process.poll() is None, (tmp_path / log).read_text()
            done = cli("components", "list", "--json", *via_router)
            return done.returncode == 0 and sorted(c["name"] for c in json.loads(done.stdout)
                                                   if c["state"] == "active") == ["listener", "talker"]
        assert wait_until(both_active, timeout=90.0), (tmp_path / "listener.log").read_text()

        # Clients only: neither recipe listens on any TCP port, so they cannot link to each other.
        assert listening_tcp_ports(talker.pid) == set()
        assert listening_tcp_ports(listener.pid) == set()
        assert port in listening_tcp_ports(router.pid)

        # The talker's words reach the listener in the other process, through the router.
        done = cli("topics", "echo", "shout", "--count", "2", "--timeout", "30", "--json", *via_router)
        assert done.returncode == 0, done.stderr
        shouts = [json.loads(line)["value"] for line in done.stdout.splitlines()]
        assert len(shouts) == 2 and all(s.startswith("TICK ") for s in shouts)
        topics = {t["name"]: t for t in cli_json("topics", "list", *via_router)}
        assert topics["chatter"]["publishers"] == 1 and topics["chatter"]["subscribers"] == 1

        # A router restart: the recipes keep running meanwhile and reconnect to the new one.
        stop(router)
        assert talker.poll() is None and listener.poll() is None
        router = start("router", "--listen", endpoint, env=cli_env(), log=tmp_path / "router2.log")
        assert wait_until(lambda: _router_ready(tmp_path / "router2.log"), timeout=30.0)
        # Zenoh clients reconnect to the router on its port; the data flows again.
        done = cli("topics", "echo", "shout", "--count", "1", "--timeout", "60", "--type", "String", "--json",
                   *via_router, timeout=90.0)
        assert done.returncode == 0, done.stderr
        assert json.loads(done.stdout.splitlines()[0])["value"].startswith("TICK ")
    finally:
        for process in (listener, talker):
            if process is not None:
                stop(process)
        stop(router)


def test_router_refuses_a_bad_endpoint() -> None:
    done = cli("router", "--listen", "not-an-endpoint")
    assert done.returncode == 1
    assert done.stderr.strip().startswith("error: ") and "not-an-endpoint" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1
