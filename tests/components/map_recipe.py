"""The "where did you see the cup?" recipe, run unchanged on each transport by test_map_encoding_recipe.py.

A robot drives along a corridor (simulated odometry), its detector sees a cup at one place and a chair
at another, and MapEncoding writes what it saw into the vector database, in a temporal layer (one
entry per cell, the newest wins). Later the cup has moved: the robot sees nothing where it was and
the cup somewhere else. The map is answered from by :meth:`MapEncoding.find` and by an LLM's RAG.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from agents_core import Launcher, Topic
from agents_core.clients import DBClient
from agents_core.components import MapEncoding, MapLayer
from agents_core.config import MapConfig
from agents_core.messages import DetectionsMsg, Header, OccupancyGridMsg, OdometryMsg, PoseMsg
from agents_core.topics import QoSConfig
from agents_core.transport.contract import Transport

MAP = Topic("map", "OccupancyGrid", qos_profile=QoSConfig(durability="transient_local", depth=1))
ODOM, SEEN = Topic("odom", "Odometry"), Topic("seen", "Detections")
RESOLUTION, ORIGIN, SIZE = 0.25, (-1.0, -2.0), (40, 16)  # 10 m x 4 m, 25 cm cells
#: Where things are: the first drive, then the second (the cup moved to the end of the corridor).
CUP, CHAIR, CUP_LATER = (1.0, 0.5), (3.0, -0.5), (6.5, 1.0)


def build(db_client: DBClient, collection: str) -> MapEncoding:
    """The recipe's component (the part that is the same on every transport)."""
    return MapEncoding(layers=[MapLayer(subscribes_to=SEEN, temporal_change=True)], position=ODOM, map_topic=MAP,
                       db_client=db_client, trigger=20.0,
                       config=MapConfig(map_name=collection, distance_func="cosine", map_wait_timeout=20.0,
                                        require_map=True))


def _grid() -> OccupancyGridMsg:
    return OccupancyGridMsg(data=np.zeros((SIZE[1], SIZE[0]), np.int8), resolution=RESOLUTION,
                            origin=PoseMsg(position=[*ORIGIN, 0.0]), header=Header(frame_id="map"))


def _wait(cond: Any, timeout: float = 30.0) -> None:
    deadline = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > deadline:
            raise TimeoutError("the recipe's map did not take the value in time")
        time.sleep(0.01)


class _MapServer:
    """Publishes the grid a few times a second until stopped (as a map server does; a late joiner gets it)."""

    def __init__(self, transport: Transport) -> None:
        self._pub = transport.create_publisher(MAP)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            self._pub.publish(_grid())
            self._stop.wait(0.2)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5)
        self._pub.close()


def drive(transport: Transport, mapper: MapEncoding, stops: list[tuple[tuple[float, float], list[str]]],
          send_odometry: Callable[[float, float], None] | None = None) -> None:
    """Drive to each stop and report what is seen there; returns once each sighting is in the database.

    ``send_odometry(x, y)`` publishes the position another way (a plain ROS node); it is repeated
    until the mapper has it, as a robot's odometry keeps coming.
    """
    odom, seen = transport.create_publisher(ODOM), transport.create_publisher(SEEN)

    def at(x: float, y: float) -> bool:
        if send_odometry is None:
            odom.publish(OdometryMsg(pose=PoseMsg(position=[x, y, 0.0]), header=Header(frame_id="map")))
        else:
            send_odometry(x, y)
        return mapper._fix is not None and (mapper._fix.x, mapper._fix.y) == (x, y)

    try:
        for (x, y), labels in stops:
            _wait(lambda x=x, y=y: at(x, y))
            before = mapper.stats["written"]
            seen.publish(DetectionsMsg(boxes=[[0, 0, 5, 5]] * len(labels), labels=labels,
                                       scores=[0.9] * len(labels)))
            _wait(lambda before=before: mapper.stats["written"] > before and mapper.stats["pending"] == 0)
    finally:
        odom.close()
        seen.close()


def run(transport: Transport, db_client: DBClient, collection: str, *, others: list[Any] | None = None,
        ask: Callable[[], Any] | None = None, send_odometry: Callable[[float, float], None] | None = None,
        serve_map: bool = True) -> dict[str, Any]:
    """The whole recipe on ``transport`` (with ``others`` components beside the mapper): where the cup was
    found after each drive, the chair, and what ``ask()`` returned at the end (e.g. an LLM's answer)."""
    mapper = build(db_client, collection)
    server = _MapServer(transport) if serve_map else None
    launcher = Launcher(transport)
    launcher.add_pkg(components=[mapper, *(others or [])])
    found: dict[str, Any] = {"mapper": mapper}
    try:
        with launcher:
            drive(transport, mapper, [((0.0, 0.0), []), (CUP, ["cup"]), ((2.0, 0.0), []), (CHAIR, ["chair"])],
                  send_odometry)
            found["first"] = mapper.run_on_worker(lambda: mapper.find("cup", layer="seen", n=1))
            found["chair"] = mapper.run_on_worker(lambda: mapper.find("chair", layer="seen", n=1))
            # The cup moved: nothing where it was, the cup at the end of the corridor.
            drive(transport, mapper, [(CUP, []), (CUP_LATER, ["cup"])], send_odometry)
            found["later"] = mapper.run_on_worker(lambda: mapper.find("cup", layer="seen", n=1))
            found["asked"] = ask() if ask is not None else None
    finally:
        if server is not None:
            server.close()
    return found
