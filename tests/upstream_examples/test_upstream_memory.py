"""Upstream 0.7.4's Memory recipes (go_to_x, semantic_map, tool_calling) with a fake robot and local model servers.

Each recipe under ``recipes/v0_7_4/`` is upstream's file with the module renamed and its servers
swapped for local ones (``memory_servers.py``): a RoboML whose detector is the real COCO SSD, and an
Ollama whose embeddings follow the words and whose model turns "go to X" into a tool call. A fake
robot (``fake_robot.py``) stands in a kitchen (the coffee photo) and by a sofa (the cat photo); the
test checks that the memory stored what was seen at the place it was seen, that asking for a place
makes the LLM call the memory's ``locate`` (or the recipe's own tool), and that the goal point it
publishes is that place, where the robot then drives. Every recipe runs on memory in this process;
go_to_x also runs as a script on Zenoh and on ROS 2.
"""

from __future__ import annotations

import contextlib
import math
import os
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from agents_core.ros import Topic
from agents_core.testing.pairs import missing_requirement, private_ros_environment
from agents_core.testing.recipes import RecipeProcess, recipe_environment
from agents_core.transport.registry import resolve_transport

from ..components.vision_recipe import needs_ssd
from ..conftest import wait_for
from .fake_robot import FakeRobot, Place, photo
from .harness import RECIPES, ROOT, launched_as_script, launched_here
from .memory_servers import CocoRoboMLServer, GoToOllamaServer

pytest.importorskip("emem", reason="the memory extra is not installed (pip install 'agents-core[memory]')")

#: The COCO SSD runs in the RoboML stand-in (onnxruntime and the shared model files).
pytestmark = pytest.mark.local_models

V074 = RECIPES / "v0_7_4"
#: Every model the recipes ask the Ollama stand-in for.
MODELS = ["nomic-embed-text-v2-moe:latest", "qwen3.5:latest", "qwen2.5vl:latest"]
#: How many frames of a place's object the robot waits for there: locate averages its 10 best matches, and a
#: frame may be merged with the next into one snapshot.
FRAMES_PER_PLACE = 16


@contextlib.contextmanager
def servers(place_argument: str = "concept") -> Iterator[tuple[GoToOllamaServer, CocoRoboMLServer]]:
    """The Ollama and RoboML stand-ins (skips without the COCO SSD)."""
    model = needs_ssd()
    with GoToOllamaServer(MODELS, place_argument=place_argument) as ollama, CocoRoboMLServer(model) as roboml:
        yield ollama, roboml


def ports(ollama: GoToOllamaServer, roboml: CocoRoboMLServer, db: Path) -> dict[str, Any]:
    return {"UPSTREAM_OLLAMA_PORT": ollama.port, "UPSTREAM_ROBOML_RESP_PORT": roboml.resp_port,
            "UPSTREAM_MEMORY_DB": str(db)}


def house() -> tuple[Place, Place]:
    """The kitchen (a cup of coffee on a table) and the sofa (a cat)."""
    return Place("kitchen", 4.0, 1.0, photo("coffee.png")), Place("sofa", -2.0, 3.0, photo("chelsea.png"))


def labels_seen(transport: Any) -> list[list[str]]:
    """The labels of every Detections published from now on, one list per frame."""
    seen: list[list[str]] = []
    transport.create_subscription(Topic(name="detections", msg_type="Detections"),
                                  lambda d: seen.append(list(d.labels)))
    return seen


def frames_of(seen: list[list[str]], label: str, since: int) -> Callable[[], bool]:
    return lambda: sum(label in labels for labels in seen[since:]) >= FRAMES_PER_PLACE


def tour(robot: FakeRobot, seen: list[list[str]], kitchen: Place, sofa: Place) -> None:
    """The robot sees the cup in the kitchen, then the cat by the sofa (where it stays)."""
    for place, label in ((kitchen, "cup"), (sofa, "cat")):
        assert robot.visit(place, frames_of(seen, label, len(seen)), timeout=90), \
            f"fewer than {FRAMES_PER_PLACE} frames with a {label} at the {place.name}: {seen[-5:]}"


def near(goal: tuple[float, float, float], place: Place, tolerance: float = 0.3) -> bool:
    return math.hypot(goal[0] - place.x, goal[1] - place.y) <= tolerance


