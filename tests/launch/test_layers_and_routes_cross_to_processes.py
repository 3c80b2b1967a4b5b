"""MapLayer and Route reach a component's own process (upstream's complete_agent_multiprocessing passes both)."""

from __future__ import annotations

import numpy as np

from agents_core.components import MapLayer
from agents_core.launch.spec import decode_value, encode_value
from agents_core.ros import Route, Topic


def test_a_map_layer_with_an_array_position_round_trips() -> None:
    layer = MapLayer(subscribes_to=Topic(name="rooms", msg_type="String"), resolution_multiple=3,
                     pre_defined=[(np.array([1.1, 2.1, 3.2]), "The door is here.")], template="room: {{ text }}")
    copy = decode_value(encode_value(layer, "layers[0]"))
    assert isinstance(copy, MapLayer)
    assert (copy.name, copy.resolution_multiple) == ("rooms", 3)
    assert copy.pre_defined == [((1.1, 2.1, 3.2), "The door is here.")]
    assert copy.text_of("kitchen") == "room: kitchen"  # the template is compiled again in the process


def test_a_route_round_trips() -> None:
    route = Route(routes_to=Topic(name="goto_query", msg_type="String"), samples=["Go to the door", "Fetch a ball"])
    copy = decode_value(encode_value(route, "routes[0]"))
    assert isinstance(copy, Route)
    assert (copy.name, copy.samples) == ("goto_query", ["Go to the door", "Fetch a ball"])
