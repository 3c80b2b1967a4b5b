"""A component module for the fork-server tests: it records the process that imported it.

``IMPORTED_IN`` is the pid of the process that ran this module's top level. The fork server
imports it before forking, so a forked component process sees the server's pid there.
"""

from __future__ import annotations

import os
from typing import Any

from agents_core import Component, Topic
from agents_core.supported_types import String

IMPORTED_IN = os.getpid()


class WhereAmI(Component):
    """Answers each text with ``text:<pid that imported this module>:<own pid>``; holds a token it never shows."""

    def __init__(self, source: str, target: str, component_name: str, token: str = "", **kwargs: Any) -> None:
        self.allowed_inputs = {"Required": [String]}
        self.allowed_outputs = {"Required": [String]}
        inp = Topic(source, "String")
        super().__init__(inputs=[inp], outputs=[Topic(target, "String")], trigger=inp,
                         component_name=component_name, **kwargs)
        self.token = token

    def _execution_step(self, **kwargs: Any) -> None:
        text = self.trig_callbacks[self.inputs[0].name].get_output()
        self.publishers_dict[self.outputs[0].name].publish(f"{text}:{IMPORTED_IN}:{os.getpid()}")


class ReadsEnvironment(Component):
    """Answers each text, a variable's name, with ``<its value in this process's environment>:<own pid>``."""

    def __init__(self, source: str, target: str, component_name: str, **kwargs: Any) -> None:
        self.allowed_inputs = {"Required": [String]}
        self.allowed_outputs = {"Required": [String]}
        inp = Topic(source, "String")
        super().__init__(inputs=[inp], outputs=[Topic(target, "String")], trigger=inp,
                         component_name=component_name, **kwargs)

    def _execution_step(self, **kwargs: Any) -> None:
        name = self.trig_callbacks[self.inputs[0].name].get_output()
        self.publishers_dict[self.outputs[0].name].publish(f"{os.environ.get(name, '<unset>')}:{os.getpid()}")
