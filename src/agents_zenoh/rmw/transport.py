"""The ``rmw_zenoh`` transport: the core's transport contract in ROS 2's own Zenoh wire format, without rclpy.

``Launcher(transport="rmw_zenoh")``. Each component is one ROS 2 node (a ``NN`` liveliness token) owning
its topics and services; the rest belong to one node of the transport (``agents_core_<pid>``). It maps:

- topics to rmw_zenoh data keys (:mod:`.wire`), values converted by the ``ros2`` transport's conversions
  and written as CDR (:mod:`.codec`); each publisher / subscription declares its ``MP`` / ``MS`` token;
  a subscription listens on the whole topic and refuses (counts, as decode errors) samples of another
  type or hash, a missing or malformed attachment, and CDR that does not decode;
- request/reply to ROS services ``agents_interfaces/srv/JsonCall`` on queryables (``SS`` token; a
  client's queries carry its ``SC`` token's GID and a sequence number, echoed in the reply);
- presence to the standard lifecycle services ``<component>/get_state`` and ``<component>/change_state``
  (``lifecycle_msgs``); the core publishes ``<component>/status`` as on the ``ros2`` transport;
- discovery to the liveliness tokens under ``@ros2_lv/<domain>/`` (plain ROS nodes' topics included).

QoS: reliability (Zenoh reliable + block / best effort + drop) and transient_local (Zenoh's advanced
publisher cache and subscriber history, as rmw_zenoh does) are honoured; depth bounds the cache and the
core's delivery queue; deadline, lifespan and liveliness other than automatic are not (rmw_zenoh has none
either). Long-running goals are ROS 2 actions of the action type's ``ros_type``
(``<name>/_action/send_goal`` ... as rcl_action names them, see :mod:`.goals`).

Options: ``domain_id`` (default ``ROS_DOMAIN_ID``), ``connect`` / ``listen`` / ``mode`` (default: as
rmw_zenoh, see :mod:`.session`), ``router_timeout`` (seconds to wait for a router, default 3; 0: none),
``zenoh_options`` (config key -> value), ``max_graph_tokens`` (other sessions' liveliness tokens the graph holds
at most, an int of at least 1, default :data:`~agents_zenoh.rmw.discovery.MAX_TOKENS`; past it new ones are
dropped and counted, and read again once room comes back).
"""

from __future__ import annotations

import itertools
import json
import logging
import os
import threading
import time
from typing import Any

import zenoh

from agents_core.errors import ConfigError, RequestTimeoutError, ServiceUnavailableError, TransportError
from agents_core.messages import ComponentStatusMsg
from agents_core.status import HealthStatus, LifecycleState
from agents_core.support import bounded_json
from agents_core.support.bounded_json import REQUEST_JSON_LIMITS
from agents_core.supported_types import ComponentStatus
from agents_core.topics import Topic
from agents_core.transport.core import DriverTransport, status_topic
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
from agents_core.transport.requests import json_call_reply

from .codec import codec_for
from .discovery import MAX_TOKENS, GraphCache, graph_of
from .entities import SERVICE_QOS, Entity, Node, Publisher, ServiceServer, Subscription, absolute, node_name
from .goals import RmwActionClient, RmwActionServer, RmwGoal
from .session import domain_from_environment, open_rmw_session, session_config
from .typesupport import ros_types
from .wire import decode_attachment

__all__ = ["RmwZenohDriver", "RmwZenohTransport"]

logger = logging.getLogger(__name__)

JSON_CALL = "agents_interfaces/srv/JsonCall"
GET_STATE = "lifecycle_msgs/srv/GetState"
CHANGE_STATE = "lifecycle_msgs/srv/ChangeState"
#: lifecycle_msgs/msg/State ids of the resting states.
STATE_IDS = {"unconfigured": 1, "inactive": 2, "active": 3, "finalized": 4, "errorprocessing": 15}
#: How long a request waits for a route to a server of which no token is seen (discovery settling).
_SETTLE_S = 1.0
_OPTIONS = {"domain_id", "connect", "listen", "mode", "router_timeout", "zenoh_options", "request_workers",
            "max_graph_tokens"}


