"""MapEncoding on the memory transport with a DBClient double: placement, layers, and every bad input."""

from __future__ import annotations

import contextlib
import json
import re
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from agents_core import Launcher, MemoryTransport, Topic
from agents_core.clients import DBClient
from agents_core.components import LLM, MapEncoding, MapLayer
from agents_core.config import LLMConfig, MapConfig
from agents_core.errors import ClientConnectionError, ComponentError, ConfigError, WiringError
from agents_core.messages import (
    DetectionsMsg,
    Header,
    OccupancyGridMsg,
    OdometryMsg,
    PoseMsg,
    StreamingStringMsg,
)
from agents_core.status import HealthStatus
from agents_core.topics import QoSConfig
from agents_core.vectordbs import DB

from ..conftest import wait_for
from .scripted_client import ScriptedChatClient, tool_call

MAP = Topic("map", "OccupancyGrid", qos_profile=QoSConfig(durability="transient_local", depth=1))
ODOM, POSE = Topic("odom", "Odometry"), Topic("pose", "PoseStamped")
SEEN, HEARD, SAID = Topic("seen", "Detections"), Topic("heard", "String"), Topic("said", "StreamingString")
RESOLUTION, ORIGIN = 0.5, (-2.0, -1.0)  # a 10 m x 5 m grid of 20 x 10 cells


class MapDB(DBClient):
    """A DBClient double following db_base's contract: upsert, conditional add, word-overlap query with
    ``where`` (equality, ``$in``, ``$and``), metadata query; ``down`` makes every call fail like a dead server."""

    def __init__(self) -> None:
        super().__init__(db=DB(name="map"))
        self.rows: dict[str, dict[str, tuple[str, dict[str, Any]]]] = {}
        self.down = False
        self.adds = 0

    def _fail_if_down(self) -> None:
        if self.down:
            raise ClientConnectionError("map db: connection refused")

    def _check_connection(self) -> None:
        self._fail_if_down()

    def _initialize(self) -> None: ...
    def _deinitialize(self) -> None: ...

    def _add(self, db_input: dict[str, Any]) -> dict[str, Any]:
        self._fail_if_down()
        self.adds += 1
        rows = self.rows.setdefault(db_input["collection_name"], {})
        for i, doc, meta in zip(db_input["ids"], db_input["documents"], db_input["metadatas"], strict=True):
            rows[i] = (doc, dict(meta))
        return {"ids": list(db_input["ids"])}

    def _conditional_add(self, db_input: dict[str, Any]) -> dict[str, Any]:
        self._fail_if_down()
        rows = self.rows.setdefault(db_input["collection_name"], {})
        for i, doc, meta in zip(db_input["ids"], db_input["documents"], db_input["metadatas"], strict=True):
            rows[i] = (rows[i][0], {**rows[i][1], **meta}) if i in rows else (doc, dict(meta))
        return {"added": [], "skipped": [], "updated_metadatas": list(db_input["ids"])}

    @classmethod
    def _matches(cls, meta: dict[str, Any], where: dict[str, Any] | None) -> bool:
        if not where:
            return True
        if "$and" in where:
            return all(cls._matches(meta, w) for w in where["$and"])
        return all(meta.get(k) in v["$in"] if isinstance(v, dict) else meta.get(k) == v for k, v in where.items())

    def _query(self, db_input: dict[str, Any]) -> dict[str, Any]:
        self._fail_if_down()
        words = set(re.findall(r"[a-z]+", db_input["query"].lower()))

        def distance(doc: str) -> float:
            return 1.0 - len(words & set(re.findall(r"[a-z]+", doc.lower()))) / max(len(words), 1)

        rows = [(i, d, m) for i, (d, m) in self.rows.get(db_input["collection_name"], {}).items()
                if self._matches(m, db_input.get("where"))]
        rows = sorted(rows, key=lambda r: distance(r[1]))[: db_input["n_results"]]
        return {"ids": [r[0] for r in rows], "documents": [r[1] for r in rows], "metadatas": [r[2] for r in rows],
                "distances": [distance(r[1]) for r in rows]}

    def _metadata_query(self, db_input: dict[str, Any]) -> dict[str, Any]:
        self._fail_if_down()
        rows = [(i, d, m) for i, (d, m) in self.rows.get(db_input["collection_name"], {}).items()
                if self._matches(m, db_input["where"])]
        return {"ids": [r[0] for r in rows], "documents": [r[1] for r in rows], "metadatas": [r[2] for r in rows]}

    def layer(self, name: str, collection: str = "map") -> dict[str, tuple[str, dict[str, Any]]]:
        return {i: row for i, row in self.rows.get(collection, {}).items() if row[1]["layer"] == name}