def go_to(transport: Any, robot: FakeRobot, where: str, place: Place) -> None:
    """Ask for ``where``; the goal point published is ``place`` and the robot drives there."""
    before = len(robot.goals)
    pub = transport.create_publisher(Topic(name="goto_in", msg_type="String"))
    try:
        # Across processes the first request can precede discovery: ask again, a bounded number of times.
        for _ in range(4):
            pub.publish(f"Go to the {where}")
            if wait_for(lambda: len(robot.goals) > before, timeout=15, interval=0.05):
                break
        assert len(robot.goals) > before, f"no goal point for {where!r}"
    finally:
        pub.close()
    goal = robot.goals[before]
    assert near(goal, place), f"goal {goal} for {where!r} is not at the {place.name} ({place.x}, {place.y})"
    assert wait_for(lambda: robot.arrived_at(goal[0], goal[1]), timeout=20), robot.position


def component(launcher: Any, name: str) -> Any:
    return next(c for c in launcher.components if c.component_name == name)


def stored_near(memory: Any, place: Place) -> str:
    """What the memory answers for the 0.5 m around ``place`` (everything buffered is written first)."""
    return str(memory.spatial_query(x=place.x, y=place.y, radius=0.5, n_results=50))


def check_memory(memory: Any, kitchen: Place, sofa: Place) -> None:
    at_kitchen, at_sofa = stored_near(memory, kitchen), stored_near(memory, sofa)
    assert "cup" in at_kitchen and "cat" not in at_kitchen, at_kitchen
    assert "cat" in at_sofa and "cup" not in at_sofa, at_sofa


# -- on memory, in this process ---------------------------------------------------------------------


