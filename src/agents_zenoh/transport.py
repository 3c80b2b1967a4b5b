"""The Zenoh transport: the core's transport contract over one Zenoh session.

``ZenohTransport(**options)`` opens one session (options are the fields of
:class:`~agents_zenoh.config.ZenohConfig`, or pass ``config=ZenohConfig(...)``). It is the core's
:class:`~agents_core.transport.core.DriverTransport` around :class:`ZenohDriver`, which maps:

- topics to key expressions ``<namespace>/<topic>``: a publisher puts msgpack payloads
  (:mod:`agents_zenoh.codecs`) with encoding ``application/msgpack;<TypeName>`` and an
  attachment ``{"seq": n, "stamp_ns": t}`` (with telemetry on, also ``"traceparent"``); a subscriber
  decodes each sample on Zenoh's thread and hands it to the core's sink (a bounded delivery thread
  for user callbacks, the component's worker for component inputs). A sample that does not decode is counted
  (``statistics().decode_errors``), logged once per topic with the reason, and skipped;
- services to queryables on ``<namespace>/<service>`` (msgpack or JSON maps in and out;
  a handler's exception goes back as an error reply and is raised as
  :class:`~agents_core.errors.RemoteError`);
- components to a liveliness token plus two queryables (state, transition), see
  :mod:`agents_zenoh.keys`;
- graph discovery to a liveliness token per publisher and subscriber (:mod:`agents_zenoh.graph`).
- long-running goals to one query stream per goal (and queryables goal, cancel, result, topics feedback, status) under
  ``<namespace>/<action>/@action/``, see :mod:`agents_zenoh.goals`.

QoS: ``reliable`` -> Zenoh reliable + congestion control *block*; ``best_effort`` -> best
effort + *drop*; ``depth`` / ``history`` -> the subscriber's BoundedDelivery queue;
``transient_local`` -> Zenoh's advanced publisher (a cache of ``depth`` samples) and advanced
subscriber (which fetches that history on joining); priority ``data`` unless
:attr:`ZenohConfig.priorities` names another; requests and lifecycle queries go at
``interactive_high`` so they never queue behind bulk data.

The full wire format is in ``docs/zenoh-wire-format.md``.
"""

from __future__ import annotations

import logging
import os
import time
from typing import Any

import attrs
import zenoh

from agents_core.errors import (
    ConfigError,
    RequestTimeoutError,
    ServiceUnavailableError,
    TransportError,
)
from agents_core.messages import ComponentStatusMsg
from agents_core.supported_types import ComponentStatus
from agents_core.topics import Topic
from agents_core.transport.core import DriverTransport
from agents_core.transport.driver import (
    DriverBase,
    GoalEvents,
    GoalServerHooks,
    Lane,
    ServiceHandler,
    Sink,
    TransitionHandler,
)
from agents_core.transport.goals import ActionType
from agents_core.transport.graph import Graph
from agents_core.transport.requests import with_caller_timeout

from .codecs import MSGPACK, CodecError, codec_for, decode_value, pack
from .config import ZenohConfig
from .context import CONTROL_PRIORITY, ZenohContext
from .goal_client import ZenohGoal
from .goals import ZenohActionServer
from .graph import discover_graph
from .keys import state_key, transition_key
from .pubsub import ZenohPublisher, ZenohSubscription
from .queryables import ZenohPresence, ZenohService, read_reply
from .session import joined_rendezvous, open_session

__all__ = ["ZenohDriver", "ZenohTransport", "options_from_environment"]

logger = logging.getLogger(__name__)

_CONTROL_PRIORITY = CONTROL_PRIORITY


# -- the transport ------------------------------------------------------------------------------


