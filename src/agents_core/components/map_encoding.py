"""``MapEncoding``: a semantic map of what the robot saw and heard, and where, in a vector database.

Each :class:`MapLayer` names one input topic (String, StreamingString, Detections or Trackings).
Every value that arrives on it is turned into text and placed where the robot was at that moment:
the latest position (an Odometry or PoseStamped topic) on the grid of the latest map (an
OccupancyGrid topic; a layer's cells are ``resolution_multiple`` x ``resolution_multiple`` grid
cells). Each step writes the new entries through the :class:`~agents_core.clients.db_base.DBClient`
into the collection ``config.map_name``, with the metadata::

    {"layer": str, "cell_x": int, "cell_y": int, "x": float, "y": float, "stamp": float, "frame_id": str}

(``x``/``y`` the robot's position in the map frame, ``stamp`` seconds since the epoch). A layer with
``temporal_change=True`` keeps one entry per cell (its id is the layer and the cell, written as an
upsert: the newest value wins); the others accumulate entries with their time.

Never at a guessed place: a value whose position is older than ``config.position_timeout`` (or
missing), that arrives before any map, or whose position is outside the grid, is not written and
is counted (:attr:`MapEncoding.stats`). The component starts without a map, as upstream's
(``MapConfig.map_wait_timeout`` / ``require_map`` make configure wait for one, or fail without it).
When the database cannot be written, the step fails with the
client's typed error (health ``COMPONENT_FAILURE``), the entries stay in a buffer of
``config.buffer_size`` and are retried by the next steps; a full buffer drops its oldest entry
(counted).

The grid is taken as axis-aligned with the map frame (the origin's rotation is ignored), as
``nav_msgs/OccupancyGrid`` maps from SLAM usually are; positions must be given in the map's frame.

Reading back: :meth:`MapEncoding.find` (a component action; an LLM tool with
``llm.register_tool(mapper.find, mapper.available_actions()["find"])``) returns the nearest
entries with their coordinates; an :class:`~agents_core.components.llm.LLM` with RAG on the same
collection (``add_metadata=True``, optionally :meth:`~agents_core.components.llm.LLM.set_rag_filter`
``({"layer": ...})``) gets the coordinates in its context.
"""

from __future__ import annotations

import collections
import itertools
import math
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

from attrs import define, field

from ..actions import component_action
from ..clients.db_base import DBClient
from ..config import BaseAttrs
from ..errors import ComponentError, ConfigError, ModelClientError, WiringError
from ..messages import DetectionsMsg, OccupancyGridMsg, OdometryMsg, PoseMsg, StreamingStringMsg, TrackingsMsg
from ..status import HealthStatus
from ..supported_types import Detections, OccupancyGrid, Odometry, Pose, String, Trackings
from ..topics import Topic
from .component_base import Component, TriggerType
from .layer_points import convert_points, position_of, pre_defined_validator
from .map_encoding_config import MapConfig

__all__ = ["MapEncoding", "MapLayer"]

#: Layer input types whose values can become text (subclasses included: StreamingString is a String).
_TEXT_TYPES = (String, Detections, Trackings)
#: Written in place of a detection list that found nothing (a temporal layer then forgets the cell's objects).
_NOTHING = "nothing"


def _check_layer_topic(instance: Any, attribute: Any, value: Any) -> None:
    if not isinstance(value, Topic):
        raise ConfigError(f"MapLayer.subscribes_to must be a Topic, got {value!r}")
    if not issubclass(value.msg_type, _TEXT_TYPES):
        raise WiringError(f"MapLayer {value.name!r}: a {value.type_name} cannot be turned into text; a layer takes "
                          "String, StreamingString, Detections or Trackings")


def _check_multiple(instance: Any, attribute: Any, value: Any) -> None:
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise ConfigError(f"MapLayer.resolution_multiple must be an int >= 1, got {value!r}")


def _points(value: Any) -> list[tuple[Any, str]]:
    return convert_points("MapLayer", value)


