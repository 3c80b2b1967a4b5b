"""A fleet across real network hosts: network namespaces on a bridge, one router, two robots, one operator.

Four hosts (:class:`tests.fleet.netns.Lan`: a namespace each, a veth into one bridge, addresses
10.77.0.1-4 assigned here): ``router`` runs ``agentsctl router``; ``robot1`` and ``robot2`` run the
same recipe (``tests/fleet/fleet_recipe.py robot``) under the namespaces ``robot1`` and
``robot2``, as Zenoh clients of the router; ``operator`` tallies both robots' sequence numbers
and uses ``agentsctl``. Every Zenoh endpoint is explicit (the router's address) and multicast
scouting is off (the project's default), so the router is the only way between the hosts.

Checked: the operator sees both robots' components and topics under their namespaces and
addresses each (``agentsctl call robot1/counter identify``, ``--namespace robot2``); the router
reports its three clients. Then the router is killed (SIGKILL: a crash) and restarted on the same
address: every client is back within 5 s, and the only messages lost are those the robots sent
while it was down (until they reconnected): counted from the robots' own logs of what they sent.

Skipped, with the reason, where network namespaces cannot be made (not root, no iproute2, a
container that refuses them); ``nox -s fleet`` runs it alone. Every process and namespace is
removed even on failure (by PID and by name: :meth:`Lan.close`).
"""

from __future__ import annotations

import json
import os
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from agents_core.testing.pairs import missing_requirement
from tests.fleet.netns import Lan, kill, netns_unavailable, stop

_WHY_NOT = netns_unavailable() if sys.platform.startswith("linux") else "network namespaces are Linux only"
pytestmark = [
    pytest.mark.fleet, pytest.mark.zenoh,
    pytest.mark.skipif(missing_requirement("zenoh") is not None, reason=str(missing_requirement("zenoh"))),
    pytest.mark.skipif(_WHY_NOT is not None, reason=str(_WHY_NOT)),
]

REPO = Path(__file__).resolve().parents[2]
RECIPE = "tests/fleet/fleet_recipe.py"
PORT = 7447
ROBOTS = ("robot1", "robot2")
#: The robots publish at this rate (fleet_recipe.RATE_HZ).
RATE_HZ = 20.0
RECONNECT_S = 5.0


def _env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("AGENTS_ZENOH_", "AGENTS_TRANSPORT",
                                                                     "AGENTS_NAMESPACE"))}
    src = str(REPO / "src")
    env["PYTHONPATH"] = os.pathsep.join([src, str(REPO), *filter(None, [env.get("PYTHONPATH")])])
    env["AGENTS_QUIET"] = "1"
    return env


def _cli(*args: str) -> list[str]:
    return [sys.executable, "-m", "agents_core.cli", *args]


def _wait(predicate: Any, timeout: float, interval: float = 0.1) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(interval)
    return bool(predicate())


def _lines(path: Path) -> list[str]:
    return path.read_text(errors="replace").splitlines() if path.exists() else []


def _json_lines(path: Path) -> list[dict[str, Any]]:
    docs = []
    for line in _lines(path):
        if line.startswith("{"):
            try:
                docs.append(json.loads(line))
            except json.JSONDecodeError:
                continue  # a line being written
    return docs


