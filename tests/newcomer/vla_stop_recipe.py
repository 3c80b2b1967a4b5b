"""A VLA recipe as upstream writes it: the termination event is set before the launch, on a topic condition.

``python -m tests.newcomer.vla_stop_recipe --transport zenoh --listen tcp/127.0.0.1:PORT --policy-port P
[--multiprocessing]``: the VLA of :mod:`tests.components.vla_recipe`; a goal ends successfully when
``arm_done`` (Bool) carries True. Prints ``READY`` once active.
"""

from __future__ import annotations

import argparse

from agents_core import Launcher, Topic
from agents_core.events import Event
from tests.components.recipe_main import serve, transport_options
from tests.components.vla_recipe import build

DONE = Topic(name="arm_done", msg_type="Bool")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--transport", required=True, choices=["memory", "zenoh", "ros2"])
    parser.add_argument("--listen", default=None)
    parser.add_argument("--policy-port", type=int, required=True)
    parser.add_argument("--multiprocessing", action="store_true")
    args = parser.parse_args(argv)
    vla = build(args.policy_port)
    vla.set_termination_trigger("event", stop_event=Event(DONE.msg.data == True))  # noqa: E712  # a condition
    launcher = Launcher(transport=args.transport, transport_options=transport_options(args.transport, args.listen))
    launcher.add_pkg(components=[vla], multiprocessing=args.multiprocessing)
    serve(launcher)


if __name__ == "__main__":
    main()
