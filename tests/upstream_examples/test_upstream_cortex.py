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

import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from agents_core.messages import Header, OdometryMsg, PoseMsg
from agents_core.ros import Topic
from agents_core.transport.goals import GoalStatus

from ..conftest import wait_for
from ..servers.roboml_server import RoboMLTestServer
from ..servers.scripted_ollama_server import ScriptedOllamaServer, calls, text
from .harness import RECIPES, launched_here
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
