"""``Memory``: what the robot observed, where and when, kept in the emem engine and answered by tools.

Each :class:`~agents_core.components.memory.layers.MemLayer` subscribes to one topic. At every
step (``auto_store``) the newest value each layer received since the last step is turned into text
and kept as an observation at the robot's position (an Odometry or PoseStamped topic) when the value
arrived, with its time; a layer whose topic triggers the component keeps every value (each one fired
a step: none is merged into the next when the worker is behind). The ``store`` action keeps each
layer's newest value at the current position. Observations are embedded by the ``embedding_client``
and committed to the SQLite database at ``config.db_path`` in batches (one embedding request and one
transaction for what is waiting), with its vectors; the vector index is saved beside it. What was
committed survives a restart of the component and of the process, a crash included (the index is
re-synced from the rows at open); one process writes a database (an OS lock), another embedding model
or a file that is not a Memory database is refused (``docs/memory.md`` has every guarantee).

Never lost silently: an observation whose position is older than ``config.position_timeout`` (or
missing) is not stored, and counted; one that cannot be stored (a place that is not finite, a text
that is not valid Unicode or longer than ``config.max_text_length``) is refused and counted, and never
holds back the ones after it (and the step reports ``ALGORITHM_FAILURE``). When the
embedding server or the database fails, the step fails with the typed error (health
``COMPONENT_FAILURE``: a :class:`~agents_core.errors.ModelClientError`, or
:class:`~agents_core.components.memory.engine.MemoryStoreError` for the database); the
observations stay in a buffer of ``config.buffer_size`` and the next steps retry them; a full
buffer drops its oldest (counted). :attr:`Memory.stats` has the counters.

Episodes (``start_episode`` / ``end_episode``) group the observations of a task; ending one
consolidates it into a searchable summary through the ``model_client`` (the texts joined, without
one). The retrieval tools (``semantic_search``, ``spatial_query``, ``temporal_query``,
``episode_summary``, ``get_current_context``, ``search_gists``, ``entity_query``, ``locate``,
``recall``, ``body_status``) are component actions with JSON-schema descriptions; their arguments
are checked against the schema before anything runs. :meth:`Memory.register_tools_on` offers them
to an :class:`~agents_core.components.llm.LLM`.
"""

from __future__ import annotations

import collections
import functools
import logging
import math
import sqlite3
import threading
import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

from ...actions import component_action
from ...clients.model_base import ModelClient
from ...errors import AlgorithmFailure, ComponentError, ConfigError, ModelClientError, WiringError
from ...messages import OdometryMsg, PoseMsg, StreamingStringMsg
from ...status import HealthStatus
from ...supported_types import Odometry, Pose, SupportedType
from ...topics import Topic
from ..component_base import Component, TriggerType
from ..layer_points import position_of
from .config import MemoryConfig
from .engine import ClientEmbedder, ClientSummarizer, MemoryStoreError, Observation, open_engine, require_emem
from .layers import Fix, MemLayer
from .tools import TOOL_NAMES, action_description, check_arguments, tool_description
from .writing import MAX_LAYER_NAME, MemoryWriting, problem_of

if TYPE_CHECKING:
    from ..llm import LLM

__all__ = ["Memory"]

#: The layer of notes written through ``store_specific_memory`` (kept apart from the perception streams).
NOTES_LAYER = "agent_notes"
#: A value as it arrived: layer, text, Unix time, the robot's position then, ``time.monotonic()`` then.
_Arrival = tuple[str, str, float, Fix | None, float]