class ZenohDriver(DriverBase):
    """The Zenoh primitives under :class:`ZenohTransport` (see the module docstring)."""

    name = "zenoh"
    cross_process = True
    #: Each received value is validated as it is decoded (the codec / the conversion calls ``validate``).
    validates_incoming = True

    def __init__(self, config: ZenohConfig) -> None:
        self.config = config
        self._session = open_session(config)
        #: Whether the loopback rendezvous was taken and this session joined the peers there (the
        #: launcher's transport line says so: two recipes on one host then share their topics).
        self.joined_rendezvous = joined_rendezvous(config)
        #: What the handles (publishers, services, goals, ...) get instead of this driver.
        self.context = ZenohContext(self._session, config)

    # -- helpers ----------------------------------------------------------------------------

    def _check_open(self, what: str) -> None:
        self.context.check_open(what)

    def _key(self, name: str, what: str = "topic") -> str:
        return self.context.key(name, what)

    # -- primitives -------------------------------------------------------------------------

    def open_publisher(self, topic: Topic, owner: str | None) -> ZenohPublisher:
        codec_for(topic.msg_type)  # a type without codec fails here, not at the first sample
        return ZenohPublisher(self.context, topic)

    def open_subscriber(self, topic: Topic, sink: Sink, owner: str | None) -> ZenohSubscription:
        codec_for(topic.msg_type)
        return ZenohSubscription(self.context, topic, sink)

    def serve(self, name: str, handler: ServiceHandler, owner: str | None, lane: Lane) -> ZenohService:
        return ZenohService(self.context, name, handler, lane)

    def call(self, name: str, payload: dict[str, Any], timeout: float) -> dict[str, Any]:
        return self._query(self._key(name, "service"), repr(name), pack(payload), timeout)

    def _query(self, key: str, what: str, body: bytes | bytearray, timeout: float) -> dict[str, Any]:
        start = time.monotonic()
        try:
            replies = self._session.get(key, payload=body, encoding=MSGPACK, timeout=timeout,
                                        consolidation=zenoh.ConsolidationMode.NONE,
                                        priority=_CONTROL_PRIORITY)
            for reply in replies:
                return read_reply(reply, what, timeout)
        except zenoh.ZError as exc:
            self._check_open(f"request {what}")
            raise TransportError(f"request {what} failed: {exc}") from exc
        self._check_open(f"request {what}")  # closing the session ends pending queries without replies
        if time.monotonic() - start >= timeout:
            raise RequestTimeoutError(f"request {what} got no reply within {timeout:g} s")
        raise ServiceUnavailableError(f"nobody serves {what} on zenoh (key {key!r})")

    def serve_goals(self, name: str, definition: ActionType, hooks: GoalServerHooks, owner: str | None,
                    lane: Lane) -> ZenohActionServer:
        self._check_open(f"serve the action {name!r}")
        return ZenohActionServer(self.context, name, hooks, lane)

    def send_goal(self, name: str, definition: ActionType, goal_id: str, goal: dict[str, Any], events: GoalEvents,
                  timeout: float) -> ZenohGoal:
        self._check_open(f"send a goal to {name!r}")
        sent = ZenohGoal(self.context, name, goal_id, events)
        try:
            sent.send(goal, timeout)
        except zenoh.ZError as exc:
            sent.close()
            self._check_open(f"send a goal to {name!r}")
            raise TransportError(f"goal to {name!r} failed: {exc}") from exc
        except BaseException:
            sent.close()
            raise
        return sent

    def declare_presence(self, name: str, on_transition: TransitionHandler, lane: Lane) -> ZenohPresence:
        self._key(name, "component")
        return ZenohPresence(self.context, name, on_transition, lane)

    def request_transition(self, name: str, transition: str, timeout: float) -> bool:
        answer = self._query(transition_key(self.config.namespace, name), f"{name!r} lifecycle",
                             pack(with_caller_timeout({"transition": transition}, timeout)), timeout)
        return bool(answer.get("ok"))

    def read_state(self, name: str, timeout: float) -> ComponentStatusMsg | None:
        key = state_key(self.config.namespace, name)
        try:
            for reply in self._session.get(key, timeout=timeout, consolidation=zenoh.ConsolidationMode.NONE,
                                           priority=_CONTROL_PRIORITY):
                if reply.ok is None:
                    continue
                try:
                    status: ComponentStatusMsg = decode_value(ComponentStatus, reply.ok.payload.to_bytes())
                except CodecError as exc:
                    logger.warning("component %r answered a state that does not decode: %s", name, exc)
                    continue
                return status
        except zenoh.ZError as exc:
            self._check_open(f"read the state of {name!r}")
            raise TransportError(f"reading the state of {name!r} failed: {exc}") from exc
        return None

    def discover(self, timeout: float) -> Graph:
        """Topics and components from the liveliness tokens of every reachable session (:mod:`agents_zenoh.graph`)."""
        self._check_open("discover the graph")
        return discover_graph(self._session, self.config.namespace, timeout)

    def peer_process_options(self) -> dict[str, Any]:
        """ZenohTransport options reaching this session from another process (``multiprocessing=True``).

        A peer listening on fixed endpoints is joined by connecting to them (each child listens
        on its own OS-chosen loopback port, so that Zenoh's gossip links the children to each
        other); a client, a config file or the loopback rendezvous are reused as they are.
        """
        options = attrs.asdict(self.config, recurse=False)
        listen = self.config.listen or []
        if self.config.mode in (None, "peer", "router") and self.config.config_file is None and listen:
            fixed = [ep for ep in listen if not ep.endswith(":0")]
            if not fixed:
                raise ConfigError("multiprocessing on zenoh needs this process to listen on a fixed port "
                                  f"(listen={listen}); give one, or leave listen/connect unset for the rendezvous")
            options.update(mode="peer", listen=["tcp/127.0.0.1:0"], connect=[*fixed, *(self.config.connect or [])])
        return options

    def close(self) -> None:
        """Close the session (the core has closed every publisher, subscriber and queryable)."""
        if self.context.closed:
            return
        self.context.close()  # first: a handle or call racing the close fails as closed, not on a dead session
        try:
            self._session.close()  # type: ignore[no-untyped-call]  # zenoh's stub leaves it unannotated
        except zenoh.ZError as exc:
            logger.debug("closing the zenoh session failed: %s", exc)
        # Zenoh unlinks its shared-memory segment when the last reference to the session is
        # dropped; a step still running on a daemon thread at exit keeps this driver alive,
        # so the references go now (every later call fails on the closed check first).
        del self._session

    def __repr__(self) -> str:
        return f"<ZenohDriver mode={self.config.mode or 'peer'} namespace={self.config.namespace!r}>"


