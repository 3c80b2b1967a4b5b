"""``launcher.record(path, ...)``: a recording started with the recipe and finished (summary written) when it stops.

The recipe is the benchmarks' relay on the memory transport (no discovery there: the recording
takes the components' own topics). The file is read back with the ``mcap`` package's reader.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from agents_core import Launcher, Topic
from agents_core.errors import ConfigError
from benchmarks.common import TOPICS
from benchmarks.parts import EchoRelay

from ..conftest import wait_for

mcap_reader = pytest.importorskip("mcap.reader", reason="pip install 'agents-core[record]'")

STR_IN, STR_OUT = TOPICS["string64"]


def _summary_counts(path: Path) -> dict[str, int]:
    with open(path, "rb") as f:
        summary = mcap_reader.make_reader(f).get_summary()
    assert summary is not None and summary.statistics is not None  # a finished file, not a cut one
    return {c.topic: summary.statistics.channel_message_counts.get(c.id, 0) for c in summary.channels.values()}


def test_the_recording_follows_the_launcher(tmp_path: Path) -> None:
    out = tmp_path / "relay.mcap"
    launcher = Launcher("memory", quiet=True)
    launcher.add_pkg(components=[EchoRelay()])
    recording = launcher.record(out, encoding="msgpack", flush_interval_s=0.2)
    assert recording.statistics() is None  # nothing runs before the recipe starts
    got: list[str] = []
    with launcher:
        transport = launcher.transport
        sub = transport.create_subscription(Topic(STR_OUT, "String"), got.append)
        pub = transport.create_publisher(Topic(STR_IN, "String"))
        for i in range(20):
            pub.publish(f"hello {i}")
            assert wait_for(lambda n=i: len(got) > n, timeout=5)
        live = recording.statistics()
        assert live is not None and {STR_IN, STR_OUT, "relay/status"} <= set(live.topics)
        sub.close()
        pub.close()
    final = recording.statistics()
    assert final is not None and final.dropped == 0 and final.errors == 0 and final.queued == 0, final
    counts = _summary_counts(out)
    assert counts[f"/{STR_IN}"] == 20 and counts[f"/{STR_OUT}"] == 20
    assert counts.get("/relay/status", 0) >= 1
    assert final.files == [out]


def test_chosen_topics_and_limits(tmp_path: Path) -> None:
    from agents_core.recording import RecordingLimits  # noqa: PLC0415

    out = tmp_path / "split.mcap"
    launcher = Launcher("memory", quiet=True)
    launcher.add_pkg(components=[EchoRelay()])
    recording = launcher.record(out, topics=[Topic(STR_OUT, "String")], encoding="msgpack",
                                limits=RecordingLimits(max_file_bytes=2000))
    got: list[str] = []
    with launcher:
        sub = launcher.transport.create_subscription(Topic(STR_OUT, "String"), got.append)
        pub = launcher.transport.create_publisher(Topic(STR_IN, "String"))
        for i in range(40):
            pub.publish("x" * 100 + str(i))
            assert wait_for(lambda n=i: len(got) > n, timeout=5)
        sub.close()
        pub.close()
    final = recording.statistics()
    # The named topic, and no other (the status topic comes with include_status, the default).
    assert final is not None and set(final.topics) - {"relay/status"} == {STR_OUT}, final
    assert final.over_limit == 0 and final.written >= 40
    assert len(final.files) > 1  # split by size
    assert sum(_summary_counts(p).get(f"/{STR_OUT}", 0) for p in final.files) == 40


def test_a_wrong_option_is_refused_where_it_is_written(tmp_path: Path) -> None:
    launcher = Launcher("memory", quiet=True)
    with pytest.raises(ConfigError, match="unknown option"):
        launcher.record(tmp_path / "x.mcap", queue=3)
