"""Record the voice loop running on Zenoh in another process, and read the file back with mcap and rosbags.

The recipe (tests/components/voice_recipe.py: Whisper tiny.en + Silero VAD -> SmolLM2 -> Piper,
the shared clips) runs in a child process. This process speaks a question into ``mic`` in 20 ms
chunks through one Zenoh session and records every topic and the components' status topics through
another. The file is then read with the ``mcap`` package's reader and with ``rosbags`` (neither
uses our code): the ROS types, the message counts, the stamps, and what was heard and said.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from agents_core.testing.helpers import free_tcp_port
from agents_core.testing.recipes import open_recipe_transport, run_recipe
from agents_core.transport.registry import resolve_transport

from ..components import voice_recipe
from ..components.models_dir import REPO
from ..components.voice_recipe import chunks, clip, needs_voice_loop, silence
from ..conftest import wait_for

pytestmark = [pytest.mark.local_models, pytest.mark.zenoh, pytest.mark.slow]

mcap_reader = pytest.importorskip("mcap.reader", reason="pip install 'agents-core[record]'")
pytest.importorskip("zenoh", reason="pip install 'agents-core[zenoh]'")

QUESTION = np.concatenate([silence(0.3), clip("pick_up_red_cube_16k.wav"), silence(1.0)])


def _record_the_voice_loop(tmp_path: Path) -> tuple[Path, int]:
    """Run the loop on Zenoh, speak until heard and answered, record it all; (file, mic chunks sent)."""
    from agents_core.recording import Recorder  # noqa: PLC0415

    transport = open_recipe_transport("zenoh")
    out = tmp_path / "voice.mcap"
    sent = 0
    with run_recipe("tests.components.voice_recipe", transport, tmp_path, cwd=REPO, ready_timeout=90):
        asker_endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
        asker = resolve_transport("zenoh", mode="peer", listen=[asker_endpoint], connect=[transport.endpoint],
                                  multicast_scouting=False)
        recording_side = resolve_transport("zenoh", mode="peer", listen=[],
                                           connect=[transport.endpoint, asker_endpoint], multicast_scouting=False)
        recorder = Recorder(recording_side, out, discover_every_s=0.3, flush_interval_s=0.2)
        recorder.start()
        try:
            heard: list[str] = []
            spoken: list[Any] = []
            subs = [asker.create_subscription(voice_recipe.HEARD, heard.append, inline=True),
                    asker.create_subscription(voice_recipe.SPOKEN, spoken.append, inline=True)]
            mic = asker.create_publisher(voice_recipe.MIC)
            wanted = {"mic", "heard", "answer", "spoken", "ears/status", "brain/status", "mouth/status"}
            assert wait_for(lambda: wanted <= set(recorder.statistics().topics), timeout=30), recorder.statistics()
            deadline = time.monotonic() + 60
            while not heard and time.monotonic() < deadline:
                for msg in chunks(QUESTION):
                    mic.publish(msg)
                    sent += 1
                wait_for(lambda: bool(heard), timeout=8)
            assert heard and "red cube" in heard[0].lower(), heard
            assert wait_for(lambda: sum(a.duration for a in spoken) > 0.5, timeout=60), "no spoken answer"
            time.sleep(2.0)  # the rest of the answer, and the recorder's own deliveries of it
            mic.close()
            for sub in subs:
                sub.close()
        finally:
            stats = recorder.stop()
            recording_side.close()
            asker.close()
    assert stats.dropped == 0 and stats.errors == 0 and stats.written > 0, stats
    return out, sent


def test_record_the_voice_loop_and_read_it_back(tmp_path: Path) -> None:
    needs_voice_loop()
    pytest.importorskip("rclpy", reason="CDR needs the ros2 extra")
    path, sent = _record_the_voice_loop(tmp_path)

    # -- the mcap package's reader: types, counts, stamps -----------------------------------------------
    with open(path, "rb") as f:
        reader = mcap_reader.make_reader(f)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        schemas = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
        assert schemas["/mic"] == schemas["/spoken"] == "agents_interfaces/msg/Audio"
        assert schemas["/heard"] == "std_msgs/msg/String"
        assert schemas["/answer"] == "agents_interfaces/msg/StreamingString"
        assert schemas["/ears/status"] == "agents_interfaces/msg/ComponentStatus"
        assert all(c.message_encoding == "cdr" for c in summary.channels.values())
        counts = {c.topic: summary.statistics.channel_message_counts[c.id] for c in summary.channels.values()}
        assert counts["/mic"] == sent  # every chunk spoken was recorded, none lost or doubled
        assert counts["/heard"] >= 1 and counts["/answer"] >= 2 and counts["/spoken"] >= 1
        times: dict[str, list[tuple[int, int]]] = {}
        for _, channel, message in reader.iter_messages(log_time_order=False):
            times.setdefault(channel.topic, []).append((message.log_time, message.publish_time))
    start, end = summary.statistics.message_start_time, summary.statistics.message_end_time
    assert all(abs(t / 1e9 - time.time()) < 600 for t in (start, end))
    # Each topic's values were received in order (the writer keeps the queue's order) within the recording.
    for topic, stamps in times.items():
        logs = [log for log, _ in stamps]
        assert logs == sorted(logs) and start <= logs[0] and logs[-1] <= end, topic
    # The answer comes after the question: its first chunk after the first mic chunk was received.
    assert times["/mic"][0][0] < times["/heard"][0][0] < times["/answer"][0][0] < times["/spoken"][0][0]

    # -- rosbags, from the schemas in the file: the words heard and the voice's audio ---------------------
    from rosbags.highlevel import AnyReader  # noqa: PLC0415

    heard: list[str] = []
    answer: list[str] = []
    spoken_samples = 0
    rates = set()
    with AnyReader([path]) as bag:
        for conn, _, raw in bag.messages(connections=[c for c in bag.connections
                                                      if c.topic in ("/heard", "/answer", "/spoken")]):
            msg = bag.deserialize(raw, conn.msgtype)
            if conn.topic == "/heard":
                heard.append(msg.data)
            elif conn.topic == "/answer":
                answer.append(msg.data)
            else:
                assert msg.format == "S16LE" and msg.channels == 1
                rates.add(msg.sample_rate)
                spoken_samples += len(msg.data) // 2
    assert "red cube" in heard[0].lower(), heard
    assert "".join(answer).strip(), answer
    assert rates == {22_050} and spoken_samples / 22_050 > 0.5
