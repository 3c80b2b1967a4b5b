"""A component module that starts a helper process when it is imported (issue: the fork server's subreaper).

Importing it starts ``sleep 300`` and writes ``helper.<importer pid>`` (the helper's pid) in the folder
``$SPAWNING_MARKERS``: the fork server imports it (it preloads the component classes' modules), so the
server has a child of its own that is no component's orphan. :class:`Bystander` writes
``bystander.<pid>`` on activate.
"""

from __future__ import annotations

import os
import subprocess
from pathlib import Path
from typing import Any

from agents_core import Component, Topic
from agents_core.supported_types import String

_MARKERS = os.environ.get("SPAWNING_MARKERS", "")
if _MARKERS:
    _helper = subprocess.Popen(["sleep", "300"])
    Path(_MARKERS, f"helper.{os.getpid()}").write_text(f"{_helper.pid}\n")


class Bystander(Component):
    """Does nothing; it only has to stay up while another component process dies."""

    def __init__(self, component_name: str, markers: str, **kwargs: Any) -> None:
        self.allowed_inputs = {"Required": [String]}
        source = Topic("bystander/in", "String")
        super().__init__(inputs=[source], trigger=source, component_name=component_name, **kwargs)
        self.markers = markers

    def custom_on_activate(self) -> None:
        Path(self.markers, f"bystander.{os.getpid()}").write_text("")

    def _execution_step(self, **kwargs: Any) -> None:
        pass