@define(kw_only=True)
class MapLayer(BaseAttrs):  # BaseAttrs: a layer can be sent to the component's own process
    """One layer of a :class:`MapEncoding` map.

    :param subscribes_to: the topic whose values are stored (String, StreamingString: each finished
        stream, Detections / Trackings: their labels).
    :param temporal_change: keep only the newest entry per cell (things move); False: accumulate
        entries with their time.
    :param resolution_multiple: this layer's cells are this many grid cells wide (coarser layers).
    :param pre_defined: ``(position, text)`` points written once at configure (e.g. room names).
    :param template: a Jinja2 template making the stored text from ``text`` (the value as text) and
        ``labels`` (the detected labels, for Detections / Trackings), e.g. ``"I saw {{ text }}"``.
    """

    subscribes_to: Topic = field(validator=_check_layer_topic)
    temporal_change: bool = field(default=False)
    resolution_multiple: int = field(default=1, validator=_check_multiple)
    pre_defined: list[tuple[Any, str]] = field(factory=list, converter=_points,
                                               validator=pre_defined_validator("MapLayer"))
    template: str | None = field(default=None)
    _compiled: Any = field(default=None, init=False, repr=False)

    def __attrs_post_init__(self) -> None:
        if self.template is not None:
            import jinja2  # noqa: PLC0415  (only layers with a template need it)

            try:
                # A name the template uses but the message lacks renders empty, as upstream's templates.
                self._compiled = jinja2.Environment(autoescape=False).from_string(self.template)
            except jinja2.TemplateSyntaxError as exc:
                raise ConfigError(f"MapLayer {self.name!r}: template is not valid Jinja2: {exc}") from exc

    @property
    def name(self) -> str:
        """The layer's name: its topic's name."""
        return self.subscribes_to.name

    def text_of(self, value: Any) -> str | None:
        """The text stored for ``value`` (None: nothing to store)."""
        labels: list[str] = []
        if isinstance(value, DetectionsMsg | TrackingsMsg):
            labels = list(value.labels)
            text = ", ".join(labels) if labels else _NOTHING
            if not labels and not self.temporal_change:
                return None  # "nothing here" only matters to a layer that forgets
        elif isinstance(value, str):
            text = value.strip()
        else:
            raise ComponentError(f"MapLayer {self.name!r}: cannot turn a {type(value).__name__} into text")
        if not text:
            return None
        if self._compiled is not None:
            text = str(self._compiled.render(text=text, labels=labels)).strip()
        return text or None


@define(frozen=True)
class _Grid:
    resolution: float
    origin_x: float
    origin_y: float
    width: int
    height: int
    frame_id: str

    def cell(self, x: float, y: float, multiple: int) -> tuple[int, int] | None:
        col, row = math.floor((x - self.origin_x) / self.resolution), math.floor((y - self.origin_y) / self.resolution)
        if not (0 <= col < self.width and 0 <= row < self.height):
            return None
        return col // multiple, row // multiple


@define(frozen=True)
class _Fix:
    x: float
    y: float
    stamp: float
    frame_id: str
    received: float  # time.monotonic() at arrival


