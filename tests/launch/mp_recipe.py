"""A recipe run by the process tests: ``python mp_recipe.py --transport zenoh --port P [...]``.

Its component class is defined here, in the recipe itself (the children import this file by
path, without running the ``__main__`` block). Two ``Shout`` components in a chain
(``mp/in`` -> shout_a -> ``mp/mid`` -> shout_b -> ``mp/out``) each upper-case the text and
append their suffix; a message on ``mp/cmd`` sets shout_b's suffix through an event and an
action that runs in shout_b's process. ``shout_a`` holds a client with an API key.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
from typing import Any

from agents_core import Component, Topic
from agents_core.actions import Action, component_action
from agents_core.clients.generic import GenericHTTPClient
from agents_core.events import Event
from agents_core.launch.launcher import Launcher
from agents_core.models import GenericLLM
from agents_core.supported_types import String


class Shout(Component):
    """Upper-cases each text and appends a suffix; the suffix is a component action."""

    def __init__(self, source: str, target: str, component_name: str, suffix: str = "!",
                 client: GenericHTTPClient | None = None, **kwargs: Any) -> None:
        self.allowed_inputs = {"Required": [String]}
        self.allowed_outputs = {"Required": [String]}
        inp = Topic(source, "String")
        super().__init__(inputs=[inp], outputs=[Topic(target, "String")], trigger=inp,
                         component_name=component_name, **kwargs)
        self.suffix = suffix
        self.client = client

    def _execution_step(self, **kwargs: Any) -> None:
        text = self.trig_callbacks[self.inputs[0].name].get_output()
        self.publishers_dict[self.outputs[0].name].publish(f"{text.upper()}{self.suffix}[{os.getpid()}]")

    @component_action
    def set_suffix(self, suffix: str) -> str:
        """Change the suffix appended to each text."""
        self.suffix = suffix
        return suffix


def announce_giveup() -> None:
    """The launcher's on_giveup action: a line the test waits for."""
    print("GAVE_UP", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--transport", default="zenoh")
    parser.add_argument("--port", type=int, default=0)
    parser.add_argument("--retries", type=int, default=3)
    parser.add_argument("--api-key", default=None)
    parser.add_argument("--config-file", default=None)
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO, stream=sys.stderr)
    # The key reaches the recipe on stdin in the tests, as a deployment would read it from a
    # secret store: never on this command line.
    api_key = sys.stdin.readline().strip() if args.api_key == "-" else args.api_key
    client = GenericHTTPClient(GenericLLM(name="llm", checkpoint="x"), host="127.0.0.1", port=9,
                               api_key=api_key)
    shout_a = Shout("mp/in", "mp/mid", "shout_a", suffix="!", client=client)
    shout_b = Shout("mp/mid", "mp/out", component_name="shout_b", suffix="?")
    cmd = Topic("mp/cmd", "String")
    options: dict[str, Any] = {}
    if args.transport == "zenoh" and args.port and not args.config_file:
        options = {"mode": "peer", "listen": [f"tcp/127.0.0.1:{args.port}"], "connect": [],
                   "multicast_scouting": False}
    launcher = Launcher(transport=None if args.config_file else args.transport,
                        transport_options=options or None, config_file=args.config_file)
    launcher.add_pkg(components=[shout_a, shout_b], multiprocessing=True,
                     events_actions={Event("set_suffix", cmd): Action(shout_b.set_suffix, args=(cmd.msg.data,))})
    launcher.on_process_fail(max_retries=args.retries, on_giveup=Action(announce_giveup))
    launcher.bringup()


if __name__ == "__main__":
    main()
