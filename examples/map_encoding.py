"""A semantic map: what the robot saw, and where, in a vector database (MapEncoding).

``mapper`` (MapEncoding) places each ``detections`` value (Detections) at the robot's latest
``odom`` position (Odometry) on the cells of the ``map`` (OccupancyGrid) and writes it to the
database. Its layer is temporal: one entry per cell, the newest wins, so a thing that moved is
found at its new place. ``SimulatedRobot`` stands in for the robot: a map server, odometry at 20 Hz,
and a detector that sees a cup and a chair along a corridor, then the cup somewhere else.

The map lives in a Chroma server (the ``servers`` extra brings ``chroma``), its texts embedded by a
llama.cpp server in embedding mode (key, if any, in ``EMBEDDINGS_API_KEY``). The example starts
whichever of the two does not answer on its port (``--no-start-servers`` to refuse)::

    python examples/map_encoding.py --once

To run the servers yourself: ``python -m agents_core.example_servers`` (``--print`` shows the commands).

"Where is the cup?" is the mapper's ``find`` action, asked through its ``execute_method`` service
as any process on the transport can (``agentsctl call mapper find '["cup"]'``).
"""

from __future__ import annotations

import argparse
import os
import threading
import time

import numpy as np
from example_cli import make_launcher, parser, run, servers

from agents_core import Launcher, Topic
from agents_core.clients import ChromaClient, GenericHTTPClient
from agents_core.components import MapEncoding, MapLayer
from agents_core.config import MapConfig
from agents_core.messages import DetectionsMsg, Header, OccupancyGridMsg, OdometryMsg, PoseMsg
from agents_core.models import GenericLLM
from agents_core.topics import QoSConfig
from agents_core.transport.contract import Transport
from agents_core.vectordbs import ChromaDB

# transient_local: a component that starts later still gets the last map (as a ROS map server's is latched).
MAP = Topic("map", "OccupancyGrid", qos_profile=QoSConfig(durability="transient_local", depth=1))
ODOM, SEEN = Topic("odom", "Odometry"), Topic("detections", "Detections")
#: The robot's route: where it stops and what its detector sees there.
FIRST_DRIVE = [((1.0, 0.5), ["cup"]), ((3.0, -0.5), ["chair"])]
SECOND_DRIVE = [((1.0, 0.5), []), ((6.5, 1.0), ["cup"])]  # the cup moved to the end of the corridor


class SimulatedRobot:
    """A 10 m x 4 m map (25 cm cells), odometry at 20 Hz, and a detector reporting what it sees."""

    def __init__(self, transport: Transport) -> None:
        self.x, self.y = 0.0, 0.0
        self._stop = threading.Event()
        self._map, self._odom = transport.create_publisher(MAP), transport.create_publisher(ODOM)
        self._detections = transport.create_publisher(SEEN)
        self._thread = threading.Thread(target=self._run, name="simulated-robot", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        grid = OccupancyGridMsg(data=np.zeros((16, 40), np.int8), resolution=0.25,
                                origin=PoseMsg(position=[-1.0, -2.0, 0.0]), header=Header(frame_id="map"))
        tick = 0
        while not self._stop.wait(0.05):
            if tick % 20 == 0:  # the map once a second
                self._map.publish(grid)
            self._odom.publish(OdometryMsg(pose=PoseMsg(position=[self.x, self.y, 0.0]),
                                           header=Header(frame_id="map")))
            tick += 1

    def stop_at(self, x: float, y: float, seen: list[str]) -> None:
        """Drive to (x, y), then report what the detector sees there."""
        self.x, self.y = x, y
        time.sleep(0.5)  # a few odometry messages at the new place reach the mapper first
        self._detections.publish(DetectionsMsg(boxes=[[0, 0, 5, 5]] * len(seen), labels=seen,
                                               scores=[0.9] * len(seen)))

    def close(self) -> None:
        """Stop publishing."""
        self._stop.set()
        self._thread.join(timeout=5.0)
        for publisher in (self._map, self._odom, self._detections):
            publisher.close()


def build(chroma_port: int, embeddings_port: int, embeddings_model: str = "embeddings") -> MapEncoding:
    """The mapper and its database client."""
    embedder = GenericHTTPClient(GenericLLM(name="embeddings", checkpoint=embeddings_model), port=embeddings_port,
                                 api_key=os.environ.get("EMBEDDINGS_API_KEY"))
    db = ChromaClient(ChromaDB(name="house_db", collection_name="house"), port=chroma_port,
                      embedding_client=embedder)
    return MapEncoding(layers=[MapLayer(subscribes_to=SEEN, temporal_change=True)], position=ODOM, map_topic=MAP,
                       db_client=db, trigger=20.0, component_name="mapper",
                       config=MapConfig(map_name="house", distance_func="cosine"))


def main(argv: list[str] | None = None) -> None:
    """Run the mapper, drive the simulated robot twice, and ask where the cup is after each drive."""
    p = parser(__doc__)
    p.add_argument("--chroma-port", type=int, default=8000, help="the Chroma server's port on 127.0.0.1")
    p.add_argument("--embeddings-port", type=int, default=8080, help="the embeddings server's port on 127.0.0.1")
    p.add_argument("--embeddings-model", default="embeddings", help="the embedding model's name on that server")
    p.add_argument("--no-start-servers", action="store_true", help="fail rather than start a server that is down")
    args = p.parse_args(argv)
    with servers(args, "./map_db"):
        _serve(args)


def _serve(args: argparse.Namespace) -> None:
    mapper = build(args.chroma_port, args.embeddings_port, args.embeddings_model)
    launcher = make_launcher(args)
    launcher.add_pkg(components=[mapper])
    robots: list[SimulatedRobot] = []
    finished = threading.Event()

    def where_is(running: Launcher, thing: str) -> None:
        reply = running.transport.request("mapper/execute_method", {
            "method": "find", "args": [thing], "kwargs": {"layer": "detections", "n": 1}}, timeout=30.0)
        for match in reply["result"]:
            print(f"{match['text']} at x={match['x']:.2f} y={match['y']:.2f}", flush=True)

    def settled(before: dict[str, int]) -> bool:
        now = mapper.stats  # counters of what became of each value: written, or dropped and why
        return now["pending"] == 0 and any(now[key] != before[key] for key in before if key != "pending")

    def sighting(robot: SimulatedRobot, x: float, y: float, seen: list[str]) -> None:
        # A value is never stored at a guessed place: before the first map (or without a fresh
        # position) the mapper drops it and counts why. Report again until it is written (bounded).
        for _ in range(20):
            before = mapper.stats
            robot.stop_at(x, y, seen)
            deadline = time.monotonic() + 30.0
            while not settled(before) and time.monotonic() < deadline:
                time.sleep(0.05)
            if mapper.stats["written"] > before["written"]:
                return
        raise RuntimeError(f"the mapper did not take the sighting at ({x}, {y}): {mapper.stats}")

    def drive(running: Launcher) -> None:
        robot = SimulatedRobot(running.transport)
        robots.append(robot)
        for name, route in (("first drive", FIRST_DRIVE), ("second drive", SECOND_DRIVE)):
            for (x, y), seen in route:
                sighting(robot, x, y, seen)
            print(f"after the {name}:", flush=True)
            where_is(running, "cup")
        finished.set()

    try:
        run(launcher, args, on_ready=drive, done=finished)
    finally:
        for robot in robots:
            robot.close()


if __name__ == "__main__":
    main()
