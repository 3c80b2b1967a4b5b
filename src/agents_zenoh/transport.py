"""The Zenoh transport: the core's transport contract over one Zenoh session.

``ZenohTransport(**options)`` opens one session (options are the fields of
:class:`~agents_zenoh.config.ZenohConfig`, or pass ``config=ZenohConfig(...)``) and maps:

- topics to key expressions ``<namespace>/<topic>``: a publisher puts msgpack payloads
  (:mod:`agents_zenoh.codecs`) with encoding ``application/msgpack;<TypeName>`` and an
  attachment ``{"seq": n, "stamp_ns": t}``; a subscription decodes each sample and hands it to
  a :class:`~agents_core.transport.delivery.BoundedDelivery` (the shared queue policy). A
  sample that does not decode is counted (``statistics().decode_errors``), logged once per
  topic with the reason, and skipped;
- services to queryables on ``<namespace>/<service>`` (msgpack or JSON maps in and out;
  a handler's exception goes back as an error reply and is raised as
  :class:`~agents_core.errors.RemoteError`);
- components to a liveliness token plus two queryables (state, transition), see
  :mod:`agents_zenoh.keys`.

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
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import zenoh

from agents_core.errors import (
    ConfigError,
    RequestTimeoutError,
    ServiceUnavailableError,
    TransportClosedError,
    TransportError,
    WiringError,
)
from agents_core.messages import ComponentStatusMsg
from agents_core.supported_types import ComponentStatus
from agents_core.topics import Topic
from agents_core.transport.contract import (
    ServiceHandler,
    SubscriptionCallback,
    TransitionHandler,
    Transport,
    TransportCapabilities,
)
from agents_core.transport.delivery import TopicCounters, TopicStatistics
from agents_core.transport.requests import RequestLanes, check_timeout, with_caller_timeout

from .codecs import MSGPACK, CodecError, codec_for, decode_value, pack
from .config import ZenohConfig
from .keys import state_key, topic_key, transition_key
from .pubsub import ZenohPublisher, ZenohSubscription
from .queryables import ZenohPresence, ZenohService, read_reply
from .session import open_session

__all__ = ["ZenohTransport"]

logger = logging.getLogger(__name__)

_CONTROL_PRIORITY = zenoh.Priority.INTERACTIVE_HIGH


def _closed_error(what: str) -> TransportClosedError:
    return TransportClosedError(f"{what}: the zenoh transport is closed")


# -- the transport ------------------------------------------------------------------------------


class ZenohTransport:
    """The core's transport contract on one Zenoh session (see the module docstring).

    :param config: a :class:`ZenohConfig`; or pass its fields as keyword options instead
        (what ``Launcher(transport="zenoh", transport_options={...})`` does).
    """

    name = "zenoh"
    capabilities = TransportCapabilities(cross_process=True, services=True, actions=False,
                                         shared_memory=True, zero_copy=False, lifecycle_services=True)

    def __init__(self, config: ZenohConfig | None = None, **options: Any) -> None:
        if config is None:
            config = ZenohConfig.from_dict(options, source="ZenohTransport options")
        elif options:
            raise ConfigError("pass either config=ZenohConfig(...) or its fields as options, not both")
        elif not isinstance(config, ZenohConfig):
            raise ConfigError(f"config must be a ZenohConfig, got {type(config).__name__}")
        self.config = config
        self._lock = threading.RLock()
        self._closed = False
        self._types: dict[str, str] = {}
        self._entities: set[Any] = set()
        self._services: dict[str, ZenohService] = {}
        self._components: dict[str, ZenohPresence] = {}
        self._counters = TopicCounters()
        # Each component's requests on a lane of its own: a busy component never delays another's.
        self._lanes = RequestLanes("zenoh-request", shared_workers=config.request_workers)
        try:
            self._session = open_session(config)
        except BaseException:
            self._lanes.shutdown()
            raise

    # -- helpers ----------------------------------------------------------------------------

    def _check_open(self, what: str) -> None:
        if self._closed:
            raise _closed_error(what)

    def _key(self, name: str, what: str = "topic") -> str:
        return topic_key(self.config.namespace, name, what)

    def key_expr(self, topic: Topic | str) -> str:
        """The key expression that carries ``topic`` (a Topic or a topic / service name)."""
        return self._key(topic.name if isinstance(topic, Topic) else topic)

    def _priority(self, topic: Topic) -> zenoh.Priority:
        name = self.config.priorities.get(topic.name, "data")
        priority: zenoh.Priority = getattr(zenoh.Priority, name.upper())
        return priority

    def _check_type(self, topic: Topic) -> None:
        codec_for(topic.msg_type)  # a type without codec fails here, not at the first sample
        known = self._types.setdefault(topic.name, topic.type_name)
        if known != topic.type_name:
            raise WiringError(f"topic {topic.name!r} already carries {known}; cannot also use it for {topic.type_name}")

    def _forget(self, entity: Any) -> None:
        with self._lock:
            self._entities.discard(entity)
            if isinstance(entity, ZenohService) and self._services.get(entity.name) is entity:
                del self._services[entity.name]
            if isinstance(entity, ZenohPresence) and self._components.get(entity.name) is entity:
                del self._components[entity.name]

    def _submit(self, owner: str | None, func: Callable[[zenoh.Query], None], query: zenoh.Query) -> None:
        try:
            self._lanes.submit(owner, func, query)
        except RuntimeError:  # the lanes are shut down: the transport is closing
            query.drop()  # type: ignore[no-untyped-call]  # zenoh's stub leaves it unannotated

    def statistics(self, topic_name: str | None = None) -> dict[str, TopicStatistics]:
        """Counters per topic of this transport's publishers and subscriptions, as a snapshot.

        ``published`` counts values this process put; ``delivered`` / ``dropped`` /
        ``callback_errors`` / ``discarded`` / ``decode_errors`` sum over its subscriptions.
        """
        return self._counters.snapshot(topic_name)

    # -- pub / sub --------------------------------------------------------------------------

    def create_publisher(self, topic: Topic, *, owner: str | None = None) -> ZenohPublisher:
        """A publisher for ``topic`` (``owner`` is accepted for the contract and not used)."""
        with self._lock:
            self._check_open(f"create a publisher on {topic.name!r}")
            self._check_type(topic)
            pub = ZenohPublisher(self, topic)
            self._counters.track(topic.name)
            self._entities.add(pub)
        return pub

    def create_subscription(
        self, topic: Topic, callback: SubscriptionCallback, *, owner: str | None = None
    ) -> ZenohSubscription:
        """Decode every sample on ``topic`` and call ``callback(value)`` from a delivery thread."""
        with self._lock:
            self._check_open(f"subscribe to {topic.name!r}")
            self._check_type(topic)
            sub = ZenohSubscription(self, topic, callback)
            self._entities.add(sub)
        return sub

    # -- request / reply --------------------------------------------------------------------

    def create_service(self, name: str, handler: ServiceHandler, *, owner: str | None = None) -> ZenohService:
        """Serve requests on ``<namespace>/<name>`` with ``handler`` (run on the request pool)."""
        with self._lock:
            self._check_open(f"serve {name!r}")
            if name in self._services:
                raise WiringError(f"service {name!r} is already served on this transport")
            service = ZenohService(self, name, handler, owner)
            self._services[name] = service
            self._entities.add(service)
        return service

    def request(self, name: str, payload: dict[str, Any], *, timeout: float = 5.0) -> dict[str, Any]:
        """Send ``payload`` to the service ``name`` and return its reply map."""
        timeout = check_timeout(timeout, f"request to {name!r}")
        self._check_open(f"request {name!r}")
        return self._query(self._key(name, "service"), repr(name), pack(with_caller_timeout(payload, timeout)),
                           timeout)

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

    # -- presence ---------------------------------------------------------------------------

    def declare_component(self, name: str, *, on_transition: TransitionHandler) -> ZenohPresence:
        """Declare the liveliness token and the state / transition queryables of component ``name``."""
        with self._lock:
            self._check_open(f"declare component {name!r}")
            self._key(name, "component")
            if name in self._components:
                raise WiringError(f"a component named {name!r} is already declared on this transport")
            presence = ZenohPresence(self, name, on_transition)
            self._components[name] = presence
            self._entities.add(presence)
        return presence

    def get_component_state(self, name: str, *, timeout: float = 2.0) -> ComponentStatusMsg | None:
        """Query ``<ns>/@agents/state/<name>``; None when no such component answers."""
        timeout = check_timeout(timeout, f"state of {name!r}")
        self._check_open(f"read the state of {name!r}")
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

    def request_transition(self, name: str, transition: str, *, timeout: float = 5.0) -> bool:
        """Ask component ``name`` (in any process) to run ``transition``; True if it did."""
        timeout = check_timeout(timeout, f"transition of {name!r}")
        self._check_open(f"request a transition of {name!r}")
        reply = self._query(transition_key(self.config.namespace, name), f"{name!r} lifecycle",
                            pack(with_caller_timeout({"transition": transition}, timeout)), timeout)
        return bool(reply.get("ok"))

    # -- teardown ---------------------------------------------------------------------------

    def close(self) -> None:
        """Withdraw every component, subscription, service and publisher, then close the session."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            # Components first, so observers see them go before their topics fall silent.
            entities = sorted(self._entities, key=lambda e: not isinstance(e, ZenohPresence))
        for entity in entities:
            try:
                entity.close()
            except Exception as exc:
                logger.debug("closing %r failed: %s", entity, exc)
        self._lanes.shutdown()
        try:
            self._session.close()  # type: ignore[no-untyped-call]  # zenoh's stub leaves it unannotated
        except zenoh.ZError as exc:
            logger.debug("closing the zenoh session failed: %s", exc)
        # Zenoh unlinks its shared-memory segment when the last reference to the session is
        # dropped; a step still running on a daemon thread at exit keeps this transport alive,
        # so the reference goes now (every later call fails on the closed check first).
        del self._session

    def __enter__(self) -> ZenohTransport:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return (f"<ZenohTransport mode={self.config.mode or 'peer'} namespace={self.config.namespace!r} "
                f"closed={self._closed}>")


if TYPE_CHECKING:
    # mypy checks here that ZenohTransport satisfies the Transport protocol.
    _conforms: Transport = ZenohTransport()
