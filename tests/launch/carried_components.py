"""Component classes and functions that ``carried_recipe.py`` imports as a module next to it.

The recipe imports this file as the top-level module ``carried_components`` (its own directory is
on its ``sys.path``); a component process finds it only through the launcher's import path.
"""

from __future__ import annotations

import os
from typing import Any

from agents_core import Component
from agents_core.supported_types import String


class Ticker(Component):
    """Publishes ``tick[<pid>]`` at each step; meant to be triggered by an Event."""

    def __init__(self, **kwargs: Any) -> None:
        self.allowed_outputs = {"Required": [String]}
        super().__init__(**kwargs)

    def _execution_step(self, **kwargs: Any) -> None:
        event = kwargs.get("event")
        name = event.name if event is not None else "none"
        self.publishers_dict[self.outputs[0].name].publish(f"tick:{name}[{os.getpid()}]")


def tag_answer(text: str) -> str:
    """A publisher pre-processor: marks the text with the pid of the process that published it."""
    return f"{text} <tagged by {os.getpid()}>"


def lookup(key: str) -> str:
    """A tool for the LLM."""
    return key.upper()
