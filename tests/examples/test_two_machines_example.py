"""``examples/two_machines.py``: a router and two client processes that reach each other only through it.

Three processes on the loopback, as a user starts them: the router on an explicit
``tcp/127.0.0.1`` port, the robot and the operator as Zenoh clients of it (multicast scouting
off). The operator must print the robot's battery readings, and neither client may listen on
any TCP port (so no direct link between them is possible).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from agents_core.testing.helpers import free_tcp_port
from agents_core.testing.pairs import missing_requirement
from agents_core.testing.recipes import RecipeProcess, recipe_environment
from tests.cli.helpers import listening_tcp_ports

from .test_examples import EXAMPLES, _run_example

pytestmark = [pytest.mark.zenoh,
              pytest.mark.skipif(missing_requirement("zenoh") is not None, reason=str(missing_requirement("zenoh")))]


def test_robot_and_operator_talk_through_the_router(tmp_path: Path) -> None:
    port = free_tcp_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    example = EXAMPLES / "two_machines.py"
    router = RecipeProcess(example, ["router", "--listen", endpoint, "--seconds", "180"], tmp_path / "router.log",
                           env=recipe_environment())
    robot = None
    try:
        router.wait_ready(30)
        robot = RecipeProcess(example, ["robot", "--connect", endpoint, "--seconds", "180"], tmp_path / "robot.log",
                              env=recipe_environment())
        robot.wait_ready(60)
        # A client listens nowhere; the router listens on its one endpoint.
        assert listening_tcp_ports(robot.pid) == set()
        assert port in listening_tcp_ports(router.pid)
        out = _run_example("two_machines.py", "operator", "--connect", endpoint, "--once", "--seconds", "60",
                           timeout=120)
    finally:
        if robot is not None:
            robot.stop()
        router.stop()
    readings = [float(m) for m in re.findall(r"^operator got battery ([0-9.]+)%$", out, re.MULTILINE)]
    assert len(readings) >= 3, out
    # The robot's battery drains: the readings come from its running component, in order.
    assert readings == sorted(readings, reverse=True) and readings[0] < 100.0, readings


def test_two_machines_refuses_other_transports() -> None:
    import subprocess  # noqa: PLC0415
    import sys  # noqa: PLC0415

    done = subprocess.run([sys.executable, str(EXAMPLES / "two_machines.py"), "robot", "--transport", "memory"],
                          capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode != 0 and "Zenoh only" in done.stderr
