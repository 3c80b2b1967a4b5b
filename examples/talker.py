"""A talker and a listener: the recipe the ``agentsctl`` section of the README uses.

``talker`` says ``"<word> <n>"`` on ``chatter`` at 5 Hz; its action ``set_word(word)``
(a ``@component_action``) changes the word. ``listener`` prints what it hears, upper-cased, and
publishes it on ``shout``.

Run it::

    python examples/talker.py                      # memory transport, until Ctrl-C
    python examples/talker.py --transport zenoh    # then, in another terminal:
    agentsctl topics echo chatter
    agentsctl call talker set_word '{"word": "hello"}'

``--once`` stops after the listener has heard three lines, ``--seconds N`` after N seconds.
"""

from __future__ import annotations

import threading
from typing import Any

from example_cli import make_launcher, parser, run

from agents_core import Topic
from agents_core.actions import component_action
from agents_core.components import Component

CHATTER = Topic("chatter", "String")
SHOUT = Topic("shout", "String")


class Talker(Component):
    """Says ``<word> <n>`` at each step."""

    def __init__(self, **kwargs: Any) -> None:
        self.word = "tick"
        self.count = 0
        super().__init__(**kwargs)

    def _execution_step(self, **kwargs: Any) -> None:
        self.count += 1
        self.publishers_dict["chatter"].publish(f"{self.word} {self.count}")

    @component_action
    def set_word(self, word: str) -> str:
        """Change the word the talker says."""
        self.word = str(word)
        return f"now saying {self.word}"


class Listener(Component):
    """Prints what it hears, upper-cased, and publishes it on ``shout``."""

    def __init__(self, heard: threading.Event | None = None, **kwargs: Any) -> None:
        self.lines = 0
        self._heard = heard
        super().__init__(**kwargs)

    def _execution_step(self, **kwargs: Any) -> None:
        value = self.trig_callbacks["chatter"].get_output()
        if value is None:
            return
        text = str(value).upper()
        print(f"heard: {text}", flush=True)
        self.publishers_dict["shout"].publish(text)
        self.lines += 1
        if self.lines >= 3 and self._heard is not None:
            self._heard.set()


def main(argv: list[str] | None = None) -> None:
    """Run the talker and the listener."""
    args = parser(__doc__).parse_args(argv)
    heard = threading.Event()
    launcher = make_launcher(args)
    launcher.add_pkg(components=[
        Talker(inputs=[], outputs=[CHATTER], trigger=5.0, component_name="talker"),
        Listener(heard, inputs=[CHATTER], outputs=[SHOUT], trigger=CHATTER, component_name="listener"),
    ])
    run(launcher, args, done=heard)


if __name__ == "__main__":
    main()
