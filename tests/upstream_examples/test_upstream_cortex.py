"""Upstream 0.7.4's Cortex recipes (``cortex_agent.py``, ``memory_with_cortex.py``), run with only the module renamed.

The planner is a real HTTP server on 127.0.0.1 replaying scripted tool calls and confirmations
(:class:`tests.servers.scripted_ollama_server.ScriptedOllamaServer`): a small local model cannot
plan these tasks reliably, and the tests check what the plan did, not what a model chose. The VLM
and the embeddings are the same Ollama stand-in's plain answers; the detector is the RoboML RESP
stand-in (``cortex_agent``) or the shared COCO detector (``memory_with_cortex``); the speaker is
:mod:`sound_device_standin`. A fake robot publishes the shared photos on the camera topic (and,
for Memory, odometry and a battery level). Each test sends a task goal to Cortex and checks that
the plan's actions really ran (the LED, tracking, a description, speech, Memory's answers) and the
task's result: in this process on memory, in one process per component on Zenoh, and on ROS 2.
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading
import time
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import pytest

from agents_core.messages import Header, OdometryMsg, PoseMsg
from agents_core.ros import Topic
from agents_core.testing.pairs import missing_requirement, private_ros_environment
from agents_core.testing.recipes import RecipeProcess, recipe_environment
from agents_core.transport.contract import Transport
from agents_core.transport.goals import GoalStatus
from agents_core.transport.registry import resolve_transport

from ..conftest import wait_for
from ..servers.roboml_server import RoboMLTestServer
from ..servers.scripted_ollama_server import ScriptedOllamaServer, calls, text
from .harness import RECIPES, ROOT, launched_here, launched_in_processes
from .sound_device_standin import sounddevice as sound

V074 = RECIPES / "v0_7_4"
SOUND_STANDIN = Path(__file__).resolve().parent / "sound_device_standin"
#: Every model name the two recipes ask the Ollama stand-in for.
OLLAMA_MODELS = ["qwen3.5:latest", "qwen2.5vl:latest", "gemma4:latest", "nomic-embed-text-v2-moe:latest"]

pytestmark = pytest.mark.local_models


@pytest.fixture
def speaker(monkeypatch: pytest.MonkeyPatch) -> list[tuple[int, int]]:
    """The stand-in sound card, as ``import sounddevice`` finds it in this process."""
    monkeypatch.setitem(sys.modules, "sounddevice", sound)
    sound.played.clear()
    return sound.played


def _photo(name: str = "astronaut.png") -> Any:
    from ..components.vision_recipe import photo  # noqa: PLC0415  (needs Pillow)

    return photo(name)


class Camera:
    """A fake robot's camera (and odometry): publishes a shared photo at 5 Hz until stopped."""

    def __init__(self, transport: Any, extra: list[tuple[Topic, Any]] | None = None) -> None:
        self._pubs = [(transport.create_publisher(Topic(name="/image_raw", msg_type="Image")), _photo())]
        self._pubs += [(transport.create_publisher(topic), value) for topic, value in extra or []]
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="fake-camera", daemon=True)

    def _run(self) -> None:
        while not self._stop.wait(0.2):
            for pub, value in self._pubs:
                pub.publish(value)

    def __enter__(self) -> Camera:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(5)
        for pub, _ in self._pubs:
            pub.close()


def _send_task(transport: Any, task: str, timeout: float = 60.0) -> tuple[GoalStatus, dict[str, Any], list[str]]:
    feedback: list[str] = []
    goal = transport.send_goal("cortex", "VisionLanguageAction", {"task": task},
                               feedback=lambda f: feedback.append(str(f.get("status"))), timeout=10.0)
    assert goal.accepted, goal.result(0.1)
    status, result = goal.result(timeout)
    return status, result, feedback


def _collect(transport: Any, name: str, msg_type: str) -> list[Any]:
    got: list[Any] = []
    transport.create_subscription(Topic(name=name, msg_type=msg_type), got.append)
    return got


# -- cortex_agent.py ------------------------------------------------------------------------------------

CORTEX_AGENT = V074 / "cortex_agent.py"
DESCRIPTION = "A person in a white space suit."


