"""A small real recipe for the MCP tests: an Arm whose ``move`` is bounded and ``launch`` needs a yes.

``python -m tests.mcp.mcp_parts --listen tcp/127.0.0.1:PORT`` runs it on Zenoh (``--transport ros2``: on
ROS 2) in its own process (the stdio test's "recipe running elsewhere"); it prints READY once active and
stops on SIGTERM.
"""

from __future__ import annotations

import argparse
import signal
import threading
from typing import Any

from agents_core import Launcher, Topic
from agents_core.actions import component_action
from agents_core.components import Component
from agents_core.ros import String

COMMANDS = Topic("commands", "String")
MOTION = Topic("motion", "String")


class Arm(Component):
    """Publishes what it did on ``motion``; counts its moves (``moves``) to prove a refused call never ran."""

    def __init__(self, **kwargs: Any) -> None:
        self.allowed_inputs = {"Required": [String]}
        self.allowed_outputs = {"Required": [String]}
        self.moves: list[float] = []
        self.launches: list[str] = []
        super().__init__(**kwargs)

    def _execution_step(self, **kwargs: Any) -> None:
        pass

    @component_action(limits={"speed": (0.0, 0.5)})
    def move(self, speed: float, distance: float = 1.0) -> str:
        """Move the arm forward.

        :param speed: metres a second
        :param distance: metres
        """
        self.moves.append(speed)
        self.publishers_dict[MOTION.name].publish(f"moved {distance} m at {speed} m/s")
        return f"moved {distance} m at {speed} m/s"

    @component_action(approval=True, approval_timeout=5.0)
    def launch(self, target: str) -> str:
        """Throw the payload at ``target`` (needs a person's yes).

        :param target: where to
        """
        self.launches.append(target)
        self.publishers_dict[MOTION.name].publish(f"launched at {target}")
        return f"launched at {target}"

    @component_action
    def count(self) -> int:
        """How many moves ran."""
        return len(self.moves)


class PatientArm(Arm):
    """The Arm of a recipe in another process: its yes comes from ``agentsctl approve``, itself a new process
    (seconds to start on a loaded machine), so the call waits longer than the in-process tests' 5 s."""

    @component_action(approval=True, approval_timeout=45.0)
    def launch(self, target: str) -> str:
        """Throw the payload at ``target`` (needs a person's yes).

        :param target: where to
        """
        return super().launch(target)


def arm(name: str = "arm", kind: type[Arm] = Arm) -> Arm:
    return kind(inputs=[COMMANDS], outputs=[MOTION], trigger=COMMANDS, component_name=name)


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--transport", default="zenoh", choices=["zenoh", "ros2"])
    parser.add_argument("--listen", help="the Zenoh endpoint (tcp/127.0.0.1:PORT)")
    args = parser.parse_args()
    options = ({"mode": "peer", "listen": [args.listen], "connect": [], "multicast_scouting": False}
               if args.transport == "zenoh" else {})
    launcher = Launcher(args.transport, transport_options=options)
    launcher.add_pkg(components=[arm(kind=PatientArm)])
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    with launcher:
        print("READY", flush=True)
        stop.wait(300)  # bounded: the test stops it long before
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
