"""Item 8 of issue 38: a value of the wrong type is refused with an error that names the topic (it named only
the type), in a component's step as in a plain publisher."""

from __future__ import annotations

from typing import Any

import pytest

from agents_core import Launcher, Topic
from agents_core.components import Component
from agents_core.errors import TypeValidationError
from agents_core.testing.helpers import wait_for

COUNT = Topic("count", "Int32")


class Wrong(Component):
    """Publishes a str on an Int32 output."""

    def _execution_step(self, **kwargs: Any) -> None:
        self.publishers_dict["count"].publish("five")


def test_the_error_names_the_topic() -> None:
    wrong = Wrong(inputs=[], outputs=[COUNT], trigger=20.0, component_name="wrong")
    launcher = Launcher("memory")
    launcher.add_pkg(components=[wrong])
    with launcher:
        with pytest.raises(TypeValidationError, match=r"^topic 'count' \(Int32\): Int32 expects int, got str"):
            launcher.transport.create_publisher(COUNT).publish("five")
        assert wait_for(lambda: "topic 'count' (Int32)" in wrong.health_message, 5.0), wrong.health_message