#: Environment variables read for the options not given explicitly (what ``agentsctl run --connect`` sets).
MODE_ENV_VAR = "AGENTS_ZENOH_MODE"
CONNECT_ENV_VAR = "AGENTS_ZENOH_CONNECT"
LISTEN_ENV_VAR = "AGENTS_ZENOH_LISTEN"
NAMESPACE_ENV_VAR = "AGENTS_ZENOH_NAMESPACE"
#: The loopback rendezvous port (ZenohConfig.port): recipes with different ones never join each other.
PORT_ENV_VAR = "AGENTS_ZENOH_PORT"


def options_from_environment() -> dict[str, Any]:
    """ZenohConfig fields from ``AGENTS_ZENOH_MODE``, ``_NAMESPACE`` and the comma-separated ``_CONNECT`` / ``_LISTEN``.

    So a recipe that says only ``Launcher()`` (or ``Launcher(transport="zenoh")``) can be pointed at a
    router from outside: ``AGENTS_ZENOH_CONNECT=tcp/10.0.0.2:7447`` makes it a client of that router
    unless ``AGENTS_ZENOH_MODE`` says otherwise. Explicit options win over these.
    """
    found: dict[str, Any] = {}
    for key, var in (("connect", CONNECT_ENV_VAR), ("listen", LISTEN_ENV_VAR)):
        raw = os.environ.get(var, "").strip()
        if raw:
            found[key] = [ep.strip() for ep in raw.split(",") if ep.strip()]
    namespace = os.environ.get(NAMESPACE_ENV_VAR, "").strip()
    if namespace:
        found["namespace"] = namespace
    port = os.environ.get(PORT_ENV_VAR, "").strip()
    if port:
        if not port.isdigit():
            raise ConfigError(f"{PORT_ENV_VAR}={port!r} is not a port number (1-65535)")
        found["port"] = int(port)
    mode = os.environ.get(MODE_ENV_VAR, "").strip()
    if mode:
        found["mode"] = mode
    elif "connect" in found and "listen" not in found:
        found["mode"] = "client"
    return found


class ZenohTransport(DriverTransport):
    """The core's transport on one Zenoh session: a :class:`DriverTransport` around a :class:`ZenohDriver`.

    :param config: a :class:`ZenohConfig`; or pass its fields as keyword options instead
        (what ``Launcher(transport="zenoh", transport_options={...})`` does). With options, the
        ones not given are read from the environment (:func:`options_from_environment`).
    """

    driver: ZenohDriver

    def __init__(self, config: ZenohConfig | None = None, **options: Any) -> None:
        if config is None:
            config = ZenohConfig.from_dict({**options_from_environment(), **options},
                                           source="ZenohTransport options")
        elif options:
            raise ConfigError("pass either config=ZenohConfig(...) or its fields as options, not both")
        elif not isinstance(config, ZenohConfig):
            raise ConfigError(f"config must be a ZenohConfig, got {type(config).__name__}")
        super().__init__(ZenohDriver(config), request_workers=config.request_workers)

    @property
    def config(self) -> ZenohConfig:
        """The options of the session."""
        return self.driver.config

    def key_expr(self, topic: Topic | str) -> str:
        """The key expression that carries ``topic`` (a Topic or a topic / service name)."""
        return self.driver.context.key(topic.name if isinstance(topic, Topic) else topic)
