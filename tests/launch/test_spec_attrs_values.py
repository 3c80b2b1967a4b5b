"""Values of any attrs class (not only configs) cross to a component process: upstream's SemanticRouter recipes.

Upstream's ``semantic_router.py`` passes ``Route`` objects (an attrs class, not a config) to the
router; with ``multiprocessing=True`` its spec refused them ("a Route cannot be sent to a component
process"), so the recipe could not run in its own processes (issue 26).
"""

from __future__ import annotations

from typing import Any

import attrs

from agents_core.clients import ChromaClient
from agents_core.components import SemanticRouter
from agents_core.config import SemanticRouterConfig
from agents_core.launch.spec import ComponentSpec, check_rebuild, decode_value, encode_value
from agents_core.ros import Route, Topic
from agents_core.vectordbs import ChromaDB


@attrs.define(kw_only=True)
class Waypoint:
    """A recipe's own attrs data class, with a field left out of ``__init__``."""

    name: str
    xyz: tuple[float, ...]
    visits: int = attrs.field(init=False, default=0)


def _routes() -> list[Route]:
    chat: Any = ["How are you?", "Whats up?"]  # Any: mypy reads Route.samples through its converter
    goto: Any = ["Go to the door"]
    return [Route(routes_to=Topic(name="chat_in", msg_type="String"), samples=chat),
            Route(routes_to=Topic(name="goto_in", msg_type="String"), samples=goto)]


def test_a_route_round_trips() -> None:
    route = _routes()[0]
    assert decode_value(encode_value(route)) == route


def test_an_attrs_class_of_the_recipe_round_trips_through_its_init_fields() -> None:
    point = Waypoint(name="kitchen", xyz=(1.0, 2.0, 0.0))
    back = decode_value(encode_value(point))
    assert isinstance(back, Waypoint) and back == point


def test_a_semantic_router_with_routes_is_rebuilt_for_its_own_process() -> None:
    routes = _routes()
    router = SemanticRouter(inputs=[Topic(name="question", msg_type="String")], routes=routes,
                            default_route=routes[0], config=SemanticRouterConfig(router_name="r", distance_func="l2"),
                            db_client=ChromaClient(db=ChromaDB(), port=9), component_name="router")
    spec = ComponentSpec.from_component(router, "memory", {}, 0)
    check_rebuild(router, spec)  # refuses any difference the child would have
    rebuilt = ComponentSpec.from_dict(spec.to_dict()).build()
    assert isinstance(rebuilt, SemanticRouter)
    assert rebuilt.routes == routes and rebuilt.default_route == routes[0]