class Memory(MemoryWriting, Component):
    """Remembers what its layers receive, where and when (see the module docs).

    :param layers: the :class:`MemLayer` list (one topic each, distinct).
    :param position: an Odometry or PoseStamped topic: where the robot is (world frame, metres).
    :param model_client: summarises episodes and extracts entities at consolidation (optional: without
        it the texts are joined).
    :param embedding_client: a client that computes embeddings (``GenericHTTPClient`` against an
        OpenAI-compatible ``/v1/embeddings``, ``OllamaClient``); nothing is downloaded.
    :param config: a :class:`~agents_core.components.memory.config.MemoryConfig`.
    :param trigger: when snapshots are taken: a rate in Hz (default 10.0) or topics.
    """

    config_class = MemoryConfig

    def __init__(
        self,
        *,
        layers: Sequence[MemLayer] | None = None,
        position: Topic | None = None,
        model_client: ModelClient | None = None,
        embedding_client: ModelClient | None = None,
        config: MemoryConfig | None = None,
        trigger: TriggerType = 10.0,
        component_name: str = "memory",
        **kwargs: Any,
    ) -> None:
        layers = list(layers or [])
        if not layers or not all(isinstance(layer, MemLayer) for layer in layers):
            raise WiringError(f"component {component_name!r}: layers must be a non-empty list of MemLayer")
        names = [layer.name for layer in layers]
        if len(set(names)) != len(names) or NOTES_LAYER in names:
            raise WiringError(f"component {component_name!r}: layers need distinct topics other than "
                              f"{NOTES_LAYER!r} ({names})")
        if not isinstance(position, Topic) or not issubclass(position.msg_type, Odometry | Pose):
            raise WiringError(f"component {component_name!r}: position must be an Odometry or PoseStamped topic, "
                              f"got {position!r}")
        if position.name in names:
            raise WiringError(f"component {component_name!r}: the position topic cannot also be a layer")
        if not isinstance(embedding_client, ModelClient) or type(embedding_client)._embed is ModelClient._embed:
            raise WiringError(f"component {component_name!r}: embedding_client must be a client that computes "
                              f"embeddings (GenericHTTPClient, OllamaClient), got {embedding_client!r} (Memory "
                              "never downloads an embedding model)")
        if model_client is not None and not isinstance(model_client, ModelClient):
            raise WiringError(f"component {component_name!r}: model_client must be a ModelClient or None")
        self.layers = {layer.name: layer for layer in layers}
        self.position = position
        self.model_client, self.embedding_client = model_client, embedding_client
        self.allowed_inputs = {"Required": [[Odometry, Pose]], "Optional": [SupportedType]}
        super().__init__(inputs=[*(layer.subscribes_to for layer in layers), position], outputs=[], config=config,
                         trigger=trigger, component_name=component_name, **kwargs)
        self.config: MemoryConfig
        self._lock = threading.Lock()  # the buffers below, shared with the transport's threads
        self._engine_lock = threading.RLock()  # the engine: steps, actions and direct calls one at a time
        self._fix: Fix | None = None
        self._partial: dict[str, str] = {}  # per StreamingString layer: the stream in progress
        self._overlong: set[str] = set()  # StreamingString layers whose stream in progress was refused
        # An arrival: (layer, text, Unix time, the position then, time.monotonic() then). Per sampled layer its
        # newest not yet taken by a step; on the layers that trigger the component, every value in order.
        self._fresh: dict[str, _Arrival] = {}
        self._latest: dict[str, tuple[str, float]] = {}  # per layer: the newest value (for ``store``)
        self._arrived: collections.deque[_Arrival] = collections.deque()
        self._actions: dict[str, dict[str, Any]] | None = None
        self._last_stored: dict[str, tuple[str, tuple[int, int]]] = {}  # per layer: text and cell
        self._pending: collections.deque[Observation] = collections.deque()
        self._pending_since: float | None = None
        self._counts: collections.Counter[str] = collections.Counter()
        self._engine: Any = None
        self._embedder: ClientEmbedder | None = None
        self._summarizer: ClientSummarizer | None = None
        self._index_saved = time.monotonic()
        self._clients_ready = False
        self._unplaced = 0  # values dropped for want of a position, since one last arrived
        for name in (*self.layers, position.name):
            cb = self.callbacks.get(name)
            if cb is not None:  # trigger topics record their value in _make_topic_trigger, before the step
                take = self._on_position if name == position.name else functools.partial(self._on_value, name)
                cb.on_callback_execute(take)

    def _make_topic_trigger(self, topic: Topic) -> Callable[[Any], None]:
        fire = super()._make_topic_trigger(topic)

        def record_then_fire(value: Any) -> None:
            if topic.name == self.position.name:
                self._on_position(value)
            else:
                self._on_value(topic.name, value, every=True)
            fire(value)

        return record_then_fire

    # -- counters -----------------------------------------------------------------------------

    @property
    def stats(self) -> dict[str, int]:
        """Counters: ``stored`` observations; not stored: ``no_position`` (no recent position), ``unchanged``
        (same value, same place, on a layer without ``temporal_change``), ``dropped`` (buffer full),
        ``unreadable`` (a value without a text form), ``refused`` (an observation that cannot be stored: a
        place or time that is not finite, a text that is not valid Unicode or too long, or one the database
        or the embedding server refused); failures: ``embed_errors``, ``store_errors``;
        ``pending`` (buffered, to be written, including values that wait for the next step)."""
        with self._lock:
            counts = {k: self._counts[k] for k in ("stored", "no_position", "unchanged", "dropped", "unreadable",
                                                   "refused", "embed_errors", "store_errors")}
            counts["pending"] = len(self._pending) + len(self._arrived)
        return counts

    # -- arrivals (the transport's thread: short) ---------------------------------------------

    def _on_position(self, value: Any) -> None:
        pose = value.pose if isinstance(value, OdometryMsg) else value
        if not isinstance(pose, PoseMsg):
            return
        p = [float(v) for v in pose.position]
        if not all(math.isfinite(v) for v in p):
            return
        with self._lock:
            self._fix = Fix(p[0], p[1], p[2], time.monotonic())

    def _on_value(self, layer: str, value: Any, every: bool = False) -> None:
        if isinstance(value, StreamingStringMsg):
            with self._lock:
                if layer in self._overlong:  # the rest of a stream already refused
                    if value.done:
                        self._overlong.discard(layer)
                    return
                text = self._partial.pop(layer, "") + value.data
                overlong = len(text) > self.config.max_text_length
                if overlong:  # a stream that never ends is not kept whole
                    self._counts["refused"] += 1
                    if not value.done:
                        self._overlong.add(layer)
                elif not value.done:
                    self._partial[layer] = text
                    return
            if overlong:
                self._logger.warning("layer %r: a stream longer than max_text_length=%d: not stored", layer,
                                     self.config.max_text_length)
                return
            value = text
        try:
            stored = self.layers[layer].text_of(value)
        except Exception as exc:  # a value without a text form must not break the transport's thread
            self._count("unreadable")
            self._logger.warning("layer %r: value not stored: %s", layer, exc)
            return
        if stored is None:
            return
        with self._lock:
            arrival = (layer, stored, time.time(), self._fix, time.monotonic())
            self._latest[layer] = (stored, arrival[2])
            if not every:
                self._fresh[layer] = arrival
                return
            if len(self._arrived) >= self.config.buffer_size:
                self._arrived.popleft()
                self._counts["dropped"] += 1
            self._arrived.append(arrival)

    # -- lifecycle ----------------------------------------------------------------------------

    def custom_on_configure(self) -> None:
        require_emem()
        try:
            self._open()
        except (ModelClientError, MemoryStoreError) as exc:
            # Not fatal: observations wait in the buffer and every step retries.
            self._set_health(HealthStatus.COMPONENT_FAILURE, f"{type(exc).__name__}: {exc}")
            self._logger.warning("memory not ready at configure (retrying at each step): %s", exc)

    def custom_on_deactivate(self) -> None:
        self._write_all_quietly()
        self._save_index()

    def custom_on_shutdown(self) -> None:
        self._write_all_quietly()
        with self._engine_lock:
            if self._engine is not None:
                try:
                    self._engine.close()
                except (sqlite3.Error, OSError) as exc:
                    self._logger.warning("memory database did not close cleanly: %s", exc)
                self._engine = None
        if self._clients_ready:
            for client in (self.embedding_client, self.model_client):
                if client is not None:
                    try:
                        client.deinitialize()
                    except Exception as exc:
                        self._logger.warning("client did not deinitialize cleanly: %s", exc)
            self._clients_ready = False
        with self._lock:
            if self._pending or self._arrived:
                self._logger.error("%d observations could not be written before shutdown",
                                   len(self._pending) + len(self._arrived))

    def _write_all_quietly(self) -> None:
        try:
            self._write(force=True)
        except (ModelClientError, MemoryStoreError) as exc:
            self._logger.warning("%d observations not written: %s", self.stats["pending"], exc)

    def _open(self) -> Any:
        """The engine, opening it (and the clients) first if needed; typed errors, counted."""
        with self._engine_lock:
            if self._engine is not None:
                return self._engine
            try:
                if not self._clients_ready:
                    for client in (self.embedding_client, self.model_client):
                        if client is not None:
                            client.check_connection()
                            if client.init_on_activation:
                                client.initialize()
                    self._clients_ready = True
                if self._embedder is None:
                    self._embedder = ClientEmbedder(self.embedding_client)
            except ModelClientError:
                self._count("embed_errors")
                raise
            if self._summarizer is None and self.model_client is not None:
                self._summarizer = ClientSummarizer(self.model_client)
            try:
                engine, notes = open_engine(self.config, self._embedder, self._summarizer)
            except MemoryStoreError:
                self._count("store_errors")
                raise
            count = engine.store.count_observations()
            first_time = count == 0
            self._engine = engine
            self._logger.log(logging.WARNING if notes else logging.INFO,
                             "memory database %r open: %d observation(s), %d entr(ies) findable by meaning%s",
                             self.config.db_path, count, len(engine.store._hnsw_id_map),
                             "".join(f"; {note}" for note in notes))
        if first_time:
            self._write_pre_defined()
        return engine

    def _write_pre_defined(self) -> None:
        for layer in self.layers.values():
            for point, text in layer.pre_defined:
                x, y, z = position_of(point, "pre_defined position")
                self._enqueue(Observation(text.strip(), x, y, z, time.time(), layer.name, layer.is_internal_state))

    # -- snapshots and writing ----------------------------------------------------------------

    def _execution_step(self, **kwargs: Any) -> None:
        if self.config.auto_store:
            self._unplaced += self._snapshot(everything=False)
        self._write(force=False)
        if self._unplaced:
            # The health says so until a position arrives (not only on the step that dropped a value).
            if self._position_is_recent():
                self._unplaced = 0
            else:
                raise AlgorithmFailure(f"{self._unplaced} observation(s) not stored: no position on "
                                       f"{self.position.name!r} in the last {self.config.position_timeout} s")

    def _position_is_recent(self) -> bool:
        with self._lock:
            fix = self._fix
        return fix is not None and time.monotonic() - fix.received <= self.config.position_timeout

    def _snapshot(self, *, everything: bool) -> int:
        """Buffer the values that arrived since the last step, each at the position known when it arrived
        (``everything``: the newest of each layer, at the current position); how many could not be placed
        (no recent position)."""
        with self._lock:
            if everything:
                now, fix = time.monotonic(), self._fix
                taken = [(name, text, stamp, fix, now) for name, (text, stamp) in self._latest.items()]
            else:
                taken = [*self._arrived, *self._fresh.values()]
                self._arrived.clear()
            self._fresh.clear()
        return sum(not self._place(*arrival) for arrival in taken)

    def _place(self, name: str, text: str, stamp: float, fix: Fix | None, now: float) -> bool:
        """Buffer one value at ``fix`` (unless unchanged); False when ``fix`` was not recent at ``now``
        (both read when the value arrived: a worker busy with a slow embedding server loses nothing)."""
        if fix is None or now - fix.received > self.config.position_timeout:
            self._count("no_position")
            return False
        layer = self.layers[name]
        grain = self.config.cell_size * layer.resolution_multiple
        cell = (math.floor(fix.x / grain), math.floor(fix.y / grain))
        if not layer.temporal_change and self._last_stored.get(name) == (text, cell):
            self._count("unchanged")
            return True
        if self._enqueue(Observation(text, fix.x, fix.y, fix.z, stamp, name, layer.is_internal_state)) is None:
            self._last_stored[name] = (text, cell)
        return True

    # -- storage actions ----------------------------------------------------------------------

    @component_action(description={
        "description": "Store the newest value of every layer now, at the robot's current position and time "
                       "(snapshots are otherwise taken automatically at the component's rate).",
        "parameters": {"type": "object", "properties": {}, "required": []},
    })
    def store(self) -> int:
        """Store the newest value of every layer now; returns how many observations were written."""
        if self._snapshot(everything=True):
            raise ComponentError(f"component {self.component_name!r}: no position on {self.position.name!r} in "
                                 f"the last {self.config.position_timeout} s: nothing stored")
        return self._write(force=True)

    @component_action(description={
        "description": "Remember a piece of text (a decision, something the operator said) as an observation. "
                       f"It goes into the '{NOTES_LAYER}' layer unless another layer is named; without x and y "
                       "it is placed at the robot's current position.",
        "parameters": {"type": "object", "properties": {
            "content": {"type": "string", "description": "the text to remember"},
            "layer_name": {"type": "string", "description": f"the layer (default '{NOTES_LAYER}')"},
            "x": {"type": "number", "description": "x (m); omit for the current position"},
            "y": {"type": "number", "description": "y (m); omit for the current position"},
            "z": {"type": "number", "description": "z (m); default 0 or the current position's"}},
            "required": ["content"]},
    })
    def store_specific_memory(self, content: str, layer_name: str = NOTES_LAYER, x: float | None = None,
                              y: float | None = None, z: float | None = None) -> bool:
        """Write ``content`` as an observation now (at x, y, or at the current position); True once written."""
        name = f"component {self.component_name!r}: store_specific_memory"
        if not isinstance(content, str) or not content.strip():
            raise ComponentError(f"{name} needs a non-empty text")
        if not isinstance(layer_name, str) or not 0 < len(layer_name) <= MAX_LAYER_NAME:
            raise ComponentError(f"{name}: layer_name must be a text of 1 to {MAX_LAYER_NAME} characters")
        for axis, value in (("x", x), ("y", y), ("z", z)):
            if value is not None and (isinstance(value, bool) or not isinstance(value, int | float)
                                      or not math.isfinite(value)):
                self._count("refused")
                raise ComponentError(f"{name}: {axis} must be a finite number, got {value!r:.40}: not stored")
        if (x is None) != (y is None):
            raise ComponentError(f"{name}: give both x and y, or neither")
        if x is None or y is None:
            with self._lock:
                fix = self._fix
            if fix is None or time.monotonic() - fix.received > self.config.position_timeout:
                self._count("no_position")
                raise ComponentError(f"{name}: no x, y given and no recent position on {self.position.name!r}: "
                                     "not stored")
            place = (fix.x, fix.y, fix.z if z is None else float(z))
        else:
            place = (float(x), float(y), 0.0 if z is None else float(z))
        layer = self.layers.get(layer_name)
        internal = layer is not None and layer.is_internal_state
        problem = self._enqueue(Observation(content.strip(), *place, time.time(), layer_name, internal))
        if problem is not None:
            raise ComponentError(f"{name}: {problem}: not stored")
        self._write(force=True)
        return True

    @component_action(description={
        "description": "Begin a named episode: the observations from now until end_episode are grouped under it "
                       "and summarised when it ends. Use it when a task begins.",
        "parameters": {"type": "object", "properties": {
            "name": {"type": "string", "description": "the episode's name, e.g. 'kitchen patrol'"}},
            "required": ["name"]},
    })
    def start_episode(self, name: str) -> str:
        """Start an episode named ``name`` (ending the active one first, if any); returns its id."""
        if not isinstance(name, str) or not name.strip():
            raise ComponentError(f"component {self.component_name!r}: an episode needs a name")
        problem = problem_of(Observation(name.strip(), 0.0, 0.0, 0.0, 0.0, "episode", False), MAX_LAYER_NAME)
        if problem is not None:
            raise ComponentError(f"component {self.component_name!r}: start_episode: "
                                 f"{problem.replace('its text', 'the name')}")
        with self._engine_lock:
            self._write(force=True)  # what was observed before belongs to no (or the previous) episode
            engine = self._open()
            if engine.active_episode_id:
                self.end_episode()
            return str(engine.start_episode(name.strip()))

    @component_action(description={
        "description": "End the active episode: its observations are consolidated into a summary (and the things "
                       "they name into entities). Use it when the task is finished.",
        "parameters": {"type": "object", "properties": {}, "required": []},
    })
    def end_episode(self) -> str:
        """End the active episode and consolidate it; returns its id (or says there was none)."""
        with self._engine_lock:
            self._write(force=True)  # every buffered observation must be in the episode before it closes
            engine = self._open()
            try:
                ended = engine.end_episode()
            except (sqlite3.Error, OSError, RuntimeError) as exc:
                self._count("store_errors")
                raise MemoryStoreError(f"cannot consolidate the episode: {type(exc).__name__}: {exc}") from exc
            return str(ended) if ended else "No active episode"

    # -- retrieval tools ----------------------------------------------------------------------

    def available_actions(self) -> dict[str, dict[str, Any]]:
        """The component actions and their descriptions (looked up once: every ``execute_method`` asks)."""
        if self._actions is None:
            self._actions = super().available_actions()
        return dict(self._actions)

    def _tool(self, name: str, arguments: dict[str, Any]) -> str:
        checked = check_arguments(name, arguments)
        with self._engine_lock:
            try:
                self._write(force=True)  # answer with everything observed so far
            except (ModelClientError, MemoryStoreError) as exc:
                self._logger.warning("%s answered without %d buffered observations: %s", name,
                                     self.stats["pending"], exc)
            engine = self._open()
            try:
                return str(engine.dispatch_tool_call(name, checked))
            except (sqlite3.OperationalError, OSError) as exc:
                raise MemoryStoreError(f"{name}: the memory database failed: {type(exc).__name__}: {exc}") from exc
            except (ModelClientError, ComponentError):
                raise
            except Exception as exc:  # the engine refused these arguments: one clear error, never a raw one
                raise ComponentError(f"component {self.component_name!r}: {name} cannot answer {checked!r:.200}: "
                                     f"{type(exc).__name__}: {str(exc)[:200]}") from exc

    @component_action(description=action_description("semantic_search"))
    def semantic_search(self, **kwargs: Any) -> str:
        """Observations nearest in meaning to ``query``."""
        return self._tool("semantic_search", kwargs)

    @component_action(description=action_description("spatial_query"))
    def spatial_query(self, **kwargs: Any) -> str:
        """Observations within ``radius`` of ``x``, ``y``."""
        return self._tool("spatial_query", kwargs)

    @component_action(description=action_description("temporal_query"))
    def temporal_query(self, **kwargs: Any) -> str:
        """Observations in a time window."""
        return self._tool("temporal_query", kwargs)

    @component_action(description=action_description("episode_summary"))
    def episode_summary(self, **kwargs: Any) -> str:
        """Summaries of recorded episodes."""
        return self._tool("episode_summary", kwargs)

    @component_action(description=action_description("get_current_context"))
    def get_current_context(self, **kwargs: Any) -> str:
        """Where the robot is and what is around it."""
        return self._tool("get_current_context", kwargs)

    @component_action(description=action_description("search_gists"))
    def search_gists(self, **kwargs: Any) -> str:
        """Consolidated summaries nearest in meaning to ``query``."""
        return self._tool("search_gists", kwargs)

    @component_action(description=action_description("entity_query"))
    def entity_query(self, **kwargs: Any) -> str:
        """Known entities by name, kind or place."""
        return self._tool("entity_query", kwargs)

    @component_action(description=action_description("locate"))
    def locate(self, **kwargs: Any) -> str:
        """Where ``concept`` was observed: centre and spread."""
        return self._tool("locate", kwargs)

    @component_action(description=action_description("recall"))
    def recall(self, **kwargs: Any) -> str:
        """Everything remembered about ``query`` and around it."""
        return self._tool("recall", kwargs)

    @component_action(description=action_description("body_status"))
    def body_status(self, **kwargs: Any) -> str:
        """The latest reading of each internal-state layer."""
        return self._tool("body_status", kwargs)

    def register_tools_on(self, llm: LLM, tools: Sequence[str] | None = None,
                          send_tool_response_to_model: bool = True) -> None:
        """Let ``llm`` call the retrieval tools (all ten, or those named in ``tools``).

        :param send_tool_response_to_model: give a tool's answer back to the model to answer with
            (default); False publishes the tool's answer itself.
        """
        chosen = list(TOOL_NAMES if tools is None else tools)
        unknown = sorted(set(chosen) - set(TOOL_NAMES))
        if unknown:
            raise ConfigError(f"component {self.component_name!r}: no memory tool(s) {unknown}; "
                              f"the tools are {list(TOOL_NAMES)}")
        for name in chosen:
            llm.register_tool(getattr(self, name), tool_description(name), send_tool_response_to_model)
