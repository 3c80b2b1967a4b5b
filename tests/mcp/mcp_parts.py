"""A small real recipe for the MCP tests: an Arm whose ``move`` is bounded and ``launch`` needs a yes.

``python -m tests.mcp.mcp_parts --listen tcp/127.0.0.1:PORT`` runs it on Zenoh (``--transport ros2``: on
ROS 2) in its own process (the stdio test's "recipe running elsewhere"); it prints READY once active and
stops on SIGTERM.
"""

from __future__ import annotations

from typing import Any

from agents_core import Topic
from agents_core.actions import component_action
from agents_core.components import Component
from agents_core.ros import String

from ..serve_recipe import serve

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
    return serve(lambda: [arm(kind=PatientArm)])


if __name__ == "__main__":
    raise SystemExit(main())