def _cortex_agent_script() -> dict[str, Any]:
    """Research the camera, then: follow the detector's label, describe, say it, toggle the LED; then answer."""
    return {"plan": [calls(("inspect_component", {"component": "vision"})),
                     calls(("vision.track", {"label": "object"}), ("vlm.describe", {"query": "What do you see?"}),
                           ("tts.say", {"text": "<output from step 2>"}), ("toggle_led", {})),
                     text("I am tracking the object, said what I see and turned the LED on.")],
            # The third confirmation fills the placeholder with the description, as the model would.
            "confirm": [text("EXECUTE"), text("EXECUTE"),
                        calls(("tts.say", {"text": DESCRIPTION}), answer="EXECUTE: the description is known"),
                        text("EXECUTE")]}


@pytest.fixture
def cortex_servers() -> Iterator[tuple[ScriptedOllamaServer, RoboMLTestServer]]:
    with ScriptedOllamaServer(**_cortex_agent_script(), models=OLLAMA_MODELS, reply=DESCRIPTION) as ollama, \
            RoboMLTestServer() as roboml:
        yield ollama, roboml


def _ports(ollama: ScriptedOllamaServer, roboml: RoboMLTestServer) -> dict[str, int]:
    return {"UPSTREAM_OLLAMA_PORT": ollama.port, "UPSTREAM_ROBOML_RESP_PORT": roboml.resp_port}


def _check_cortex_agent_plan(ollama: ScriptedOllamaServer, status: GoalStatus, result: dict[str, Any],
                             feedback: list[str]) -> None:
    assert status == GoalStatus.SUCCEEDED, (result, feedback)
    assert result["success"] and result["steps"] == 4, result
    assert result["message"].startswith("I am tracking the object"), result
    assert any("plan: vision.track, vlm.describe, tts.say, toggle_led" in f for f in feedback), feedback
    tools = {t["function"]["name"] for t in ollama.planning_requests[0]["tools"]}
    assert {"vision.track", "vision.take_picture", "vlm.describe", "tts.say", "toggle_led"} <= tools, tools
    led = next(t for t in ollama.planning_requests[0]["tools"] if t["function"]["name"] == "toggle_led")
    assert led["function"]["description"] == "Toggle the robot's LED on or off."  # the recipe's, not the docstring
    # Each step's outcome went back to the planner: the VLM's description among them.
    assert DESCRIPTION in str(ollama.planning_requests[-1]["messages"])
    # The VLM was asked with the camera's image (a chat request without tools, with images).
    vlm_asks = [r.json for r in ollama.requests_to("/api/chat") if not r.json.get("tools")]
    assert any(m.get("images") for r in vlm_asks for m in r["messages"]), "the VLM saw no image"