def grid() -> OccupancyGridMsg:
    return OccupancyGridMsg(data=np.zeros((10, 20), np.int8), resolution=RESOLUTION,
                            origin=PoseMsg(position=[*ORIGIN, 0.0]), header=Header(frame_id="map"))


def odom(x: float, y: float) -> OdometryMsg:
    return OdometryMsg(pose=PoseMsg(position=[x, y, 0.0]), header=Header(frame_id="map"))


def seen(*labels: str) -> DetectionsMsg:
    return DetectionsMsg(boxes=[[0, 0, 10, 10]] * len(labels), labels=list(labels), scores=[0.9] * len(labels))


def mapper(db: DBClient, layers: list[MapLayer] | None = None, **config: Any) -> MapEncoding:
    config.setdefault("map_wait_timeout", 2.0)  # these tests start with the map there: wait for it, fail without
    config.setdefault("require_map", True)
    return MapEncoding(layers=layers or [MapLayer(subscribes_to=SEEN, temporal_change=True),
                                         MapLayer(subscribes_to=HEARD)],
                       position=config.pop("position", ODOM), map_topic=MAP, db_client=db,
                       config=MapConfig(**config), trigger=20.0)


@contextlib.contextmanager
def running(component: Any, *, publish_map: bool = True) -> Iterator[tuple[Launcher, Any]]:
    """The component on a memory transport whose (latched) map was published before it starts."""
    transport = MemoryTransport()
    if publish_map:
        transport.create_publisher(MAP).publish(grid())
    launcher = Launcher(transport)
    launcher.add_pkg(components=[component])
    try:
        with launcher:
            yield launcher, lambda topic, value: transport.create_publisher(topic).publish(value)
    finally:
        transport.close()


def settle(m: MapEncoding, written: int) -> None:
    assert wait_for(lambda: m.stats["written"] >= written and m.stats["pending"] == 0, timeout=5), m.stats