class Received:
    """The operator's tally file: per robot, seq -> (time sent, time received)."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def read(self) -> dict[str, dict[int, tuple[float, float]]]:
        found: dict[str, dict[int, tuple[float, float]]] = {r: {} for r in ROBOTS}
        for line in _lines(self.path):
            parts = line.split()
            if len(parts) == 4 and parts[0] in found:
                found[parts[0]][int(parts[1])] = (float(parts[2]), float(parts[3]))
        return found


def _sent(path: Path) -> dict[int, float]:
    sent = {}
    for line in _lines(path):
        parts = line.split()
        if len(parts) == 2:
            sent[int(parts[0])] = float(parts[1])
    return sent


@pytest.fixture
def lan() -> Iterator[Lan]:
    with Lan(["router", *ROBOTS, "operator"]) as network:
        yield network
    assert network.names() == [], "a network namespace was left behind"


def test_a_fleet_through_a_router_on_separate_hosts_survives_a_router_restart(lan: Lan, tmp_path: Path) -> None:
    endpoint = f"tcp/{lan.address['router']}:{PORT}"
    via = ["--transport", "zenoh", "--connect", endpoint]
    env = _env()
    router_log = tmp_path / "router.log"
    router = lan.start("router", _cli("router", "--listen", endpoint, "--json"), router_log, env=env, cwd=REPO)
    assert _wait(lambda: any("router" in d for d in _json_lines(router_log)), 30.0), router_log.read_text()

    robots = {}
    for name in ROBOTS:
        robots[name] = lan.start(name, _cli("run", RECIPE, *via, "--namespace", name, "robot",
                                            str(tmp_path / f"{name}.sent")), tmp_path / f"{name}.log",
                                 env=env, cwd=REPO)
    received = Received(tmp_path / "operator.received")
    operator = lan.start("operator", _cli("run", RECIPE, *via, "operator", str(received.path), *ROBOTS),
                         tmp_path / "operator.log", env=env, cwd=REPO)

    def logs() -> str:
        return "\n".join(f"--- {p.name}\n{p.read_text(errors='replace')[-3000:]}"
                         for p in sorted(tmp_path.glob("*.log")))

    def flowing(since: float = 0.0, count: int = 10) -> bool:
        for process in (*robots.values(), operator, router):
            assert process.poll() is None, logs()
        tally = received.read()
        return all(sum(1 for sent, _ in tally[r].values() if sent > since) >= count for r in ROBOTS)

    assert _wait(flowing, 60.0, 0.25), logs()

    _operator_sees_and_addresses_each_robot(lan, via, env)

    def clients() -> int:
        peers = [d["peers"] for d in _json_lines(router_log) if "peers" in d]
        return sum(1 for p in peers[-1] if p["kind"] == "client") if peers else 0

    assert _wait(lambda: clients() == 3, 10.0), router_log.read_text()  # the CLI's clients come and go

    # The router crashes, and comes back on the same address.
    killed_at = kill(router)
    time.sleep(1.5)
    router_log = tmp_path / "router2.log"
    restarted_at = time.time()
    router = lan.start("router", _cli("router", "--listen", endpoint, "--json"), router_log, env=env, cwd=REPO)
    assert _wait(lambda: any("router" in d for d in _json_lines(router_log)), 30.0, 0.02), router_log.read_text()
    back_at = time.time()
    assert _wait(lambda: clients() == 3, RECONNECT_S, 0.05), f"not every client is back within " \
        f"{RECONNECT_S} s: {_json_lines(router_log)}"
    assert _wait(lambda: flowing(since=back_at, count=1), RECONNECT_S, 0.05), \
        f"a robot's messages do not reach the operator within {RECONNECT_S} s of the restart\n{logs()}"
    tally = received.read()
    # Each robot is back with the first message it sent well after the crash that got through (one sent in
    # the crash's first milliseconds may still have passed the dying router).
    resumed = {r: min((sent, got) for sent, got in tally[r].values() if sent > killed_at + 0.5) for r in ROBOTS}
    reconnect = {r: got - back_at for r, (_, got) in resumed.items()}
    assert all(s < RECONNECT_S for s in reconnect.values()), reconnect
    assert _wait(lambda: flowing(since=back_at, count=20), 10.0, 0.1), logs()

    # Stop the robots first (what they sent last still reaches the operator), then the operator.
    stopping_at = time.time()
    for process in robots.values():
        stop(process)
    time.sleep(1.0)
    stop(operator)
    _only_the_outage_was_lost(received, tmp_path, killed_at, {r: sent for r, (sent, _) in resumed.items()},
                              stopping_at)
    for name in ROBOTS:
        print(f"{name}: back {reconnect[name]:+.2f} s from the restarted router's ready line, "
              f"{resumed[name][1] - restarted_at:.2f} s from its start ({restarted_at - killed_at:.1f} s down)")


def _operator_sees_and_addresses_each_robot(lan: Lan, via: list[str], env: dict[str, str]) -> None:
    """``agentsctl`` on the operator's host: both robots' components and topics, and a call to each."""
    def run_cli(*args: str) -> Any:
        done = lan.run("operator", _cli(*args, *via, "--json"), timeout=60.0, env=env, cwd=REPO)
        assert done.returncode == 0, f"{args}: {done.stderr[-2000:]}"
        return json.loads(done.stdout)

    components = {c["name"]: c["state"] for c in run_cli("components", "list")}
    assert components == {"robot1/counter": "active", "robot2/counter": "active"}, components
    assert [c["name"] for c in run_cli("components", "list", "--namespace", "robot2")] == ["robot2/counter"]
    topics = {t["name"] for t in run_cli("topics", "list")}
    assert {"robot1/seq", "robot2/seq", "robot1/counter/status", "robot2/counter/status"} <= topics, topics
    assert run_cli("call", "robot1/counter", "identify")["result"].startswith("robot1 at seq ")
    assert run_cli("call", "counter", "identify", "--namespace", "robot2")["result"].startswith("robot2 at seq ")
    # agentsctl top through the router: a row for each robot's component, with its state and step figures.
    rows = {r["component"]: r for r in run_cli("top")}
    assert set(rows) == {"robot1/counter", "robot2/counter"}, rows
    assert all(r["state"] == "active" for r in rows.values()), rows


def _only_the_outage_was_lost(received: Received, tmp_path: Path, killed_at: float, resumed: dict[str, float],
                              stopping_at: float) -> None:
    """Per robot: what it sent (its own log) minus what the operator got is only what was sent during the outage."""
    tally = received.read()
    for name in ROBOTS:
        sent = {seq: t for seq, t in _sent(tmp_path / f"{name}.sent").items() if t < stopping_at - 0.5}
        lost = sorted(set(sent) - set(tally[name]))
        # Only what was sent while the router was down (until the robot was back) is missing.
        window = (killed_at - 0.3, resumed[name])
        outside = [seq for seq in lost if not window[0] <= sent[seq] <= window[1]]
        assert outside == [], f"{name}: lost outside the router's outage {window}: {outside[:20]}"
        most = RATE_HZ * (window[1] - window[0]) + 2
        assert 0 < len(lost) <= most, f"{name}: {len(lost)} lost (outage {window[1] - window[0]:.1f} s)"
        print(f"{name}: sent {len(sent)}, lost {len(lost)}, all sent in the {window[1] - window[0]:.1f} s "
              "between the crash and the robot's return")