class _Presence:
    """A component's node with its lifecycle services."""

    def __init__(self, driver: RmwZenohDriver, name: str, on_transition: TransitionHandler, lane: Lane) -> None:
        self.node = driver.node_for(name)
        self._state = "unconfigured"
        types = ros_types()
        self._state_cls = types.message_class("lifecycle_msgs/msg/State")
        self._get_cls = types.message_class(f"{GET_STATE}_Response")
        self._change_cls = types.message_class(f"{CHANGE_STATE}_Response")

        def get_state(_request: Any, answer: Any) -> None:
            answer(self._get_cls(current_state=self._state_cls(id=STATE_IDS.get(self._state, 0), label=self._state)))

        def change_state(request: Any, answer: Any) -> None:
            def job() -> None:
                ok = False
                try:
                    ok = bool(on_transition(str(request.transition.label)))
                finally:
                    answer(self._change_cls(success=ok))
            lane(job)

        self._servers = [
            ServiceServer(self.node, absolute(f"{name}/get_state"), GET_STATE, get_state, driver.refused),
            ServiceServer(self.node, absolute(f"{name}/change_state"), CHANGE_STATE, change_state, driver.refused)]

    def update(self, state: LifecycleState, health: HealthStatus, message: str) -> None:
        self._state = state.value

    def close(self) -> None:
        for server in self._servers:
            server.close()


class _Latest:
    """A sink keeping the newest value (the status watch of read_state)."""

    def __init__(self) -> None:
        self.value: Any = None

    def offer(self, value: Any) -> None:
        self.value = value

    def reject(self, reason: object) -> None:
        logger.debug("unreadable status: %s", reason)


