"""The fleet test's recipe: every robot runs the same one, under its own namespace; and the operator's tally.

``agentsctl run tests/fleet/fleet_recipe.py --transport zenoh --connect EP --namespace robot1 robot SENT``
runs a ``counter`` component that publishes ``"<seq> <time sent>"`` on its relative topic ``seq``
(``robot1/seq`` on the wire) at 20 Hz, appending each ``<seq> <time sent>`` to the file ``SENT``
as it publishes; its action ``identify()`` answers with the namespace it runs under.

``agentsctl run tests/fleet/fleet_recipe.py --transport zenoh --connect EP operator RECEIVED robot1 robot2``
subscribes to each robot's ``<robot>/seq`` and appends ``<robot> <seq> <time sent> <time received>``
to ``RECEIVED`` for each message, until SIGINT.
"""

from __future__ import annotations

import os
import sys
import threading
import time
from pathlib import Path
from typing import Any

from agents_core import Launcher, Topic
from agents_core.actions import component_action
from agents_core.components import Component

SEQ = Topic("seq", "String")
RATE_HZ = 20.0


class Counter(Component):
    """Publishes a sequence number and the time it was sent; logs what it sent."""

    def __init__(self, sent_log: str = "", **kwargs: Any) -> None:
        self.seq = 0
        self.sent_log = sent_log
        super().__init__(**kwargs)

    def _execution_step(self, **kwargs: Any) -> None:
        now = time.time()
        self.publishers_dict["seq"].publish(f"{self.seq} {now:.6f}")
        with open(self.sent_log, "a") as log:
            log.write(f"{self.seq} {now:.6f}\n")
        self.seq += 1

    @component_action
    def identify(self) -> str:
        """Which robot this is (the namespace its launcher runs under)."""
        return f"{os.environ.get('AGENTS_NAMESPACE', '')} at seq {self.seq}"


def robot(sent_log: str) -> None:
    """One robot: the namespace comes from ``agentsctl run --namespace`` (AGENTS_NAMESPACE)."""
    launcher = Launcher()
    launcher.add_pkg(components=[Counter(sent_log=sent_log, inputs=[], outputs=[SEQ], trigger=RATE_HZ,
                                         component_name="counter")])
    launcher.bringup()


def operator(received: str, robots: list[str]) -> None:
    """The operator's tally of every robot's sequence numbers."""
    from agents_core.transport.registry import resolve_transport  # noqa: PLC0415

    transport = resolve_transport(None)  # Zenoh, a client of the router (agentsctl run --connect)
    lock = threading.Lock()
    out = Path(received).open("a")  # noqa: SIM115  # closed below

    def tally(robot_name: str) -> Any:
        def count(value: Any) -> None:
            seq, sent = str(value).split()
            with lock:
                out.write(f"{robot_name} {seq} {sent} {time.time():.6f}\n")
                out.flush()
        return count

    try:
        for name in robots:
            transport.create_subscription(Topic(f"{name}/seq", "String"), tally(name))
        print("READY", flush=True)
        while True:
            time.sleep(0.2)
    except KeyboardInterrupt:
        pass
    finally:
        transport.close()
        out.close()


if __name__ == "__main__":
    if sys.argv[1:2] == ["robot"]:
        robot(sys.argv[2])
    elif sys.argv[1:2] == ["operator"]:
        operator(sys.argv[2], sys.argv[3:])
    else:
        sys.exit("usage: fleet_recipe.py robot SENT | operator RECEIVED ROBOT...")