class MapEncoding(Component):
    """Writes what its layers receive into a vector database, at the robot's position (see the module docs).

    :param layers: the :class:`MapLayer` list (one topic each, distinct).
    :param position: an Odometry or PoseStamped topic: where the robot is, in the map frame.
    :param map_topic: an OccupancyGrid topic: the grid (resolution, origin, size).
    :param config: a :class:`~agents_core.config.MapConfig`.
    :param db_client: the vector database client (e.g. a ChromaClient with an embedding client).
    :param trigger: when entries are written: a rate in Hz (default 1.0: once a second) or topics.
    """

    config_class = MapConfig

    def __init__(
        self,
        layers: Sequence[MapLayer] | None = None,
        position: Topic | None = None,
        map_topic: Topic | None = None,
        config: MapConfig | None = None,
        db_client: DBClient | None = None,
        trigger: TriggerType = 1.0,
        component_name: str = "map_encoding",
        **kwargs: Any,
    ) -> None:
        layers = list(layers or [])
        if not layers or not all(isinstance(layer, MapLayer) for layer in layers):
            raise WiringError(f"component {component_name!r}: layers must be a non-empty list of MapLayer")
        names = [layer.name for layer in layers]
        if len(set(names)) != len(names):
            raise WiringError(f"component {component_name!r}: two layers subscribe to the same topic ({names})")
        if not isinstance(position, Topic) or not issubclass(position.msg_type, Odometry | Pose):
            raise WiringError(f"component {component_name!r}: position must be an Odometry or PoseStamped topic, "
                              f"got {position!r}")
        if not isinstance(map_topic, Topic) or not issubclass(map_topic.msg_type, OccupancyGrid):
            raise WiringError(f"component {component_name!r}: map_topic must be an OccupancyGrid topic, "
                              f"got {map_topic!r}")
        if not isinstance(db_client, DBClient):
            raise WiringError(f"component {component_name!r}: db_client must be a DBClient, got {db_client!r}")
        self.layers = {layer.name: layer for layer in layers}
        self.position_topic, self.map_topic, self.db_client = position, map_topic, db_client
        self.allowed_inputs = {"Required": [[Odometry, Pose], OccupancyGrid], "Optional": list(_TEXT_TYPES)}
        super().__init__(inputs=[*[layer.subscribes_to for layer in layers], position, map_topic], outputs=[],
                         config=config, trigger=trigger, component_name=component_name, **kwargs)
        self.config: MapConfig
        self._lock = threading.Lock()
        self._grid: _Grid | None = None
        self._grid_arrived = threading.Event()
        self._fix: _Fix | None = None
        self._partial: dict[str, str] = {}  # per StreamingString layer: the stream in progress
        # (layer, text, stamp, fix or None, arrival time): taken from the transport's thread.
        self._arrivals: collections.deque[tuple[str, str, float, _Fix | None, float]] = collections.deque()
        self._pending: collections.deque[tuple[str, str, dict[str, Any]]] = collections.deque()
        self._pre_defined_written = False
        self._db_ready = False
        self._seq = itertools.count()
        self._counts: collections.Counter[str] = collections.Counter()
        for name in (*self.layers, position.name, map_topic.name):
            cb = self.callbacks.get(name) or self.trig_callbacks[name]
            if name in self.layers:
                cb.on_callback_execute(self._value_hook(name))
            elif name == position.name:
                cb.on_callback_execute(self._on_position)
            else:
                cb.on_callback_execute(self._on_map)

    # -- counters -----------------------------------------------------------------------------

    @property
    def stats(self) -> dict[str, int]:
        """Counters: ``written`` entries; not written: ``stale_position`` (no recent position), ``no_map``,
        ``outside_map``, ``dropped`` (buffer full); ``db_errors`` (failed writes); ``pending`` (buffered)."""
        with self._lock:
            counts = {k: self._counts[k] for k in ("written", "stale_position", "no_map", "outside_map", "dropped",
                                                   "db_errors")}
            counts["pending"] = len(self._pending) + len(self._arrivals)
        return counts

    # -- arrivals (the transport's thread: short) ---------------------------------------------

    def _value_hook(self, layer: str) -> Callable[[Any], None]:
        def take(value: Any) -> None:
            self._on_value(layer, value)

        return take

    def _on_position(self, value: Any) -> None:
        pose = value.pose if isinstance(value, OdometryMsg) else value
        if not isinstance(pose, PoseMsg):
            return
        header = value.header
        fix = _Fix(float(pose.position[0]), float(pose.position[1]), header.stamp, header.frame_id, time.monotonic())
        with self._lock:
            self._fix = fix

    def _on_map(self, value: Any) -> None:
        if not isinstance(value, OccupancyGridMsg) or value.data.ndim != 2 or value.resolution <= 0:
            self._logger.warning("ignored a map without cells or with resolution %r",
                                 getattr(value, "resolution", None))
            return
        height, width = value.data.shape
        grid = _Grid(float(value.resolution), float(value.origin.position[0]), float(value.origin.position[1]),
                     int(width), int(height), value.header.frame_id)
        with self._lock:
            self._grid = grid
        self._grid_arrived.set()

    def _on_value(self, layer: str, value: Any) -> None:
        now = time.monotonic()
        if isinstance(value, StreamingStringMsg):
            with self._lock:
                text = self._partial.pop(layer, "") + value.data
                if not value.done:
                    self._partial[layer] = text
                    return
            value = text
        try:
            stored = self.layers[layer].text_of(value)
        except Exception as exc:  # a template error must not break the transport's thread
            self._logger.warning("layer %r: value not stored: %s", layer, exc)
            return
        if stored is None:
            return
        header = getattr(value, "header", None)
        stamp = header.stamp if header is not None else time.time()
        with self._lock:
            if len(self._arrivals) >= self.config.buffer_size:
                self._arrivals.popleft()
                self._counts["dropped"] += 1
            self._arrivals.append((layer, stored, stamp, self._fix, now))

    # -- lifecycle ----------------------------------------------------------------------------

    def custom_on_configure(self) -> None:
        if self._grid is None and self.config.map_wait_timeout > 0:
            self._wait_for_map()
        if self._grid is None:
            msg = (f"component {self.component_name!r}: no map on {self.map_topic.name!r} within "
                   f"{self.config.map_wait_timeout} s")
            if self.config.require_map:
                raise ComponentError(msg + " (publish it with durability='transient_local', or set "
                                     "MapConfig.require_map=False to start without it)")
            # The default, as upstream (which reads the map at each step): start now, use the map when it comes.
            self._logger.info("%s; values are dropped (counted as no_map) until it arrives", msg)
        try:
            self._flush()  # connects, and writes the pre-defined points
        except ModelClientError as exc:
            # Not fatal: the entries wait in the buffer and the steps retry.
            self._set_health(HealthStatus.COMPONENT_FAILURE, f"{type(exc).__name__}: {exc}")
            self._logger.warning("database not reachable at configure (retrying at each step): %s", exc)

    def _wait_for_map(self) -> None:
        # The inputs are subscribed at activate; a map (usually latched) is wanted before that.
        cb = self.callbacks.get(self.map_topic.name) or self.trig_callbacks[self.map_topic.name]
        sub = self.transport.create_subscription(self.map_topic, cb._receive, owner=self.component_name)
        try:
            self._grid_arrived.wait(self.config.map_wait_timeout)
        finally:
            sub.close()

    def custom_on_shutdown(self) -> None:
        if self._db_ready:
            try:
                self.db_client.deinitialize()
            except Exception as exc:
                self._logger.warning("database client did not deinitialize cleanly: %s", exc)
            self._db_ready = False

    def _connect(self) -> None:
        if not self._db_ready:
            self.db_client.check_connection()
            if self.db_client.init_on_activation:
                self.db_client.initialize()
            self._db_ready = True
        if not self._pre_defined_written and self._grid is not None:
            for layer in self.layers.values():
                for position, text in layer.pre_defined:
                    xy = position_of(position, "pre_defined position")[:2]
                    self._enqueue(layer.name, text, xy, time.time(), pre=True)
            self._pre_defined_written = True

    # -- the worker's side --------------------------------------------------------------------

    def _execution_step(self, **kwargs: Any) -> None:
        with self._lock:
            arrivals = list(self._arrivals)
            self._arrivals.clear()
        timeout = self.config.position_timeout
        for layer, text, stamp, fix, arrived in arrivals:
            if fix is None or arrived - fix.received > timeout:
                self._count("stale_position")
                continue
            self._enqueue(layer, text, (fix.x, fix.y), stamp)
        self._flush()

    def _count(self, what: str, n: int = 1) -> None:
        with self._lock:
            self._counts[what] += n

    def _enqueue(self, layer_name: str, text: str, xy: tuple[float, float], stamp: float, *, pre: bool = False,
                 ) -> str | None:
        """Place one entry on the map and buffer its write; its id, or None when it cannot be placed."""
        grid, layer = self._grid, self.layers[layer_name]
        if grid is None:
            self._count("no_map")
            return None
        cell = grid.cell(xy[0], xy[1], layer.resolution_multiple)
        if cell is None:
            self._count("outside_map")
            return None
        if layer.temporal_change:
            entry_id = f"{layer_name}:{cell[0]}:{cell[1]}"
        else:
            entry_id = f"{layer_name}:{cell[0]}:{cell[1]}:{'pre' if pre else round(stamp * 1e6)}:{next(self._seq)}"
        metadata = {"layer": layer_name, "cell_x": cell[0], "cell_y": cell[1], "x": float(xy[0]),
                    "y": float(xy[1]), "stamp": float(stamp), "frame_id": grid.frame_id}
        with self._lock:
            if layer.temporal_change:
                # The newer value of the same cell replaces a buffered one: only the latest is kept anyway.
                self._pending = collections.deque(p for p in self._pending if p[0] != entry_id)
            if len(self._pending) >= self.config.buffer_size:
                self._pending.popleft()
                self._counts["dropped"] += 1
            self._pending.append((entry_id, text, metadata))
        return entry_id

    def _flush(self) -> None:
        """Write the buffered entries (one upsert); on failure they stay buffered and the typed error is raised."""
        try:
            self._connect()
            with self._lock:
                batch = list(self._pending)
            if not batch:
                return
            self.db_client.add({"collection_name": self.config.map_name, "distance_func": self.config.distance_func,
                                "ids": [b[0] for b in batch], "documents": [b[1] for b in batch],
                                "metadatas": [b[2] for b in batch]})
        except ModelClientError:
            self._count("db_errors")
            raise
        with self._lock:
            written = {id(b) for b in batch}
            self._pending = collections.deque(p for p in self._pending if id(p) not in written)
            self._counts["written"] += len(batch)

    # -- actions ------------------------------------------------------------------------------

    def _no_layer(self, layer: str) -> ComponentError:
        return ComponentError(f"component {self.component_name!r} has no layer {layer!r} (has {sorted(self.layers)})")

    @component_action(description={
        "description": "Mark a place on the robot's semantic map with a text, in one of its layers.",
        "parameters": {"type": "object", "properties": {
            "layer": {"type": "string", "description": "the layer (its topic name)"},
            "position": {"type": "array", "items": {"type": "number"}, "description": "[x, y] in the map frame"},
            "text": {"type": "string", "description": "what is there"}},
            "required": ["layer", "position", "text"]},
    })
    def add_point(self, layer: str, position: Sequence[float], text: str) -> str:
        """Write ``text`` at ``position`` (x, y in the map frame) in ``layer`` now; returns the entry's id."""
        if layer not in self.layers:
            raise self._no_layer(layer)
        if not isinstance(text, str) or not text.strip():
            raise ComponentError(f"component {self.component_name!r}: add_point needs a non-empty text")
        try:
            xy = position_of(position, "add_point position")[:2]
        except ConfigError as exc:
            raise ComponentError(str(exc)) from exc
        entry_id = self._enqueue(layer, text.strip(), xy, time.time())
        if entry_id is None:
            raise ComponentError(f"component {self.component_name!r}: {xy} is not on the map (or there is no map yet)")
        self._flush()
        return entry_id

    @component_action
    def clear_layer(self, layer: str) -> int:
        """Remove every entry of ``layer`` from the map; returns how many were removed."""
        if layer not in self.layers:
            raise self._no_layer(layer)
        with self._lock:
            self._pending = collections.deque(p for p in self._pending if p[2]["layer"] != layer)
            self._arrivals = collections.deque(a for a in self._arrivals if a[0] != layer)
        self._connect()
        found = self.db_client.metadata_query({"collection_name": self.config.map_name, "where": {"layer": layer}})
        ids = list(found.get("ids") or [])
        if ids:
            # The DBClient contract has no delete: the entries are moved out of every layer (their
            # metadata only: conditional_add keeps existing documents and vectors, nothing is embedded).
            self.db_client.conditional_add({"collection_name": self.config.map_name, "ids": ids,
                                            "documents": list(found.get("documents") or []),
                                            "metadatas": [{"layer": f"{layer}#cleared"} for _ in ids]})
        return len(ids)

    @component_action(description={
        "description": "Find where things were seen or heard: the map entries nearest in meaning to a text, "
                       "with their x, y coordinates in the map frame.",
        "parameters": {"type": "object", "properties": {
            "text": {"type": "string", "description": "what to look for, e.g. 'cup'"},
            "layer": {"type": "string", "description": "only this layer (optional)"},
            "n": {"type": "integer", "description": "how many matches (default 3)"}},
            "required": ["text"]},
    })
    def find(self, text: str, layer: str | None = None, n: int = 3) -> list[dict[str, Any]]:
        """The ``n`` entries nearest to ``text`` (of ``layer``, or of any layer), nearest first, each
        ``{"text", "layer", "x", "y", "cell": [cx, cy], "stamp", "frame_id", "distance"}``."""
        if layer is not None and layer not in self.layers:
            raise self._no_layer(layer)
        if isinstance(n, bool) or not isinstance(n, int) or n < 1:
            raise ComponentError(f"component {self.component_name!r}: find needs n >= 1, got {n!r}")
        self._connect()
        # Filtered on the layers: entries moved out by clear_layer are never found.
        where = {"layer": layer} if layer is not None else {"layer": {"$in": sorted(self.layers)}}
        found = self.db_client.query({"collection_name": self.config.map_name, "query": text, "n_results": n,
                                      "where": where})
        documents = list(found.get("documents") or [])
        metadatas = list(found.get("metadatas") or [None] * len(documents))
        distances = list(found.get("distances") or [None] * len(documents))
        matches = []
        for doc, found_meta, dist in zip(documents, metadatas, distances, strict=False):
            meta = found_meta or {}
            matches.append({"text": doc, "layer": meta.get("layer"), "x": meta.get("x"), "y": meta.get("y"),
                            "cell": [meta.get("cell_x"), meta.get("cell_y")], "stamp": meta.get("stamp"),
                            "frame_id": meta.get("frame_id"), "distance": None if dist is None else float(dist)})
        return matches