class RmwZenohDriver(DriverBase):
    """The rmw_zenoh primitives under :class:`RmwZenohTransport` (see the module docstring)."""

    name = "rmw_zenoh"
    cross_process = True
    validates_incoming = True

    def __init__(self, **options: Any) -> None:
        unknown = set(options) - _OPTIONS
        if unknown:
            raise ConfigError(f"rmw_zenoh transport: unknown option(s) {sorted(unknown)}; known: {sorted(_OPTIONS)}")
        self.options = dict(options)
        bound = options.get("max_graph_tokens", MAX_TOKENS)
        if isinstance(bound, bool) or not isinstance(bound, int) or bound < 1:
            raise ConfigError(f"rmw_zenoh transport: max_graph_tokens must be an int of at least 1, got {bound!r}")
        self.domain_id = int(options.get("domain_id", domain_from_environment()))
        config = session_config(mode=options.get("mode"), connect=options.get("connect"),
                                listen=options.get("listen"), zenoh_options=options.get("zenoh_options"))
        self._session = open_rmw_session(config, float(options.get("router_timeout", 3.0)))
        self._ids = itertools.count().__next__
        self._lock = threading.Lock()
        self._nodes: dict[str, Node] = {}
        self._clients: dict[tuple[str, str], Entity] = {}
        self._action_clients: dict[tuple[str, str], RmwActionClient] = {}
        self._status: dict[str, tuple[Subscription, _Latest]] = {}
        self.refused_requests = 0
        self._closed = False
        try:
            self._graph = GraphCache(self._session, self.domain_id, bound)
            self._own = Node(self._session, self.domain_id, f"agents_core_{os.getpid()}", self._ids,
                             graph=self._graph)
        except BaseException:
            self._session.close()  # type: ignore[no-untyped-call]  # not left open behind a transport that never was
            raise

    # -- nodes --------------------------------------------------------------------------------

    def node_for(self, owner: str | None) -> Node:
        """The node of component ``owner`` (created on first use), or the transport's own.

        A namespaced component (``robot1/arm``, see :mod:`agents_core.transport.namespace`) is node ``arm`` in
        namespace ``/robot1``, as on ROS 2."""
        if owner is None:
            return self._own
        with self._lock:
            node = self._nodes.get(owner)
            if node is None:
                namespace, name = node_name(owner)
                node = self._nodes[owner] = Node(self._session, self.domain_id, name, self._ids, namespace,
                                                 self._graph)
            return node

    @property
    def graph(self) -> GraphCache:
        """The liveliness tokens seen (with the counts of bogus and dropped ones)."""
        return self._graph

    def refused(self, reason: object) -> None:
        """A query that did not decode (bad attachment or CDR): counted and logged."""
        self.refused_requests += 1
        logger.warning("rmw_zenoh: refused a request: %s", reason)

    # -- primitives -----------------------------------------------------------------------------

    def open_publisher(self, topic: Topic, owner: str | None) -> Publisher:
        return Publisher(self.node_for(owner), topic, codec_for(topic.msg_type))

    def open_subscriber(self, topic: Topic, sink: Sink, owner: str | None) -> Subscription:
        return Subscription(self.node_for(owner), topic, codec_for(topic.msg_type), sink)

    def serve(self, name: str, handler: ServiceHandler, owner: str | None, lane: Lane) -> ServiceServer:
        response = ros_types().message_class(f"{JSON_CALL}_Response")

        def serve(request: Any, answer: Any) -> None:
            def job() -> None:
                try:
                    payload = bounded_json.loads(request.request_json or "{}", REQUEST_JSON_LIMITS)
                    if not isinstance(payload, dict):
                        raise ConfigError(f"a request must be a JSON object, got {type(payload).__name__}")
                    reply = response(success=True, error="", response_json=json.dumps(handler(payload)))
                except Exception as exc:
                    reply = response(success=False, error=f"{type(exc).__name__}: {exc}", response_json="")
                answer(reply)
            lane(job)

        return ServiceServer(self.node_for(owner), absolute(name), JSON_CALL, serve, self.refused)

    def _client(self, name: str, service_type: str) -> Entity:
        with self._lock:
            found = self._clients.get((name, service_type))
            if found is None:
                types = ros_types()
                found = self._clients[(name, service_type)] = self._own.entity(
                    "SC", absolute(name), service_type, types.type_hash(service_type), SERVICE_QOS)
            return found

    def _request(self, name: str, service_type: str, request: Any, timeout: float) -> Any:
        if self._closed:
            raise TransportError(f"request to {name!r}: the rmw_zenoh transport is closed")
        types = ros_types()
        client = self._client(name, service_type)
        body = types.serialize(request, f"{service_type}_Request")
        attachment = client.attachment()
        sent = decode_attachment(attachment)
        start = time.monotonic()
        deadline = start + timeout
        while True:
            found = self._query_once(client.key, body, attachment, sent, deadline - time.monotonic(), name)
            if found is not None:
                return types.deserialize(found, f"{service_type}_Response")
            now = time.monotonic()
            if now >= deadline - 0.01:
                raise RequestTimeoutError(f"request to {name!r} got no reply within {timeout:g} s")
            # No route to the server yet (a fresh session learns of queryables a moment later): retry while its
            # token is live, or for the discovery settle time when none is seen.
            if now - start >= _SETTLE_S and not self._served(client.token):
                raise ServiceUnavailableError(f"nobody serves {name!r} on rmw_zenoh (key {client.key!r})")
            time.sleep(0.05)

    def _query_once(self, key: str, body: bytes, attachment: bytes, sent: Any, timeout: float,
                    name: str) -> bytes | None:
        try:
            replies = self._session.get(key, payload=body, attachment=attachment, timeout=max(timeout, 0.01),
                                        target=zenoh.QueryTarget.ALL_COMPLETE,
                                        consolidation=zenoh.ConsolidationMode.NONE)
            for reply in replies:
                if reply.ok is None:
                    continue
                raw = reply.ok.attachment
                try:
                    echo = decode_attachment(raw.to_bytes() if raw is not None else None)
                except ValueError as exc:
                    logger.warning("rmw_zenoh: a reply from %r without rmw_zenoh's attachment: %s", name, exc)
                    continue
                if (echo.sequence_number, echo.gid) != (sent.sequence_number, sent.gid):
                    continue  # a reply to someone else's query
                return bytes(reply.ok.payload.to_bytes())
        except zenoh.ZError as exc:
            raise TransportError(f"request to {name!r} failed: {exc}") from exc
        return None

    def ros_request(self, name: str, service_type: str, request: Any, timeout: float) -> Any:
        """Call the ROS service ``name`` (absolute) of ``service_type`` with ``request`` (an object with its fields)."""
        return self._request(name, service_type, request, timeout)

    def served(self, name: str, service_type: str) -> bool:
        """Whether a server of the ROS service ``name`` (absolute) and ``service_type`` is seen in the graph."""
        return self._served(self._client(name, service_type).token)

    def _served(self, client_token: str) -> bool:
        """Whether the graph cache holds a service server token for the client's service and type."""
        wanted = client_token.split("/")[9:11]
        for token in self._graph.tokens(0):
            parts = token.split("/")
            if len(parts) == 13 and parts[5] == "SS" and parts[9:11] == wanted:
                return True
        return False

    def call(self, name: str, payload: dict[str, Any], timeout: float) -> dict[str, Any]:
        request = ros_types().message_class(f"{JSON_CALL}_Request")(request_json=json.dumps(payload))
        response = self._request(name, JSON_CALL, request, timeout)
        return json_call_reply(name, response.success, response.error, response.response_json)

    def serve_goals(self, name: str, definition: ActionType, hooks: GoalServerHooks, owner: str | None,
                    lane: Lane) -> RmwActionServer:
        """A ROS 2 action server for ``name`` on the owner's node (the core runs the goals)."""
        if self._closed:
            raise TransportError(f"serve the action {name!r}: the rmw_zenoh transport is closed")
        return RmwActionServer(self, name, definition, hooks, owner, lane)

    def send_goal(self, name: str, definition: ActionType, goal_id: str, goal: dict[str, Any], events: GoalEvents,
                  timeout: float) -> RmwGoal:
        """Send a goal to the ROS 2 action ``name`` and wait for its acceptance."""
        if self._closed:
            raise TransportError(f"send a goal to {name!r}: the rmw_zenoh transport is closed")
        with self._lock:
            client = self._action_clients.get((name, definition.ros_type))
        if client is None:
            made = RmwActionClient(self, name, definition)
            with self._lock:
                client = self._action_clients.setdefault((name, definition.ros_type), made)
            if client is not made:
                made.close()
        sent = RmwGoal(self, client, goal_id, events)
        try:
            sent.send(goal, timeout)
        except BaseException:
            sent.close()
            raise
        return sent

    def declare_presence(self, name: str, on_transition: TransitionHandler, lane: Lane) -> _Presence:
        return _Presence(self, name, on_transition, lane)

    def read_state(self, name: str, timeout: float) -> ComponentStatusMsg | None:
        deadline = time.monotonic() + timeout
        with self._lock:
            watch = self._status.get(name)
            if watch is None:
                latest = _Latest()
                topic = status_topic(name)
                watch = self._status[name] = (Subscription(self._own, topic, codec_for(ComponentStatus), latest),
                                              latest)
        try:
            request = ros_types().message_class(f"{GET_STATE}_Request")(structure_needs_at_least_one_member=0)
            label = str(self._request(f"{name}/get_state", GET_STATE, request, timeout).current_state.label)
        except (ServiceUnavailableError, RequestTimeoutError):
            return None
        while watch[1].value is None and time.monotonic() < deadline:
            time.sleep(0.01)
        status = watch[1].value
        if status is None:
            return ComponentStatusMsg(component=name, lifecycle_state=label, health="UNKNOWN")
        state = status.lifecycle_state if status.lifecycle_state == "errorprocessing" else label
        return ComponentStatusMsg(component=name, lifecycle_state=state, health=status.health,
                                  message=status.message, header=status.header)

    def request_transition(self, name: str, transition: str, timeout: float) -> bool:
        types = ros_types()
        request = types.message_class(f"{CHANGE_STATE}_Request")(
            transition=types.message_class("lifecycle_msgs/msg/Transition")(id=0, label=transition))
        try:
            response = self._request(f"{name}/change_state", CHANGE_STATE, request, timeout)
        except ServiceUnavailableError:
            raise ServiceUnavailableError(f"no lifecycle node {name!r} on rmw_zenoh") from None
        return bool(response.success)

    def discover(self, timeout: float) -> Graph:
        """Topics and components from the ``@ros2_lv`` tokens seen since the session opened (:mod:`.discovery`)."""
        return graph_of(self._graph.tokens(timeout))

    def peer_process_options(self) -> dict[str, Any]:
        """The same options: every process meets the others through the router."""
        return dict(self.options)

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self._graph.close()
        for sub, _latest in self._status.values():
            sub.close()
        for client in self._clients.values():
            client.close()
        for action_client in self._action_clients.values():
            action_client.close()
        for node in [*self._nodes.values(), self._own]:
            node.close()
        try:
            self._session.close()  # type: ignore[no-untyped-call]
        except zenoh.ZError as exc:
            logger.debug("closing the rmw_zenoh session failed: %s", exc)

    def __repr__(self) -> str:
        return f"<RmwZenohDriver domain={self.domain_id}>"


class RmwZenohTransport(DriverTransport):
    """The core's transport on rmw_zenoh's wire format (options: see the module docstring)."""

    driver: RmwZenohDriver

    def __init__(self, **options: Any) -> None:
        workers = options.get("request_workers")
        super().__init__(RmwZenohDriver(**options), **({"request_workers": workers} if workers else {}))
