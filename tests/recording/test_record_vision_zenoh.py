"""Record the Vision recipe running on Zenoh in another process, read the file with mcap and rosbags, replay it.

The recipe (tests/components/vision_recipe.py, the real COCO detector and the shared photos) runs
in a child process; this process asks it through one Zenoh session and records everything through
another (a :class:`~agents_core.recording.Recorder` discovering topics and the status topic). The
file is then read back with the ``mcap`` reader and with ``rosbags`` (neither uses our code), and
its inputs are replayed into the same recipe on the memory transport with
:func:`~agents_core.testing.replay.replay_recording`.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from agents_core.messages import Header, ImageMsg
from agents_core.testing.helpers import free_tcp_port
from agents_core.testing.recipes import open_recipe_transport, run_recipe
from agents_core.transport.registry import resolve_transport

from ..components import vision_recipe
from ..components.models_dir import REPO
from ..components.vision_recipe import found_on, needs_ssd, photo
from ..conftest import wait_for

pytestmark = [pytest.mark.local_models, pytest.mark.zenoh]

mcap_reader = pytest.importorskip("mcap.reader", reason="pip install 'agents-core[record]'")
pytest.importorskip("zenoh", reason="pip install 'agents-core[zenoh]'")

PHOTOS = ("astronaut.png", "chelsea.png", "coffee.png")
FIRST_SEC = 100


def _record_the_recipe(tmp_path: Path) -> tuple[Path, dict[int, int]]:
    """Run the recipe on Zenoh, send each photo until it is answered, record it all; (file, camera sends per sec)."""
    from agents_core.recording import Recorder  # noqa: PLC0415

    transport = open_recipe_transport("zenoh")
    out = tmp_path / "vision.mcap"
    sent: dict[int, int] = {}
    with run_recipe("tests.components.vision_recipe", transport, tmp_path, cwd=REPO):
        # Zenoh peers do not route for each other: the recorder connects to the recipe and to the asker.
        asker_endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
        asker = resolve_transport("zenoh", mode="peer", listen=[asker_endpoint], connect=[transport.endpoint],
                                  multicast_scouting=False)
        recording_side = resolve_transport("zenoh", mode="peer", listen=[],
                                           connect=[transport.endpoint, asker_endpoint], multicast_scouting=False)
        recorder = Recorder(recording_side, out, discover_every_s=0.3, flush_interval_s=0.2)
        recorder.start()
        try:
            detections: dict[int, Any] = {}
            sub = asker.create_subscription(vision_recipe.DETECTIONS,
                                            lambda d: detections.setdefault(d.header.stamp_ns // 10**9, d))
            pub = asker.create_publisher(vision_recipe.CAMERA)
            assert wait_for(lambda: {"camera", "detections", "trackings", "eyes/status"}
                            <= set(recorder.statistics().topics), timeout=30), recorder.statistics()
            for sec, name in enumerate(PHOTOS, start=FIRST_SEC):
                deadline = time.monotonic() + 30
                while sec not in detections and time.monotonic() < deadline:
                    pub.publish(ImageMsg(data=photo(name), encoding="rgb8",
                                         header=Header(stamp_ns=sec * 10**9 + 5, frame_id="cam")))
                    sent[sec] = sent.get(sec, 0) + 1
                    wait_for(lambda s=sec: s in detections, timeout=3)
                assert sec in detections, f"no detection for {name}"
            time.sleep(1.0)  # the trackings and the recorder's own deliveries of the last photo
            sub.close()
            pub.close()
        finally:
            stats = recorder.stop()
            recording_side.close()
            asker.close()
    assert stats.dropped == 0 and stats.errors == 0 and stats.written > 0, stats
    return out, sent


def test_record_read_back_and_replay(tmp_path: Path) -> None:
    needs_ssd()
    pytest.importorskip("rclpy", reason="CDR needs the ros2 extra")
    path, sent = _record_the_recipe(tmp_path)

    # -- the mcap package's own reader: channels, schemas, encodings, counts, stamps -------------------
    with open(path, "rb") as f:
        reader = mcap_reader.make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        channels = {c.topic: c for c in summary.channels.values()}
        schemas = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
        assert schemas["/camera"] == "sensor_msgs/msg/Image"
        assert schemas["/detections"] == "agents_interfaces/msg/Detections2D"
        assert schemas["/trackings"] == "agents_interfaces/msg/Trackings"
        assert schemas["/eyes/status"] == "agents_interfaces/msg/ComponentStatus"
        assert all(c.message_encoding == "cdr" for c in channels.values())
        counts = {c.topic: summary.statistics.channel_message_counts[c.id] for c in channels.values()}
        assert counts["/camera"] == sum(sent.values())
        assert counts["/detections"] >= len(PHOTOS) and counts["/trackings"] >= len(PHOTOS)
        camera_times = [(m.log_time, m.publish_time) for _, c, m in reader.iter_messages(topics=["/camera"])]
    # publish_time is the header stamp; log_time the receipt time (now-ish, after the stamps we made up).
    assert sorted({p // 10**9 for _, p in camera_times}) == list(range(FIRST_SEC, FIRST_SEC + len(PHOTOS)))
    assert all(p % 10**9 == 5 for _, p in camera_times)
    assert all(abs(log / 1e9 - time.time()) < 600 for log, _ in camera_times)

    # -- rosbags, from the schemas in the file: the detections are the photos' objects -----------------
    from rosbags.highlevel import AnyReader  # noqa: PLC0415

    found: dict[int, Any] = {}
    with AnyReader([path]) as bag:
        conns = [c for c in bag.connections if c.topic == "/detections"]
        for conn, _, raw in bag.messages(connections=conns):
            msg = bag.deserialize(raw, conn.msgtype)
            found.setdefault(msg.header.stamp.sec, msg)
    for sec, name in enumerate(PHOTOS, start=FIRST_SEC):
        det = found[sec]
        boxes = [[b.top_left_x, b.top_left_y, b.bottom_right_x, b.bottom_right_y] for b in det.boxes]
        assert found_on(name, list(det.labels), list(det.scores), boxes), (name, det.labels)
        assert det.header.frame_id == "cam" and det.header.stamp.nanosec == 5

    # -- the same recipe on memory answers the recorded camera exactly as it did on Zenoh --------------
    from agents_core.testing.replay import replay_recording  # noqa: PLC0415

    report = replay_recording(path, vision_recipe.build, inputs=["camera"], outputs=["detections", "trackings"],
                              compare={"detections": "exact",
                                       "trackings": lambda old, new: sorted(old.labels) == sorted(new.labels)})
    report.assert_ok()
    assert report.compared >= 2 * len(PHOTOS)


def test_replay_notices_a_changed_recipe(tmp_path: Path) -> None:
    """The helper must fail when the recipe answers differently: a higher threshold drops the detections."""
    needs_ssd()
    pytest.importorskip("rclpy", reason="CDR needs the ros2 extra")
    from agents_core.testing.replay import replay_recording  # noqa: PLC0415

    path, _ = _record_the_recipe(tmp_path)

    def stricter() -> list[Any]:
        component = vision_recipe.build()
        component.config.threshold = 0.999
        return [component]

    report = replay_recording(path, stricter, inputs=["camera"], outputs=["detections"])
    assert not report.ok and report.mismatches
    with pytest.raises(AssertionError, match="differ"):
        report.assert_ok()
    assert all(isinstance(r.boxes, np.ndarray) for _, _, r, _ in report.mismatches)
