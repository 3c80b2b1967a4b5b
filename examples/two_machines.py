"""Two machines through a Zenoh router: the robot's recipe on one, the operator's on the other.

Three processes, each started with a role (the ``zenoh`` extra):

- ``router``: a Zenoh router; the only process that listens (what ``agentsctl router`` runs);
- ``robot``: a ``battery`` component that reports its charge on ``battery`` (Float32) at 5 Hz;
- ``operator``: a ``monitor`` component that prints each reading and publishes a warning on
  ``alerts`` (String) when the charge is low.

The robot and the operator are Zenoh *clients* of the router: they listen on nothing and never
scout by multicast, so everything they exchange goes through the router's one endpoint. On one
host (the loopback) or on two (the router on the robot, ``192.168.1.10`` here)::

    python examples/two_machines.py router --listen tcp/127.0.0.1:7447      # robot: tcp/0.0.0.0:7447
    python examples/two_machines.py robot --connect tcp/127.0.0.1:7447     # robot
    python examples/two_machines.py operator --connect tcp/127.0.0.1:7447  # laptop: tcp/192.168.1.10:7447

``--once`` stops the operator after three readings; ``--seconds N`` stops any role after N seconds.

A fleet: start the same robot several times under namespaces, and point the operator at one::

    python examples/two_machines.py robot --connect tcp/127.0.0.1:7447 --namespace robot1
    python examples/two_machines.py robot --connect tcp/127.0.0.1:7447 --namespace robot2
    python examples/two_machines.py operator --connect tcp/127.0.0.1:7447 --robot robot2   # robot2/battery

(``agentsctl components list --connect tcp/127.0.0.1:7447`` shows ``robot1/battery`` and ``robot2/battery``;
see docs/fleet.md.)
"""

from __future__ import annotations

import argparse
import sys
import threading
import time
from typing import Any

from example_cli import parser, run

from agents_core import Launcher, Topic
from agents_core.components import Component

BATTERY = Topic("battery", "Float32")
ALERTS = Topic("alerts", "String")
#: Below this charge (percent) the operator's monitor raises an alert.
LOW = 20.0


class Battery(Component):
    """The robot's battery: reports a charge that drops a little at each step."""

    def __init__(self, **kwargs: Any) -> None:
        self.charge = 100.0
        super().__init__(**kwargs)

    def _execution_step(self, **kwargs: Any) -> None:
        self.charge = max(0.0, self.charge - 0.5)
        self.publishers_dict["battery"].publish(self.charge)


class Monitor(Component):
    """Prints each reading it receives; publishes an alert when the charge is low."""

    def __init__(self, readings: threading.Event | None = None, **kwargs: Any) -> None:
        self.count = 0
        self._readings = readings
        super().__init__(**kwargs)

    def _execution_step(self, **kwargs: Any) -> None:
        watched = next(iter(self.trig_callbacks))
        charge = self.trig_callbacks[watched].get_output()
        if charge is None:
            return
        robot = f" from {watched.rsplit('/', 1)[0]}" if "/" in watched else ""
        print(f"operator got battery {float(charge):.1f}%{robot}\n", end="", flush=True)
        if charge < LOW:
            self.publishers_dict["alerts"].publish(f"battery low: {float(charge):.0f}%")
        self.count += 1
        if self.count >= 3 and self._readings is not None:
            self._readings.set()


def serve_router(args: argparse.Namespace) -> None:
    """The router: listens on ``--listen`` until Ctrl-C (or ``--seconds``)."""
    from agents_zenoh.router import open_router  # noqa: PLC0415  (the zenoh extra)

    session = open_router(args.listen or ["tcp/127.0.0.1:7447"])
    try:
        print("READY", flush=True)
        deadline = time.monotonic() + (args.seconds if args.seconds is not None else float("inf"))
        while time.monotonic() < deadline:
            time.sleep(0.2)
    except KeyboardInterrupt:
        pass
    finally:
        session.close()  # type: ignore[no-untyped-call]  # zenoh's stub leaves it unannotated


def main(argv: list[str] | None = None) -> None:
    """Run one role: router, robot or operator."""
    p = parser(__doc__)
    p.add_argument("role", choices=["router", "robot", "operator"])
    p.add_argument("--robot", default=None, metavar="NAMESPACE",
                   help="operator: watch this robot's battery (<NAMESPACE>/battery; default: battery)")
    p.set_defaults(transport="zenoh")
    args = p.parse_args(argv)
    if args.transport != "zenoh":
        sys.exit("two_machines.py runs on Zenoh only (a router joins the machines)")
    if args.role == "router":
        serve_router(args)
        return
    # A client of the router: no listen endpoint, no multicast scouting; the router is the one way in.
    launcher = Launcher(transport="zenoh", transport_options={
        "mode": "client", "connect": args.connect or ["tcp/127.0.0.1:7447"], "multicast_scouting": False},
        namespace=args.namespace)
    readings = threading.Event()
    if args.role == "robot":
        launcher.add_pkg(components=[Battery(inputs=[], outputs=[BATTERY], trigger=5.0, component_name="battery")])
    else:
        watched = Topic(f"{args.robot}/battery", "Float32") if args.robot else BATTERY
        launcher.add_pkg(components=[Monitor(readings, inputs=[watched], outputs=[ALERTS], trigger=watched,
                                             component_name="monitor")])
    run(launcher, args, done=readings)


if __name__ == "__main__":
    main()
