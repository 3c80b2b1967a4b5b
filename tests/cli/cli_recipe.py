"""The recipe the CLI tests inspect: a talker and a listener, run with ``agentsctl run``.

``agentsctl run tests/cli/cli_recipe.py [--transport ...] [--connect ...] -- [all|talker|listener]``

- ``talker`` publishes ``"<word> <n>"`` on ``chatter`` and a 48x64 RGB image on ``camera`` at
  20 Hz; its action ``set_word(word)`` changes the word;
- ``listener`` publishes the upper-cased text of its input on ``shout``: its input is ``words``
  when both run in this process (``all``), and ``chatter`` when it runs alone (``listener``), so
  that two processes started with ``talker`` and ``listener`` talk to each other.

The transport comes from ``AGENTS_TRANSPORT`` (``Launcher()`` with no transport), Zenoh
endpoints from ``AGENTS_ZENOH_*``, as ``agentsctl run`` sets them.
"""

from __future__ import annotations

import sys
from typing import Any

import numpy as np

from agents_core import Launcher, Topic
from agents_core.actions import component_action
from agents_core.components import Component


class Talker(Component):
    """Says ``<word> <n>`` and shows a black image at each step."""

    def __init__(self, **kwargs: Any) -> None:
        self.word = "tick"
        self.count = 0
        super().__init__(**kwargs)

    def _execution_step(self, **kwargs: Any) -> None:
        self.count += 1
        self.publishers_dict["chatter"].publish(f"{self.word} {self.count}")
        self.publishers_dict["camera"].publish(np.zeros((48, 64, 3), np.uint8))

    @component_action
    def set_word(self, word: str) -> str:
        """Change the word the talker says."""
        self.word = str(word)
        return f"now saying {self.word}"


class Listener(Component):
    """Publishes what it hears, upper-cased, on its output."""

    def _execution_step(self, **kwargs: Any) -> None:
        value = next(iter(self.trig_callbacks.values())).get_output()
        if value is not None:
            for publisher in self.publishers_dict.values():
                publisher.publish(str(value).upper())


def build(which: str) -> list[Component]:
    """The components to run for ``which`` (all, talker or listener)."""
    parts: list[Component] = []
    if which in ("all", "talker"):
        parts.append(Talker(inputs=[], outputs=[Topic("chatter", "String"), Topic("camera", "Image")],
                            trigger=20.0, component_name="talker"))
    if which in ("all", "listener"):
        heard = Topic("words" if which == "all" else "chatter", "String")
        parts.append(Listener(inputs=[heard], outputs=[Topic("shout", "String")], trigger=heard,
                              component_name="listener"))
    if not parts:
        raise SystemExit(f"usage: cli_recipe.py [all|talker|listener], got {which!r}")
    return parts


if __name__ == "__main__":
    launcher = Launcher()
    launcher.add_pkg(components=build(sys.argv[1] if len(sys.argv) > 1 else "all"))
    print("RECIPE STARTING", flush=True)
    launcher.bringup()
