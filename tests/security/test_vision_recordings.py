"""Vision's ``record_video`` from a peer (issue 36, item 6): a bound on recordings at once, refused with a
clear error past it, and ``save_path`` confined to ``config.recordings_dir``.

The calls arrive as any peer would send them: the component's ``execute_method`` service, on the
memory transport, from a second Zenoh session over loopback TCP and from a second ROS 2
participant (a private domain, discovery on this host). The Vision model is a real
RoboML HTTP server double; the camera is a real publisher sending 640x480 frames at 30 Hz.
"""

from __future__ import annotations

import os
import resource
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("PIL", reason="record_video needs Pillow")

from agents_core.clients import RoboMLHTTPClient
from agents_core.components import Vision
from agents_core.config import VisionConfig
from agents_core.errors import AgentsError
from agents_core.launch.launcher import Launcher
from agents_core.messages import ImageMsg
from agents_core.models import VisionModel
from agents_core.testing.helpers import free_tcp_port
from agents_core.testing.pairs import private_ros_environment, skip_unless_installed
from agents_core.topics import Topic

from ..servers.roboml_server import RoboMLTestServer

pytestmark = pytest.mark.timeout(120)
CAMERA = Topic("camera", "Image")


@pytest.fixture(params=["memory", "zenoh", "ros2"])
def peer(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[tuple[Vision, Any, Path]]:
    """A running Vision (recordings_dir inside tmp_path, max_recordings=2) fed by a camera, and the
    transport a peer calls it from."""
    if request.param != "memory":
        skip_unless_installed(request.param)
    domain = private_ros_environment() if request.param == "ros2" else None
    folder = tmp_path / "videos"
    with RoboMLTestServer() as server:
        client = RoboMLHTTPClient(VisionModel(name="eyes"), port=server.port)
        vision = Vision(inputs=[CAMERA], outputs=[Topic("objects", "Detections")], model_client=client,
                        config=VisionConfig(recordings_dir=str(folder), max_recordings=2), component_name="vision")
        port = free_tcp_port()
        if request.param == "memory":
            launcher = Launcher("memory")
        elif request.param == "ros2":
            launcher = Launcher(transport="ros2", transport_options={"domain_id": domain})
        else:
            launcher = Launcher(transport="zenoh", transport_options={
                "mode": "peer", "listen": [f"tcp/127.0.0.1:{port}"], "connect": [], "multicast_scouting": False})
        launcher.add_pkg(components=[vision])
        stop = threading.Event()
        with launcher:
            publisher = launcher.transport.create_publisher(CAMERA)
            frame = np.random.default_rng(0).integers(0, 255, (480, 640, 3), dtype=np.uint8)

            def feed() -> None:
                while not stop.is_set():
                    publisher.publish(ImageMsg(data=frame, encoding="rgb8"))
                    stop.wait(1 / 30)

            feeder = threading.Thread(target=feed, daemon=True)
            feeder.start()
            try:
                if request.param == "memory":
                    yield vision, launcher.transport, folder
                elif request.param == "ros2":  # a second DDS participant, as a peer process would be
                    from agents_ros2.transport import Ros2Transport  # noqa: PLC0415

                    with Ros2Transport(domain_id=domain) as other:
                        time.sleep(1.0)
                        yield vision, other, folder
                else:
                    from agents_core.transport.registry import resolve_transport  # noqa: PLC0415

                    with resolve_transport("zenoh", mode="peer", listen=[], connect=[f"tcp/127.0.0.1:{port}"],
                                           multicast_scouting=False) as other:
                        time.sleep(1.0)
                        yield vision, other, folder
            finally:
                stop.set()
                feeder.join(5)


def _record(transport: Any, **kwargs: Any) -> Any:
    reply = transport.request("vision/execute_method", {"method": "record_video", "kwargs": kwargs, "timeout": 10},
                              timeout=15)
    return reply["result"]


def _maxrss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def test_recordings_past_the_bound_are_refused_with_a_clear_error(peer: tuple[Vision, Any, Path]) -> None:
    vision, transport, folder = peer
    before = _maxrss_mb()
    accepted, refused = [], []
    for _ in range(8):
        try:
            accepted.append(_record(transport, duration=8.0, fps=30))
        except AgentsError as exc:
            refused.append(str(exc))
    assert len(accepted) == 2, (accepted, refused)
    assert len(refused) == 6 and all("max_recordings=2" in r for r in refused), refused
    deadline = time.monotonic() + 30
    while vision._recordings_running and time.monotonic() < deadline:
        time.sleep(0.1)
    assert vision._recordings_running == 0
    # a slot is free again once they end
    again = _record(transport, duration=0.3, fps=10)
    assert again
    deadline = time.monotonic() + 30
    while (vision._recordings_running or len(list(folder.glob("*.gif"))) < 3) and time.monotonic() < deadline:
        time.sleep(0.1)
    gifs = list(folder.glob("*.gif"))
    assert len(gifs) == 3, gifs
    print(f"8 record_video calls: {len(accepted)} accepted, {len(refused)} refused; RSS high-water "
          f"{before:.0f} -> {_maxrss_mb():.0f} MB")
    assert _maxrss_mb() - before < 600  # 2 recordings of 240 palette frames: ~150 MB; 8 unbounded: GBs


@pytest.mark.parametrize("where", ["/etc", "../outside", "~", "/tmp", "sub/../../x", "\x00"])
def test_a_save_path_outside_the_configured_folder_is_refused(peer: tuple[Vision, Any, Path], where: str) -> None:
    vision, transport, _ = peer
    with pytest.raises(AgentsError, match="save_path"):
        _record(transport, duration=0.2, save_path=where)
    assert vision._recordings_running == 0


def test_a_symlink_out_of_the_folder_is_refused_and_a_subfolder_is_fine(peer: tuple[Vision, Any, Path]) -> None:
    _, transport, folder = peer
    folder.mkdir(parents=True, exist_ok=True)
    outside = folder.parent / "elsewhere"
    outside.mkdir()
    os.symlink(outside, folder / "link")
    with pytest.raises(AgentsError, match="outside the configured folder"):
        _record(transport, duration=0.2, save_path="link")
    path = Path(_record(transport, duration=0.3, fps=10, save_path="sub", wait=True))
    assert path.parent == (folder / "sub").resolve() and path.is_file()
    assert list(outside.iterdir()) == []
