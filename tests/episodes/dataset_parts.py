"""Recorded episodes with known contents, for the export tests (with and without LeRobot installed).

:func:`record_episodes` publishes, on the memory transport, ``steps`` world steps per episode — a
JointState, a camera frame a moment later, then the agent's Float64 array command — into an
:class:`~agents_core.episodes.EpisodeRecorder`, one explicit episode each, and returns what each
frame of the export must hold.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from attrs import define, field

from agents_core import Topic
from agents_core.episodes import EpisodeRecorder
from agents_core.messages import ImageMsg, JointStateMsg
from agents_core.transport import MemoryTransport

JOINTS = Topic("joints", "JointState")
CAMERA = Topic("top", "Image")
COMMAND = Topic("command", "Float64MultiArray")
FEATURES = {"observation.state": "joints", "observation.images.top": "top", "action": "command"}
JOINT_NAMES = ["shoulder", "elbow", "wrist"]
HEIGHT, WIDTH = 48, 64
FPS = 20


def frame_pixels(episode: int, step: int) -> np.ndarray:
    """The camera frame of ``step`` in ``episode``: smooth (a video codec keeps it within a few levels)."""
    pixels = np.empty((HEIGHT, WIDTH, 3), np.uint8)
    pixels[:, :, 0] = (10 + 9 * step) % 250
    pixels[:, :, 1] = 30 + 40 * episode
    pixels[:, :, 2] = np.linspace(20, 220, WIDTH, dtype=np.uint8)[None, :]
    return pixels


def state(episode: int, step: int) -> np.ndarray:
    return np.array([0.1 * step, -0.05 * step + episode, np.sin(step / 3.0)], np.float64)


def action(episode: int, step: int) -> np.ndarray:
    return np.array([0.1 * step + 0.05, episode * 1.5, -0.01 * step, 0.25], np.float64)


@define
class Recorded:
    """The episodes' folder and what their frames hold, per episode."""

    directory: Path
    tasks: list[str]
    steps: list[int]
    states: list[list[np.ndarray]] = field(factory=list)
    actions: list[list[np.ndarray]] = field(factory=list)
    images: list[list[np.ndarray]] = field(factory=list)


def record_episodes(directory: Path, episodes: int = 5, steps: int = 12, step_s: float = 0.02) -> Recorded:
    """Record ``episodes`` episodes of ``steps`` (``steps + episode`` for episode > 0: lengths differ)."""
    transport = MemoryTransport()
    tasks = [("reach the target" if e % 2 == 0 else "wave") for e in range(episodes)]
    recorded = Recorded(directory, tasks, [steps + e for e in range(episodes)])
    try:
        pubs = {t.name: transport.create_publisher(t) for t in (JOINTS, CAMERA, COMMAND)}
        recorder = EpisodeRecorder(directory).attach(transport, [JOINTS, CAMERA, COMMAND])
        with recorder:
            pubs["top"].publish(ImageMsg.from_array(frame_pixels(0, 0)))  # warm up (imports), outside any episode
            for e in range(episodes):
                recorded.states.append([])
                recorded.actions.append([])
                recorded.images.append([])
                recorder.start_episode(tasks[e], extra={"seed": 100 + e})
                for s in range(recorded.steps[e]):
                    pubs["joints"].publish(JointStateMsg(name=JOINT_NAMES, position=state(e, s)))
                    pubs["top"].publish(ImageMsg.from_array(frame_pixels(e, s)))
                    time.sleep(step_s / 4)
                    pubs["command"].publish(action(e, s))
                    time.sleep(step_s)
                    recorded.states[e].append(state(e, s))
                    recorded.actions[e].append(action(e, s))
                    recorded.images[e].append(frame_pixels(e, s))
                recorder.stop_episode(success=e % 2 == 0)
    finally:
        transport.close()
    return recorded