def test_cortex_agent_in_one_process(cortex_servers: tuple[ScriptedOllamaServer, RoboMLTestServer],
                                     speaker: list[tuple[int, int]], monkeypatch: pytest.MonkeyPatch,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    ollama, roboml = cortex_servers
    with launched_here(CORTEX_AGENT, _ports(ollama, roboml), monkeypatch, timeout=120) as launcher:
        t = launcher.transport
        trackings = _collect(t, "trackings", "Trackings")
        answers = _collect(t, "cortex_output", "StreamingString")
        detections = _collect(t, "detections", "Detections")
        with Camera(t):
            assert wait_for(lambda: bool(detections), timeout=30), "the detector never ran"
            status, result, feedback = _send_task(t, "track the object and tell me what you see")
            _check_cortex_agent_plan(ollama, status, result, feedback)
            # Vision follows the label it was told to: trackings of "object" keep coming.
            assert wait_for(lambda: any("object" in list(m.labels) for m in trackings[-3:]), timeout=20), trackings
            assert wait_for(lambda: len(speaker) >= 1, timeout=30), "nothing was spoken"
        vision = next(c for c in launcher.components if c.component_name == "vision")
        assert vision.config.labels_to_track == ["object"]
        assert answers and "tracking the object" in str(answers[-1])
    # The recipe's own function ran, once.
    assert capsys.readouterr().out.count("LED toggled ON") == 1


# -- memory_with_cortex.py ------------------------------------------------------------------------------

MEMORY_WITH_CORTEX = V074 / "memory_with_cortex.py"
BATTERY = 42.0


def _answer_with_tool_result(prefix: str) -> Any:
    """A planner answer that reports the last tool result it was given (as a model summarising it would)."""
    def answer(body: dict[str, Any]) -> dict[str, Any]:
        results = [m.get("content", "") for m in body["messages"] if m.get("role") == "tool"]
        return text(prefix + (results[-1] if results else "nothing"))
    return answer


def _memory_script() -> dict[str, Any]:
    """A body query and a perception query (answered while planning), then an action task in an episode."""
    return {"plan": [calls(("memory.body_status", {})), _answer_with_tool_result("Body: "),
                     calls(("memory.locate", {"concept": "person"})), _answer_with_tool_result("Seen: "),
                     calls(("memory.start_episode", {"name": "describe the room"}),
                           ("captioner.describe", {}),
                           ("memory.store_specific_memory", {"content": "<output from step 2>"}),
                           ("memory.end_episode", {})),
                     text("I described the room and remembered it.")],
            "confirm": [text("EXECUTE"), text("EXECUTE"),
                        calls(("memory.store_specific_memory", {"content": "the room has an astronaut"}),
                              answer="EXECUTE"),
                        text("EXECUTE")]}


def _robot(transport: Any) -> Camera:
    """The camera, odometry at (1, 2) and the battery level."""
    odom = OdometryMsg(pose=PoseMsg(position=[1.0, 2.0, 0.0]), header=Header(frame_id="map"))
    return Camera(transport, [(Topic(name="/odom", msg_type="Odometry"), odom),
                              (Topic(name="/battery_level", msg_type="Float32"), BATTERY)])


@pytest.fixture
def memory_env(tmp_path: Path) -> Iterator[tuple[ScriptedOllamaServer, dict[str, Any]]]:
    from ..components.vision_recipe import SSD_MODEL, needs_ssd  # noqa: PLC0415

    needs_ssd()
    with ScriptedOllamaServer(**_memory_script(), models=OLLAMA_MODELS,
                              reply="An office with an astronaut in it.") as ollama:
        yield ollama, {"UPSTREAM_OLLAMA_PORT": ollama.port, "AGENTS_VISION_MODEL": str(SSD_MODEL),
                       "UPSTREAM_MEMORY_DB": str(tmp_path / "memory.db")}


def _check_memory_tasks(transport: Any, ollama: ScriptedOllamaServer) -> dict[str, Any]:
    """Send the three tasks; returns their results by name."""
    results: dict[str, Any] = {}
    for name, task in (("body", "What is your current battery level?"),
                       ("seen", "Where did you last see a person?"),
                       ("act", "Describe the room and remember what you see.")):
        status, result, feedback = _send_task(transport, task)
        assert status == GoalStatus.SUCCEEDED, (name, result, feedback)
        results[name] = (result, feedback)
    body, seen, act = (results[k][0] for k in ("body", "seen", "act"))
    # Memory's tools answered while planning, with what the robot really reported.
    assert body["steps"] == 0 and body["message"].startswith("Body: ") and "42" in body["message"], body
    assert seen["steps"] == 0 and seen["message"].startswith("Seen: ") and "1.0" in seen["message"], seen
    tools = {t["function"]["name"] for t in ollama.planning_requests[0]["tools"]}
    assert {"memory.body_status", "memory.locate", "memory.semantic_search", "memory.start_episode",
            "captioner.describe", "vision.take_picture", "tts.say"} <= tools, tools
    # The action task ran its four steps; the note holds the confirmed description, inside the episode.
    assert act["steps"] == 4, act
    assert any("plan: memory.start_episode, captioner.describe, memory.store_specific_memory, memory.end_episode"
               in f for f in results["act"][1]), results["act"][1]
    return results


def test_memory_with_cortex_in_one_process(memory_env: tuple[ScriptedOllamaServer, dict[str, Any]],
                                           speaker: list[tuple[int, int]],
                                           monkeypatch: pytest.MonkeyPatch) -> None:
    ollama, ports = memory_env
    with launched_here(MEMORY_WITH_CORTEX, ports, monkeypatch, timeout=120) as launcher:
        t = launcher.transport
        memory = next(c for c in launcher.components if c.component_name == "memory")
        with _robot(t):
            assert wait_for(lambda: memory.stats.get("stored", 0) >= 3, timeout=60), memory.stats
            _check_memory_tasks(t, ollama)
            # The note went into the memory and is found again by meaning.
            assert "the room has an astronaut" in memory.semantic_search(query="the room has an astronaut")
            assert "describe the room" in memory.episode_summary(task_name="describe the room")
            # Cortex's answers were spoken (its output is the TTS input).
            assert wait_for(lambda: len(speaker) >= 3, timeout=60), speaker


@pytest.mark.zenoh
@pytest.mark.slow
def test_cortex_agent_in_processes_on_zenoh(cortex_servers: tuple[ScriptedOllamaServer, RoboMLTestServer],
                                            tmp_path: Path) -> None:
    """One process per component: Cortex dispatches to the others through their ``execute_method`` services."""
    ollama, roboml = cortex_servers
    with launched_in_processes(CORTEX_AGENT, _ports(ollama, roboml), tmp_path,
                               env={"PYTHONPATH": str(SOUND_STANDIN)}) as (proc, asker):
        trackings = _collect(asker, "trackings", "Trackings")
        detections = _collect(asker, "detections", "Detections")
        answers = _collect(asker, "cortex_output", "StreamingString")
        with Camera(asker):
            assert wait_for(lambda: bool(detections) or proc.proc.poll() is not None, timeout=60), proc.output()
            assert wait_for(lambda: _subscribers(asker, "image_raw") >= 2, timeout=60), proc.output()  # the VLM too
            time.sleep(1.0)
            status, result, feedback = _send_task(asker, "track the object and tell me what you see", timeout=120)
            _check_cortex_agent_plan(ollama, status, result, feedback)
            assert wait_for(lambda: any("object" in list(m.labels) for m in trackings[-3:]), timeout=30)
        assert wait_for(lambda: bool(answers), timeout=10)
        # The recipe's function ran in Cortex's process, once.
        assert wait_for(lambda: proc.output().count("LED toggled ON") == 1, timeout=10), proc.output()


@contextlib.contextmanager
def launched_on_ros2(recipe: Path, ports: Mapping[str, int], tmp_path: Path,
                     env: Mapping[str, str]) -> Iterator[tuple[RecipeProcess, Transport]]:
    """Run ``python recipe`` (as the harness does, its ``multiprocessing`` as written) on ROS 2; yield it and an asker.

    The domain is the session's ``ROS_DOMAIN_ID`` (else one of this process's own), discovery on this host.
    """
    reason = missing_requirement("ros2")
    if reason is not None:
        pytest.skip(reason)
    domain = os.environ.get("ROS_DOMAIN_ID") or str(private_ros_environment())
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    python_path = os.pathsep.join(p for p in (env.get("PYTHONPATH", ""), str(ROOT), os.environ.get("PYTHONPATH", ""))
                                  if p)
    child_env = recipe_environment(AGENTS_TRANSPORT="ros2", ROS_DOMAIN_ID=domain, PYTHONPATH=python_path,
                                   **{k: str(v) for k, v in ports.items()})
    process = RecipeProcess("tests.upstream_examples.harness", [str(recipe)], tmp_path / "recipe.log",
                            cwd=recipe.parent, env=child_env)
    asker = resolve_transport("ros2", domain_id=int(domain))
    try:
        process.wait_ready(180.0)
        yield process, asker
    except BaseException:
        asker.close()
        process.stop()
        raise AssertionError(f"recipe {recipe.name} on ros2:\n{process.output()}") from None
    asker.close()
    process.stop()


@pytest.mark.ros2
@pytest.mark.slow
def test_cortex_agent_on_ros2(cortex_servers: tuple[ScriptedOllamaServer, RoboMLTestServer], tmp_path: Path) -> None:
    """As upstream runs it: on ROS 2, one process per component (the recipe's own ``multiprocessing=True``)."""
    ollama, roboml = cortex_servers
    with launched_on_ros2(CORTEX_AGENT, _ports(ollama, roboml), tmp_path,
                          env={"PYTHONPATH": str(SOUND_STANDIN)}) as (proc, asker):
        trackings = _collect(asker, "trackings", "Trackings")
        detections = _collect(asker, "detections", "Detections")
        with Camera(asker):
            assert wait_for(lambda: bool(detections) or proc.proc.poll() is not None, timeout=60), proc.output()
            # Detections say the Vision process has images; the VLM process subscribes on its own, and a
            # forked process can be active before DDS has matched it with the camera: wait for its match.
            assert wait_for(lambda: _subscribers(asker, "image_raw") >= 2, timeout=60), proc.output()
            time.sleep(1.0)  # a few camera frames (5 Hz) for the newly matched subscriber
            status, result, feedback = _send_task(asker, "track the object and tell me what you see", timeout=120)
            _check_cortex_agent_plan(ollama, status, result, feedback)
            assert wait_for(lambda: any("object" in list(m.labels) for m in trackings[-3:]), timeout=30)
        assert wait_for(lambda: proc.output().count("LED toggled ON") == 1, timeout=10), proc.output()


def _subscribers(transport: Any, topic: str) -> int:
    """How many subscribers ``transport`` sees on ``topic`` (0 while discovery has not found it)."""
    return sum(t.subscribers for t in transport.discover(timeout=1.0).topics if t.name == topic)


@pytest.mark.zenoh
@pytest.mark.slow
def test_memory_with_cortex_in_processes_on_zenoh(memory_env: tuple[ScriptedOllamaServer, dict[str, Any]],
                                                  tmp_path: Path) -> None:
    """Memory's tools, found and called by Cortex in another process (planning research and plan steps)."""
    ollama, ports = memory_env
    with launched_in_processes(MEMORY_WITH_CORTEX, ports, tmp_path,
                               env={"PYTHONPATH": str(SOUND_STANDIN)}) as (proc, asker):
        stored = _collect(asker, "scene_description", "String")
        with _robot(asker):
            assert wait_for(lambda: len(stored) >= 3 or proc.proc.poll() is not None, timeout=60), proc.output()
            # Memory keeps what it is given once it has a position: wait until the battery is remembered.
            assert wait_for(lambda: "42" in _body_status(asker), timeout=60), proc.output()
            _check_memory_tasks(asker, ollama)


def _body_status(transport: Any) -> str:
    """Memory's ``body_status`` through its ``execute_method`` service, as Cortex calls it."""
    try:
        reply = transport.request("memory/execute_method", {"method": "body_status", "args": [], "kwargs": {}},
                                  timeout=5.0)
        return str(reply.get("result"))
    except Exception as exc:  # not up yet: asked again
        return f"error: {exc}"


# -- the API the recipes needed ---------------------------------------------------------------------------


def test_text_on_the_ui_task_topic_becomes_a_task(monkeypatch: pytest.MonkeyPatch,
                                                  speaker: list[tuple[int, int]]) -> None:
    """``cortex.ui_main_action_input``: what the UI's text box publishes runs as a task (answer on the output)."""
    with ScriptedOllamaServer(plan=[lambda body: text("Asked: " + body["messages"][-1]["content"][-40:])],
                              models=OLLAMA_MODELS) as ollama, RoboMLTestServer() as roboml, \
            launched_here(CORTEX_AGENT, _ports(ollama, roboml), monkeypatch, timeout=120) as launcher:
        cortex = next(c for c in launcher.components if c.component_name == "cortex")
        assert cortex.ui_main_action_input.name == "cortex/task"
        answers = _collect(launcher.transport, "cortex_output", "StreamingString")
        pub = launcher.transport.create_publisher(cortex.ui_main_action_input)
        pub.publish("   ")  # blank: no task
        pub.publish("who are you " + "x" * 10_000)
        assert wait_for(lambda: bool(answers), timeout=30)
        assert cortex.tasks["succeeded"] == 1
    # One planning request, with the task cut to its bound.
    assert len(ollama.planning_requests) == 1
    asked = ollama.planning_requests[0]["messages"][-1]["content"]
    assert "who are you" in asked and "x" * 4000 not in asked[asked.index("who are you") + 4000:]
    assert str(answers[0].data).startswith("Asked: ")


def _module_function() -> None:
    """A plan step that does nothing."""


class _Robot:
    def beep(self) -> None:
        """Beep."""


def test_cortex_actions_cross_to_a_process_only_as_functions() -> None:
    from agents_core.components.cortex.transfer import ACTION_CODEC  # noqa: PLC0415  (registers it)
    from agents_core.errors import ConfigError  # noqa: PLC0415
    from agents_core.launch.spec import decode_value, encode_value  # noqa: PLC0415
    from agents_core.ros import Action  # noqa: PLC0415

    action = Action(method=_module_function, kwargs={"n": 2}, description="Do nothing, twice.")
    back = decode_value(encode_value(action))
    assert back.method is _module_function and back.kwargs == {"n": 2} and back.description == "Do nothing, twice."
    with pytest.raises(ConfigError, match="bound to a _Robot"):
        encode_value(Action(method=_Robot().beep))
    assert ACTION_CODEC.name == "action"