def test_values_are_stored_where_the_robot_was_with_their_metadata() -> None:
    db = MapDB()
    m = mapper(db, [MapLayer(subscribes_to=SEEN, temporal_change=True), MapLayer(subscribes_to=HEARD),
                    MapLayer(subscribes_to=SAID, template="someone said: {{ text }}")])
    with running(m) as (_, send):
        send(ODOM, odom(1.2, 0.7))
        assert wait_for(lambda: m._fix is not None)
        send(SEEN, seen("cup", "chair"))
        send(HEARD, "a doorbell")
        for chunk, done in (("hello ", False), ("there", True)):
            send(SAID, StreamingStringMsg(data=chunk, stream=True, done=done))
        settle(m, 3)
    cell = (int((1.2 - ORIGIN[0]) // RESOLUTION), int((0.7 - ORIGIN[1]) // RESOLUTION))
    assert db.layer("seen") == {f"seen:{cell[0]}:{cell[1]}": ("cup, chair", {
        "layer": "seen", "cell_x": cell[0], "cell_y": cell[1], "x": 1.2, "y": 0.7, "frame_id": "map",
        "stamp": db.layer("seen")[f"seen:{cell[0]}:{cell[1]}"][1]["stamp"]})}
    assert [d for d, _ in db.layer("heard").values()] == ["a doorbell"]
    assert [d for d, _ in db.layer("said").values()] == ["someone said: hello there"]
    assert m.stats == {"written": 3, "stale_position": 0, "no_map": 0, "outside_map": 0, "dropped": 0,
                       "db_errors": 0, "pending": 0}


def test_temporal_layers_keep_the_latest_per_cell_others_accumulate_and_cells_coarsen() -> None:
    db = MapDB()
    m = mapper(db, [MapLayer(subscribes_to=SEEN, temporal_change=True),
                    MapLayer(subscribes_to=HEARD, resolution_multiple=4)], position=POSE)
    with running(m) as (_, send):
        send(POSE, PoseMsg(position=[0.1, 0.1, 0.0], header=Header(frame_id="map")))
        assert wait_for(lambda: m._fix is not None)
        send(SEEN, seen("cup"))
        send(HEARD, "music")
        settle(m, 2)
        send(SEEN, seen("chair"))
        send(HEARD, "more music")
        settle(m, 4)
        send(SEEN, seen())  # nothing seen: the temporal layer forgets the chair
        send(POSE, PoseMsg(position=[1.9, 0.1, 0.0], header=Header(frame_id="map")))  # 3 cells on: same coarse cell
        assert wait_for(lambda: m._fix is not None and m._fix.x == 1.9)
        send(HEARD, "even more music")
        settle(m, 6)
    assert [d for d, _ in db.layer("seen").values()] == ["nothing"]
    heard = db.layer("heard")
    assert sorted(d for d, _ in heard.values()) == ["even more music", "more music", "music"]
    assert {(meta["cell_x"], meta["cell_y"]) for _, meta in heard.values()} == {(1, 0)}


def test_a_value_without_a_recent_position_or_off_the_grid_is_counted_not_stored() -> None:
    db = MapDB()
    m = mapper(db, position_timeout=0.2)
    with running(m) as (_, send):
        send(HEARD, "before any position")
        assert wait_for(lambda: m.stats["stale_position"] == 1)
        send(ODOM, odom(0.0, 0.0))
        assert wait_for(lambda: m._fix is not None)
        time.sleep(0.3)
        send(HEARD, "with an old position")
        assert wait_for(lambda: m.stats["stale_position"] == 2)
        send(ODOM, odom(50.0, 0.0))  # east of the 10 m grid
        assert wait_for(lambda: m._fix is not None and m._fix.x == 50.0)
        send(HEARD, "far away")
        assert wait_for(lambda: m.stats["outside_map"] == 1)
        send(ODOM, odom(0.0, 0.0))
        assert wait_for(lambda: m._fix is not None and m._fix.x == 0.0)
        send(HEARD, "here")
        settle(m, 1)
    assert [d for d, _ in db.rows["map"].values()] == ["here"]


def test_no_map_fails_configure_clearly_or_waits_for_it_when_configured_so() -> None:
    m = mapper(MapDB(), map_wait_timeout=0.2)
    with pytest.raises(ComponentError, match=r"no map on 'map' within 0\.2 s"), running(m, publish_map=False):
        pass
    db = MapDB()
    m = mapper(db, map_wait_timeout=0.1, require_map=False)
    with running(m, publish_map=False) as (_, send):
        send(ODOM, odom(0.0, 0.0))
        assert wait_for(lambda: m._fix is not None)
        send(HEARD, "lost")
        assert wait_for(lambda: m.stats["no_map"] == 1)
        send(MAP, grid())
        assert wait_for(lambda: m._grid is not None)
        send(HEARD, "found")
        settle(m, 1)
    assert [d for d, _ in db.rows["map"].values()] == ["found"]


def test_by_default_it_starts_at_once_without_a_map_and_drops_values_until_one_arrives() -> None:
    # Upstream's MapEncoding reads the map at each step: configure does not wait for it.
    db = MapDB()
    m = MapEncoding(layers=[MapLayer(subscribes_to=HEARD)], position=ODOM, map_topic=MAP, db_client=db,
                    config=MapConfig(), trigger=20.0)
    assert (m.config.map_wait_timeout, m.config.require_map) == (0.0, False)
    started = time.monotonic()
    with running(m, publish_map=False) as (_, send):
        assert time.monotonic() - started < 2.0  # no wait for the map (the old default waited 10 s)
        send(ODOM, odom(0.0, 0.0))
        assert wait_for(lambda: m._fix is not None)
        send(HEARD, "before the map")
        assert wait_for(lambda: m.stats["no_map"] == 1)
        send(MAP, grid())
        assert wait_for(lambda: m._grid is not None)
        send(HEARD, "after the map")
        settle(m, 1)
    assert [d for d, _ in db.rows["map"].values()] == ["after the map"]


def test_a_database_that_is_down_sets_health_buffers_boundedly_and_retries() -> None:
    db = MapDB()
    m = mapper(db, buffer_size=3)
    with running(m) as (_, send):
        send(ODOM, odom(0.0, 0.0))
        assert wait_for(lambda: m._fix is not None)
        db.down = True
        for word in ("one", "two", "three", "four", "five"):
            send(HEARD, word)
        assert wait_for(lambda: m.health_status == HealthStatus.COMPONENT_FAILURE)
        assert wait_for(lambda: m.stats["pending"] == 3 and m.stats["dropped"] == 2)
        assert m.stats["db_errors"] >= 1 and "ClientConnectionError" in m.health_message
        db.down = False
        settle(m, 3)
        assert wait_for(lambda: m.health_status == HealthStatus.HEALTHY)
    assert sorted(d for d, _ in db.rows["map"].values()) == ["five", "four", "three"]


def test_a_database_down_at_configure_does_not_stop_the_component() -> None:
    db = MapDB()
    db.down = True
    m = mapper(db)
    with running(m) as (_, send):
        assert m.health_status == HealthStatus.COMPONENT_FAILURE
        send(ODOM, odom(0.0, 0.0))
        assert wait_for(lambda: m._fix is not None)
        send(HEARD, "patience")
        assert wait_for(lambda: m.stats["db_errors"] >= 1)
        db.down = False
        settle(m, 1)


def test_wiring_errors_and_layers_that_cannot_become_text_are_refused_at_construction() -> None:
    with pytest.raises(WiringError, match="Image cannot be turned into text"):
        MapLayer(subscribes_to=Topic("camera", "Image"))
    with pytest.raises(ConfigError, match="resolution_multiple"):
        MapLayer(subscribes_to=HEARD, resolution_multiple=0)
    with pytest.raises(ConfigError, match=r"pre_defined\[0\]"):
        MapLayer(subscribes_to=HEARD, pre_defined=[((1.0,), "kitchen")])
    with pytest.raises(ConfigError, match="Jinja2"):
        MapLayer(subscribes_to=HEARD, template="{{ text ")
    layer = MapLayer(subscribes_to=HEARD)
    db = MapDB()
    for kwargs, match in ((dict(layers=[]), "non-empty list of MapLayer"),
                          (dict(layers=[layer, MapLayer(subscribes_to=HEARD)]), "same topic"),
                          (dict(position=Topic("p", "Twist")), "Odometry or PoseStamped"),
                          (dict(map_topic=Topic("m", "Image")), "OccupancyGrid"),
                          (dict(db_client=None), "DBClient")):
        args: dict[str, Any] = {"layers": [layer], "position": ODOM, "map_topic": MAP, "db_client": db, **kwargs}
        with pytest.raises(WiringError, match=match):
            MapEncoding(**args)


def test_pre_defined_points_actions_and_find_return_coordinates() -> None:
    db = MapDB()
    rooms = Topic("rooms", "String")
    m = mapper(db, [MapLayer(subscribes_to=SEEN, temporal_change=True), MapLayer(subscribes_to=HEARD),
                    MapLayer(subscribes_to=rooms, pre_defined=[((3.0, 1.0), "kitchen"), ((-1.0, 2.0, 0.0), "hall"),
                                                               ((99.0, 0.0), "nowhere")])])
    with running(m):
        assert sorted(d for d, _ in db.layer("rooms").values()) == ["hall", "kitchen"]
        assert m.stats["outside_map"] == 1
        entry = m.run_on_worker(lambda: m.add_point("seen", [2.2, -0.4], "red cup"))
        assert db.rows["map"][entry][1]["x"] == 2.2
        with pytest.raises(ComponentError, match="not on the map"):
            m.run_on_worker(lambda: m.add_point("seen", [40.0, 0.0], "cup"))
        with pytest.raises(ComponentError, match="no layer 'nope'"):
            m.run_on_worker(lambda: m.add_point("nope", [0.0, 0.0], "cup"))
        found = m.run_on_worker(lambda: m.find("where is the cup", n=1))
        assert found[0]["text"] == "red cup" and (found[0]["x"], found[0]["y"]) == (2.2, -0.4), found
        assert found[0]["layer"] == "seen" and found[0]["frame_id"] == "map"
        assert m.run_on_worker(lambda: m.find("kitchen", layer="rooms", n=1))[0]["x"] == 3.0
        assert m.run_on_worker(lambda: m.clear_layer("rooms")) == 2
        assert m.run_on_worker(lambda: m.find("kitchen", layer="rooms")) == []
        assert all(r["layer"] != "rooms" for r in m.run_on_worker(lambda: m.find("kitchen hall", n=5)))
        assert "find" in m.available_actions() and "clear_layer" in m.available_actions()


def test_the_llm_reads_the_map_back_with_coordinates_filtered_by_layer() -> None:
    db = MapDB()
    m = mapper(db)
    question, answer = Topic("question", "String"), Topic("answer", "String")
    client = ScriptedChatClient(["by the window"])
    llm = LLM(inputs=[question], outputs=[answer], model_client=client, db_client=db, trigger=question,
              config=LLMConfig(enable_rag=True, collection_name="map", n_results=1, add_metadata=True))
    llm.set_rag_filter({"layer": "seen"})
    with pytest.raises(ConfigError):
        llm.set_rag_filter({})
    with running(m) as (launcher, send):
        send(ODOM, odom(1.2, 0.7))
        assert wait_for(lambda: m._fix is not None)
        send(HEARD, "the cup song")  # another layer: filtered out although it matches better
        send(SEEN, seen("cup"))
        settle(m, 2)
        inner = Launcher(launcher.transport)
        inner.add_pkg(components=[llm])
        answers: list[str] = []
        with inner:
            launcher.transport.create_subscription(answer, answers.append)
            send(question, "where is the cup song?")
            assert wait_for(lambda: bool(answers))
    content = client.inputs[0]["query"][-1]["content"]
    assert "- cup (metadata:" in content and '"x": 1.2' in content and '"y": 0.7' in content, content


def test_find_is_an_llm_tool_returning_coordinates_as_structured_data() -> None:
    db = MapDB()
    m = mapper(db)
    question, answer = Topic("question", "String"), Topic("answer", "String")
    client = ScriptedChatClient([tool_call("find", {"text": "cup", "layer": "seen", "n": 1}, "call_A")])
    llm = LLM(inputs=[question], outputs=[answer], model_client=client, trigger=question)
    llm.register_tool(m.find, m.available_actions()["find"])
    with running(m) as (launcher, send):
        send(ODOM, odom(-1.0, 2.5))
        assert wait_for(lambda: m._fix is not None)
        send(SEEN, seen("cup"))
        settle(m, 1)
        inner = Launcher(launcher.transport)
        inner.add_pkg(components=[llm])
        answers: list[str] = []
        with inner:
            launcher.transport.create_subscription(answer, answers.append)
            send(question, "where is my cup?")
            assert wait_for(lambda: bool(answers))
    found = json.loads(answers[0])
    assert [(f["text"], f["x"], f["y"], f["layer"]) for f in found] == [("cup", -1.0, 2.5, "seen")]
