"""The episode recorder on the memory transport: explicit and event episodes, the pre-buffer, caps, actions, hooks."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from agents_core import Launcher, Topic
from agents_core.errors import ConfigError, RemoteError
from agents_core.messages import ImageMsg, JointStateMsg
from agents_core.transport import MemoryTransport

from ..conftest import wait_for

pytest.importorskip("mcap", reason="pip install 'agents-core[record]'")

from agents_core.episodes import (
    EpisodeError,
    EpisodeInfo,
    EpisodeLimits,
    EpisodeRecorder,
    EpisodeRecordingHooks,
    PreBuffer,
    load_episodes,
    value_bytes,
)
from agents_core.episodes.buffer import BufferedValue
from agents_core.recording import read_recording

JOINTS = Topic("joints", "JointState")
CAMERA = Topic("camera", "Image")
COMMAND = Topic("command", "Float64MultiArray")


def _publishers(transport: MemoryTransport) -> dict[str, Any]:
    return {t.name: transport.create_publisher(t) for t in (JOINTS, CAMERA, COMMAND)}


def _step(pubs: dict[str, Any], i: int, side: int = 8) -> None:
    pubs["joints"].publish(JointStateMsg(name=["a", "b"], position=[float(i), -float(i)]))
    pubs["camera"].publish(ImageMsg.from_array(np.full((side, side, 3), i % 256, np.uint8)))
    pubs["command"].publish(np.array([i * 0.5, 1.0]))


def _values(path: Path, topic: str) -> list[Any]:
    return [m.value for m in read_recording(path, topics={topic})]


def test_value_bytes_counts_arrays_of_nested_messages() -> None:
    image = ImageMsg.from_array(np.zeros((100, 50, 3), np.uint8))
    assert 15_000 <= value_bytes(image) < 15_000 + 2048
    joints = JointStateMsg(name=["a"] * 1000, position=np.zeros(1000), velocity=np.zeros(1000))
    assert value_bytes(joints) >= 16_000 + 1000
    assert value_bytes(np.zeros(1000)) == 8000


def test_the_pre_buffer_keeps_its_bytes_and_seconds(memory: MemoryTransport) -> None:
    ring = PreBuffer(max_bytes=10_000, max_s=1.0)
    item = BufferedValue("t", CAMERA.msg_type, None, None, 0, 0, 3000)  # type: ignore[arg-type]
    for k in range(10):
        ring.append(item.__class__("t", CAMERA.msg_type, None, k, k * 10**6, 0, 3000))  # type: ignore[arg-type]
    assert ring.bytes <= 10_000 and len(ring) == 3 and ring.evicted_for_bytes == 7
    ring.append(item.__class__("t", CAMERA.msg_type, None, "late", 5 * 10**9, 0, 10))  # type: ignore[arg-type]
    assert [i.value for i in ring] == ["late"]  # everything older than a second went
    ring.append(item.__class__("t", CAMERA.msg_type, None, "huge", 5 * 10**9, 0, 20_000))  # type: ignore[arg-type]
    assert ring.too_large == 1 and [i.value for i in ring] == ["late"]


def test_explicit_episodes_hold_what_was_published_between_start_and_stop(memory: MemoryTransport,
                                                                          tmp_path: Path) -> None:
    pubs = _publishers(memory)
    with EpisodeRecorder(tmp_path).attach(memory, [JOINTS, CAMERA, COMMAND]) as recorder:
        _step(pubs, 100)  # before the episode: not in it
        started = recorder.start_episode("pick the cube", extra={"seed": 7})
        for i in range(5):
            _step(pubs, i)
        info = recorder.stop_episode(success=True, extra={"steps": 5})
        _step(pubs, 200)
        with pytest.raises(EpisodeError, match="no episode is recording"):
            recorder.stop_episode()
        second = recorder.start_episode("again")
        with pytest.raises(EpisodeError, match="episode 1 is still recording"):
            recorder.start_episode()
        _step(pubs, 9)
        recorder.stop_episode(success=False)
    assert started.episode == 0 and second.episode == 1
    assert info.ended == "stopped" and info.success is True and info.messages == 15 and info.dropped == 0
    assert info.topics == {"joints": {"type": "JointState", "messages": 5}, "camera": {"type": "Image", "messages": 5},
                           "command": {"type": "Float64MultiArray", "messages": 5}}
    assert [v.position[0] for v in _values(info.mcap, "joints")] == [0, 1, 2, 3, 4]
    assert [int(v.data[0, 0, 0]) for v in _values(info.mcap, "camera")] == [0, 1, 2, 3, 4]
    assert [float(v[0]) for v in _values(info.mcap, "command")] == [0, 0.5, 1.0, 1.5, 2.0]
    doc = json.loads(info.sidecar.read_text())
    assert doc["format"] == "agents_core.episode/1" and doc["mcap"] == "episode_000000.mcap"
    assert doc["task"] == "pick the cube" and doc["extra"] == {"seed": 7, "steps": 5}
    loaded = load_episodes(tmp_path)
    assert [e.episode for e in loaded] == [0, 1] and loaded[1].success is False and loaded[1].messages == 3
    assert loaded[0].to_json() == info.to_json()


def test_numbering_continues_after_the_episodes_a_folder_holds(memory: MemoryTransport, tmp_path: Path) -> None:
    for _ in range(2):
        with EpisodeRecorder(tmp_path).attach(memory, [JOINTS]) as recorder:
            recorder.start_episode()
            recorder.stop_episode()
    assert [e.episode for e in load_episodes(tmp_path)] == [0, 1]


def test_record_episode_keeps_the_seconds_before_and_after_the_event(memory: MemoryTransport, tmp_path: Path) -> None:
    pubs = _publishers(memory)
    limits = EpisodeLimits(buffer_s=0.5)
    with EpisodeRecorder(tmp_path, limits=limits).attach(memory, [JOINTS]) as recorder:
        for i in range(10):  # 0.1 s apart: only the last ~5 stay in a 0.5 s pre-buffer
            _step(pubs, i)
            time.sleep(0.1)
        event = recorder.record_episode(before_s=0.35, after_s=0.4)
        assert event.trigger == "event" and recorder.recording is not None
        for i in range(10, 14):
            _step(pubs, i)
            time.sleep(0.05)
        extended = recorder.record_episode(before_s=0.35, after_s=0.4)  # a second event extends it
        assert extended.episode == event.episode
        time.sleep(0.2)
        _step(pubs, 14)  # within the extended window
        assert wait_for(lambda: recorder.recording is None, timeout=3)
        time.sleep(0.1)
        _step(pubs, 99)  # after it
        assert wait_for(lambda: len(recorder.episodes) == 1, timeout=3)
    info = recorder.episodes[0]
    kept = [int(v.position[0]) for v in _values(info.mcap, "joints")]
    assert kept[-5:] == [10, 11, 12, 13, 14], kept
    assert 2 <= len(kept) - 5 <= 4 and kept[:-5] == list(range(10 - (len(kept) - 5), 10)), kept
    assert info.ended == "after_s" and 0.9 < info.duration_s < 1.5, info


def test_before_s_past_the_buffer_is_refused(tmp_path: Path) -> None:
    with EpisodeRecorder(tmp_path, limits=EpisodeLimits(buffer_s=2)) as recorder, \
            pytest.raises(ConfigError, match=r"before_s=5 s is more than the pre-buffer holds \(buffer_s=2 s\)"):
        recorder.record_episode(before_s=5, after_s=1)


def test_an_episode_over_its_size_cap_is_cut_with_the_reason(memory: MemoryTransport, tmp_path: Path) -> None:
    pubs = _publishers(memory)
    limits = EpisodeLimits(max_episode_bytes=100_000)
    with EpisodeRecorder(tmp_path, limits=limits).attach(memory, [CAMERA]) as recorder:
        recorder.start_episode()
        for i in range(40):  # 40 x 30 kB frames: the cap holds three
            _step(pubs, i, side=100)
        assert wait_for(lambda: recorder.recording is None, timeout=5)
        with pytest.raises(EpisodeError):
            recorder.stop_episode()
        assert wait_for(lambda: len(recorder.episodes) == 1, timeout=5)
    info = recorder.episodes[0]
    assert info.ended == "size_cap" and info.messages == 3 and info.bytes <= 100_000
    assert info.reason is not None and "max_episode_bytes=100000" in info.reason and "'camera'" in info.reason
    assert len(_values(info.mcap, "camera")) == 3
    assert json.loads(info.sidecar.read_text())["ended"] == "size_cap"


def test_an_episode_over_its_duration_cap_is_cut(memory: MemoryTransport, tmp_path: Path) -> None:
    pubs = _publishers(memory)
    with EpisodeRecorder(tmp_path, limits=EpisodeLimits(max_episode_s=0.3)).attach(memory, [JOINTS]) as recorder:
        recorder.start_episode()
        for i in range(8):
            _step(pubs, i)
            time.sleep(0.1)
        assert recorder.recording is None
    info = load_episodes(tmp_path)[0]
    assert info.ended == "duration_cap" and "max_episode_s=0.3" in str(info.reason) and 2 <= info.messages <= 4


def test_a_full_queue_drops_and_counts(memory: MemoryTransport, tmp_path: Path) -> None:
    recorder = EpisodeRecorder(tmp_path, limits=EpisodeLimits(queue_bytes=50_000))
    recorder.start_episode()
    writer_wait = recorder._cond  # hold the writer's lock: nothing is written while values arrive
    with writer_wait:
        for i in range(20):
            recorder.offer("camera", CAMERA.msg_type, ImageMsg.from_array(np.full((60, 60, 3), i, np.uint8)))
    info = recorder.stop_episode()
    recorder.close()
    assert info.dropped > 0 and info.messages + info.dropped == 20 and info.messages <= 5


def test_the_component_s_actions_drive_it_through_execute_method(tmp_path: Path) -> None:
    from agents_core.episodes import EpisodeRecorderComponent, EpisodeRecorderConfig  # noqa: PLC0415

    with pytest.raises(ConfigError, match="give the topics to record as inputs"):
        EpisodeRecorderComponent(inputs=[])
    with pytest.raises(ConfigError, match=r"max_episode_mb: expected a number > 0 or None, got -1"):
        EpisodeRecorderConfig(max_episode_mb=-1)
    component = EpisodeRecorderComponent(inputs=[JOINTS, COMMAND], component_name="episodes",
                                         config=EpisodeRecorderConfig(directory=str(tmp_path), buffer_s=2.0))
    launcher = Launcher("memory")
    launcher.add_pkg(components=[component])
    with launcher:
        transport = launcher.transport
        pubs = _publishers(transport)

        def call(method: str, **kwargs: Any) -> Any:
            return transport.request("episodes/execute_method", {"method": method, "kwargs": kwargs,
                                                                 "timeout": 10.0})["result"]

        _step(pubs, 0)
        started = call("start_episode", task="wave")
        assert started["episode"] == 0 and started["ended"] is None
        for i in range(1, 4):
            _step(pubs, i)
        stopped = call("stop_episode", success=True)
        assert stopped["ended"] == "stopped" and stopped["messages"] == 6 and stopped["success"] is True
        with pytest.raises(RemoteError, match="no episode is recording"):
            call("stop_episode")
        event = call("record_episode", before_s=1.0, after_s=0.2, task="event")
        assert event["episode"] == 1 and event["trigger"] == "event"
        assert wait_for(lambda: len(load_episodes(tmp_path)) == 2, timeout=5)
    first, second = load_episodes(tmp_path)
    assert first.task == "wave" and [int(v.position[0]) for v in _values(first.mcap, "joints")] == [1, 2, 3]
    assert second.messages == 8  # the pre-buffer: all four steps of both topics, within the last second


def test_hooks_record_one_episode_per_evaluated_episode(memory: MemoryTransport, tmp_path: Path) -> None:
    pubs = _publishers(memory)
    hooks = EpisodeRecordingHooks.attached(memory, [JOINTS, COMMAND], tmp_path, task="reach")
    for episode, seed in enumerate((11, 12)):
        hooks.on_episode_start(episode, seed)
        for i in range(3):
            _step(pubs, i)
        hooks.on_episode_end({"episode": episode, "seed": seed, "success": episode == 1, "reward_sum": 1.5,
                              "steps": 3, "ended": "terminated", "rewards": [0.5] * 3, "frames": []})
    hooks.on_episode_start(2, 13)
    hooks.on_episode_start(3, 14)  # the runner lost an end: the previous episode is stopped, not left open
    hooks.close()
    infos = load_episodes(tmp_path)
    assert [(e.success, e.extra.get("seed"), e.task) for e in infos] == [
        (False, 11, "reach"), (True, 12, "reach"), (None, 13, "reach"), (None, 14, "reach")]
    assert infos[0].extra["result"]["reward_sum"] == 1.5 and "rewards" not in infos[0].extra["result"]
    assert infos[3].ended == "closed"
    assert [e["episode"] for e in hooks.recorded] == [0, 1, 2]


def test_a_bad_sidecar_is_named(tmp_path: Path) -> None:
    (tmp_path / "episode_000000.json").write_text('{"format": "something else"}')
    with pytest.raises(ConfigError, match=r"episode_000000.json: not an episode sidecar"):
        load_episodes(tmp_path)
    (tmp_path / "episode_000000.json").write_text('{"format": "agents_core.episode/1", "episode": 0, '
                                                  '"mcap": "../../etc/passwd", "bogus": 1}')
    with pytest.raises(ConfigError, match="unknown field 'bogus'"):
        EpisodeInfo.from_json(tmp_path / "episode_000000.json")
    (tmp_path / "episode_000000.json").write_text('{"format": "agents_core.episode/1", "episode": "0", '
                                                  '"mcap": "episode_000000.mcap"}')
    with pytest.raises(ConfigError, match="field 'episode' is a str"):
        load_episodes(tmp_path)
    (tmp_path / "episode_000000.json").write_text('{"format": "agents_core.episode/1", "episode": 0, '
                                                  '"mcap": "../x.mcap", "topics": {"t": {"type": 1}}}')
    with pytest.raises(ConfigError, match="topic 't': expected"):
        load_episodes(tmp_path)


def test_hooks_drive_a_recorder_component_of_the_recipe(tmp_path: Path) -> None:
    from agents_core.episodes import EpisodeRecorderComponent, EpisodeRecorderConfig  # noqa: PLC0415

    component = EpisodeRecorderComponent(inputs=[JOINTS], component_name="rec",
                                         config=EpisodeRecorderConfig(directory=str(tmp_path)))
    hooks = EpisodeRecordingHooks.for_component(component, task="t")
    with pytest.raises(ConfigError, match="a component name needs the transport"):
        EpisodeRecordingHooks.for_component("rec")
    with pytest.raises(ConfigError, match="'rec' is not active here"):
        hooks.on_episode_start(0, 1)
    launcher = Launcher("memory")
    launcher.add_pkg(components=[component])
    with launcher:
        pubs = _publishers(launcher.transport)
        hooks.on_episode_start(0, 5)
        _step(pubs, 1)
        hooks.on_episode_end({"episode": 0, "seed": 5, "success": True})
    (info,) = load_episodes(tmp_path)
    assert info.success is True and info.extra["seed"] == 5 and info.messages == 1


def test_an_episode_with_nothing_in_it_is_an_empty_file(tmp_path: Path) -> None:
    with EpisodeRecorder(tmp_path) as recorder:
        recorder.start_episode()
        info = recorder.stop_episode()
    assert info.messages == 0 and info.mcap.is_file() and list(read_recording(info.mcap)) == []
