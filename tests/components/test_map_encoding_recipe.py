"""The map recipe (map_recipe.py) on a real Chroma server with real llama.cpp embeddings (SmolLM2).

"Where is the cup?" must come back with the cup's coordinates (within one cell), and after the cup
moved (a temporal layer), with its new place; an LLM with RAG on the map gets the coordinates in
its context. Memory and each cross-process transport (the ``recipe_transport`` fixture, in this
process: one Zenoh session; on ROS 2 with a plain rclpy robot beside it) run the same recipe.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from typing import Any

import pytest

from agents_core import MemoryTransport, Topic
from agents_core.components import LLM
from agents_core.config import LLMConfig
from agents_core.testing.recipes import RecipeTransport
from agents_core.transport.contract import Transport

from ..clients.test_chroma_client import chroma_port  # noqa: F401  (fixtures, used by name)
from ..clients.test_components_on_real_servers import chroma  # noqa: F401
from ..clients.test_generic_client import llama_server  # noqa: F401
from ..conftest import wait_for
from . import map_recipe
from .scripted_client import ScriptedChatClient

pytestmark = pytest.mark.local_models


def _near(match: dict[str, Any], where: tuple[float, float]) -> float:
    return math.hypot(match["x"] - where[0], match["y"] - where[1])


def _recipe_on(transport: Transport, db_factory: Callable[..., Any], collection: str) -> dict[str, Any]:
    question, answer = Topic("question", "String"), Topic("answer", "String")
    client = ScriptedChatClient(["It is at the end of the corridor."])
    llm = LLM(inputs=[question], outputs=[answer], model_client=client, db_client=db_factory(collection),
              trigger=question, component_name="assistant",
              config=LLMConfig(enable_rag=True, collection_name=collection, n_results=1, add_metadata=True))
    llm.set_rag_filter({"layer": "seen"})

    def ask() -> str:
        answers: list[str] = []
        sub = transport.create_subscription(answer, answers.append)
        pub = transport.create_publisher(question)
        try:
            pub.publish("cup")
            assert wait_for(lambda: bool(answers), timeout=30)
        finally:
            pub.close()
            sub.close()
        return str(client.inputs[0]["query"][-1]["content"])

    return map_recipe.run(transport, db_factory(collection), collection, others=[llm], ask=ask)


def _check(found: dict[str, Any]) -> None:
    cell = map_recipe.RESOLUTION
    first, chair, later = found["first"][0], found["chair"][0], found["later"][0]
    assert first["text"] == "cup" and _near(first, map_recipe.CUP) <= cell, found["first"]
    assert chair["text"] == "chair" and _near(chair, map_recipe.CHAIR) <= cell, found["chair"]
    # Temporal layer: the old place now holds "nothing", the new place wins.
    assert later["text"] == "cup" and _near(later, map_recipe.CUP_LATER) <= cell, found["later"]
    context = found["asked"]
    assert "- cup (metadata:" in context and f'"x": {map_recipe.CUP_LATER[0]}' in context, context
    stats = found["mapper"].stats
    assert stats["written"] == 6 and stats["stale_position"] == stats["outside_map"] == stats["dropped"] == 0, stats


def test_where_is_the_cup_on_memory(chroma: Any) -> None:  # noqa: F811
    transport = MemoryTransport()
    try:
        _check(_recipe_on(transport, chroma, "map_memory"))
    finally:
        transport.close()


class _PlainRosRobot:
    """A plain rclpy node in a ROS context of its own (no agents_core): the robot's map server and odometry.

    It publishes nav_msgs/OccupancyGrid (latched) and nav_msgs/Odometry as any ROS 2 stack does.
    """

    def __init__(self, domain_id: int) -> None:
        import rclpy  # noqa: PLC0415  (only with the ros2 extra)
        from nav_msgs.msg import OccupancyGrid, Odometry  # noqa: PLC0415
        from rclpy.context import Context  # noqa: PLC0415
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: PLC0415

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)  # lark (via rosidl) imports sre_parse
            import rosidl_generator_py  # noqa: F401, PLC0415

        self._odometry_type = Odometry
        self._context = Context()
        rclpy.init(context=self._context, domain_id=domain_id)
        self._node = rclpy.create_node("plain_robot", context=self._context)
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                             reliability=ReliabilityPolicy.RELIABLE)
        self._map = self._node.create_publisher(OccupancyGrid, "/map", latched)
        self._odom = self._node.create_publisher(Odometry, "/odom", 10)
        grid = OccupancyGrid()
        grid.header.frame_id = "map"
        grid.info.resolution = map_recipe.RESOLUTION
        grid.info.width, grid.info.height = map_recipe.SIZE
        grid.info.origin.position.x, grid.info.origin.position.y = map_recipe.ORIGIN
        grid.info.origin.orientation.w = 1.0
        grid.data = [0] * (map_recipe.SIZE[0] * map_recipe.SIZE[1])
        self._map.publish(grid)

    def send_odometry(self, x: float, y: float) -> None:
        message = self._odometry_type()
        message.header.frame_id = "map"
        message.pose.pose.position.x, message.pose.pose.position.y = x, y
        message.pose.pose.orientation.w = 1.0
        self._odom.publish(message)

    def close(self) -> None:
        self._node.destroy_node()
        self._context.try_shutdown()


def _on_the_framework(recipe_transport: RecipeTransport, db_factory: Callable[..., Any]) -> None:
    collection = f"map_{recipe_transport.name}"
    _check(_recipe_on(recipe_transport.open_recipe_side(), db_factory, collection))


def _with_a_plain_ros_robot(recipe_transport: RecipeTransport, db_factory: Callable[..., Any]) -> None:
    """The map and odometry come from a plain rclpy node (the robot's own stack), not from the recipe."""
    assert recipe_transport.domain_id is not None
    robot = _PlainRosRobot(recipe_transport.domain_id)
    try:
        collection = "map_ros2"
        found = map_recipe.run(recipe_transport.open_recipe_side(), db_factory(collection), collection,
                               send_odometry=robot.send_odometry, serve_map=False)
        cell = map_recipe.RESOLUTION
        assert found["first"][0]["text"] == "cup" and _near(found["first"][0], map_recipe.CUP) <= cell, found
        assert _near(found["chair"][0], map_recipe.CHAIR) <= cell, found["chair"]
        assert _near(found["later"][0], map_recipe.CUP_LATER) <= cell, found["later"]
        assert found["mapper"].stats["outside_map"] == found["mapper"].stats["dropped"] == 0
    finally:
        recipe_transport.close()
        robot.close()


#: How the recipe runs on each transport; on the framework alone where none is named.
RUN_ON: dict[str, Callable[[RecipeTransport, Callable[..., Any]], None]] = {"ros2": _with_a_plain_ros_robot}


def test_where_is_the_cup_on_a_cross_process_transport(recipe_transport: RecipeTransport,
                                                        chroma: Any) -> None:  # noqa: F811
    RUN_ON.get(recipe_transport.name, _on_the_framework)(recipe_transport, chroma)