def test_go_to_x_on_memory(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    kitchen, sofa = house()
    with servers() as (ollama, roboml), \
            launched_here(V074 / "go_to_x.py", ports(ollama, roboml, tmp_path / "go_to_x.db"), monkeypatch) as launcher:
        t = launcher.transport
        seen = labels_seen(t)
        with FakeRobot(t) as robot:
            tour(robot, seen, kitchen, sofa)
            check_memory(component(launcher, "memory"), kitchen, sofa)
            go_to(t, robot, "kitchen table", kitchen)  # "table": the kitchen's detections say "dining table"
            go_to(t, robot, "cat", sofa)
    chats = [r.json for r in ollama.requests_to("/api/chat")]
    offered = {tool["function"]["name"] for body in chats for tool in body.get("tools") or []}
    assert offered == {"locate"}, offered  # register_tools_on(tools=["locate"]) offered that one tool only


def test_tool_calling_on_memory(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    kitchen, sofa = house()
    db = tmp_path / "tool_calling.db"
    with servers(place_argument="place") as (ollama, roboml), \
            launched_here(V074 / "tool_calling.py", ports(ollama, roboml, db), monkeypatch) as launcher:
        t = launcher.transport
        seen = labels_seen(t)
        with FakeRobot(t) as robot:
            tour(robot, seen, kitchen, sofa)
            check_memory(component(launcher, "memory"), kitchen, sofa)
            go_to(t, robot, "cup", kitchen)
            go_to(t, robot, "cat", sofa)
    calls = [call["function"] for r in ollama.requests_to("/api/chat")
             for call in (r.json.get("tools") or [])]
    assert {c["name"] for c in calls} == {"find_location_coordinates"}, calls


def test_semantic_map_on_memory(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    kitchen, sofa = house()
    monkeypatch.setenv("UPSTREAM_TRIGGER", "2.0")  # the VLM and the memory every 0.5 s instead of every 15 s
    rooms = {kitchen.image.shape[1]: "kitchen", sofa.image.shape[1]: "bedroom"}  # type: ignore[union-attr]
    with servers() as (ollama, roboml):
        ollama.rooms = rooms
        with launched_here(V074 / "semantic_map.py", ports(ollama, roboml, tmp_path / "semantic_map.db"),
                           monkeypatch) as launcher:
            memory = component(launcher, "memory")
            with FakeRobot(launcher.transport) as robot:
                for place, things in ((kitchen, ("cup", "kitchen")), (sofa, ("cat", "bedroom"))):
                    assert robot.visit(place, lambda p=place, w=things: all(x in stored_near(memory, p) for x in w),
                                       timeout=90), (place.name, stored_near(memory, place))
            at_kitchen, at_sofa = stored_near(memory, kitchen), stored_near(memory, sofa)
            # Each object only where the robot saw it (the camera is off while it moves). The room may also be
            # stored once where the robot arrived: the VLM answers about the last photo it has, as upstream's does.
            assert "cat" not in at_kitchen and "bedroom" not in at_kitchen, at_kitchen
            assert "cup" not in at_sofa, at_sofa
            # And the memory finds each room by meaning where the robot was in it.
            for room, place in (("kitchen", kitchen), ("bedroom", sofa)):
                best = memory.semantic_search(query=room, layer="introspection_answer", n_results=1)
                assert f"({place.x:.1f},{place.y:.1f})" in best and room in best, best


def test_memory_without_an_embedding_client_names_the_fix(tmp_path: Path) -> None:
    # Upstream falls back to downloading a sentence-transformers model; here nothing is downloaded at run time,
    # so the recipe stops at construction with the argument to add.
    from agents_core.components import Memory  # noqa: PLC0415
    from agents_core.config import MemoryConfig  # noqa: PLC0415
    from agents_core.errors import WiringError  # noqa: PLC0415
    from agents_core.ros import MemLayer  # noqa: PLC0415

    with pytest.raises(WiringError, match="embedding_client must be a client that computes embeddings") as err:
        Memory(layers=[MemLayer(subscribes_to=Topic(name="detections", msg_type="Detections"))],
               position=Topic(name="odom", msg_type="Odometry"), config=MemoryConfig(db_path=str(tmp_path / "m.db")))
    assert "OllamaClient" in str(err.value) and "never downloads" in str(err.value)


# -- as a script, across processes --------------------------------------------------------------------


def _tour_and_go(asker: Any, process: RecipeProcess, kitchen: Place, sofa: Place) -> None:
    """The same tour and requests as on memory, through ``asker`` (the recipe runs in ``process``)."""
    seen = labels_seen(asker)
    with FakeRobot(asker) as robot:
        tour(robot, seen, kitchen, sofa)
        go_to(asker, robot, "kitchen table", kitchen)
        go_to(asker, robot, "cat", sofa)
    assert process.proc.poll() is None, process.output()


@pytest.mark.zenoh
@pytest.mark.slow
@pytest.mark.skipif(missing_requirement("zenoh") is not None, reason=str(missing_requirement("zenoh")))
def test_go_to_x_as_a_script_on_zenoh(tmp_path: Path) -> None:
    kitchen, sofa = house()  # skips (before anything starts) without the photos
    with servers() as (ollama, roboml), \
            launched_as_script(V074 / "go_to_x.py", ports(ollama, roboml, tmp_path / "go_to_x.db"),
                               tmp_path) as (process, asker):
        _tour_and_go(asker, process, kitchen, sofa)


@pytest.mark.ros2
@pytest.mark.slow
@pytest.mark.skipif(missing_requirement("ros2") is not None, reason=str(missing_requirement("ros2")))
def test_go_to_x_as_a_script_on_ros2(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # The domain the session was given, else one of this process's own; discovery stays on this host.
    kitchen, sofa = house()  # skips (before anything starts) without the photos
    domain = int(os.environ.get("ROS_DOMAIN_ID") or private_ros_environment())
    monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    with servers() as (ollama, roboml):
        env = recipe_environment(AGENTS_TRANSPORT="ros2", ROS_DOMAIN_ID=str(domain),
                                 PYTHONPATH=os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p),
                                 **{k: str(v) for k, v in ports(ollama, roboml, tmp_path / "go_to_x.db").items()})
        # The harness runs the file as ``python go_to_x.py`` would and prints READY once it is up.
        process = RecipeProcess("tests.upstream_examples.harness", [str(V074 / "go_to_x.py")],
                                tmp_path / "recipe.log", cwd=V074, env=env)
        asker = resolve_transport("ros2", domain_id=domain)
        try:
            process.wait_ready(120)
            _tour_and_go(asker, process, kitchen, sofa)
        except BaseException:
            raise AssertionError(f"go_to_x.py on ros2:\n{process.output()}") from None
        finally:
            asker.close()
            process.stop()
