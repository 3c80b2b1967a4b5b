"""The entities of an rmw_zenoh session: nodes, publishers, subscriptions, service servers and clients.

Each declares its liveliness token (:func:`~agents_zenoh.rmw.wire.entity_token`) and carries its GID
(:func:`~agents_zenoh.rmw.wire.gid_of` of that token) in every attachment it sends.
"""

from __future__ import annotations

import contextlib
import itertools
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import zenoh

from agents_core.errors import TransportError
from agents_core.topics import Topic
from agents_core.transport.driver import Sink

from .codec import RmwCodec
from .typesupport import ros_types
from .wire import Qos, data_key, dds_type_name, decode_attachment, encode_attachment, entity_token, gid_of

if TYPE_CHECKING:
    from .discovery import GraphCache

__all__ = ["Entity", "Node", "Publisher", "ServiceServer", "Subscription", "absolute", "node_name", "qos_of"]


def absolute(name: str) -> str:
    """A core name as a ROS fully qualified name (``camera/image`` -> ``/camera/image``)."""
    return "/" + name.strip("/")


def node_name(full: str) -> tuple[str, str]:
    """A component's wire name as ROS 2's node namespace and name (``robot1/arm`` -> ``("/robot1", "arm")``)."""
    namespace, _, node = full.strip("/").rpartition("/")
    return "/" + namespace, node


def qos_of(topic: Topic) -> Qos:
    """The rmw_zenoh QoS of a topic's :class:`~agents_core.topics.QoSConfig`."""
    q = topic.qos_profile
    return Qos(reliability=1 if q.reliability == "reliable" else 2,
               durability=1 if q.durability == "transient_local" else 2,
               history=2 if q.history == "keep_all" else 1, depth=q.depth)


#: Services' QoS (rclcpp's services default: reliable, volatile, keep last 10).
SERVICE_QOS = Qos(depth=10)


class Node:
    """One ROS 2 node on the session (a component, or the transport's own): ``name`` in ``namespace``."""

    def __init__(self, session: zenoh.Session, domain_id: int, name: str, ids: Callable[[], int],
                 namespace: str = "/", graph: GraphCache | None = None) -> None:
        self.session = session
        self.domain_id = domain_id
        self.name = name
        self.namespace = namespace
        self.zid = str(session.zid())
        self.nid = ids()
        self._ids = ids
        self.graph = graph
        self.token = entity_token(domain_id, self.zid, self.nid, self.nid, "NN", namespace, name)
        self._live = self.declare(self.token)

    def declare(self, token: str) -> Any:
        """Declare liveliness token ``token``, claimed first in the driver's graph (always held there)."""
        if self.graph is not None:
            self.graph.claim(token)
        return self.session.liveliness().declare_token(token)

    def withdraw(self, token: str, handle: Any) -> None:
        """Undeclare a token :meth:`declare` declared."""
        _undeclare(handle)
        if self.graph is not None:
            self.graph.release(token)

    def entity(self, kind: str, name: str, ros_type: str, type_hash: str, qos: Qos) -> Entity:
        """A new entity of this node (its token declared)."""
        return Entity(self, kind, name, ros_type, type_hash, qos)

    def close(self) -> None:
        """Withdraw the node's token."""
        self.withdraw(self.token, self._live)


class Entity:
    """A token, a GID and a sequence counter."""

    def __init__(self, node: Node, kind: str, name: str, ros_type: str, type_hash: str, qos: Qos) -> None:
        self.node = node
        self.key = data_key(node.domain_id, name, ros_type, type_hash)
        self.token = entity_token(node.domain_id, node.zid, node.nid, node._ids(), kind, node.namespace, node.name,
                                  name=name,
                                  ros_type=dds_type_name(ros_type), type_hash=type_hash, qos=qos)
        self.gid = gid_of(self.token)
        self._seq = itertools.count(1)
        self._live = node.declare(self.token)

    def attachment(self) -> bytes:
        """The next attachment: sequence number (from 1), now, this entity's GID."""
        return encode_attachment(next(self._seq), time.time_ns(), self.gid)

    def close(self) -> None:
        """Withdraw the token."""
        self.node.withdraw(self.token, self._live)


def _undeclare(handle: Any) -> None:
    with contextlib.suppress(zenoh.ZError):
        handle.undeclare()


class Publisher:
    """Puts one topic's values as CDR with rmw_zenoh's attachment."""

    def __init__(self, node: Node, topic: Topic, codec: RmwCodec) -> None:
        self._codec = codec
        self._lock = threading.Lock()
        self._buffer: bytearray | None = None
        self._entity = node.entity("MP", absolute(topic.name), codec.ros_type, codec.type_hash, qos_of(topic))
        reliable = topic.qos_profile.reliability == "reliable"
        options: dict[str, Any] = {
            "congestion_control": zenoh.CongestionControl.BLOCK if reliable else zenoh.CongestionControl.DROP,
            "reliability": zenoh.Reliability.RELIABLE if reliable else zenoh.Reliability.BEST_EFFORT}
        self._pub: Any
        if topic.qos_profile.durability == "transient_local":
            self._pub = zenoh.ext.declare_advanced_publisher(
                node.session, self._entity.key, cache=zenoh.ext.CacheConfig(topic.qos_profile.depth),
                publisher_detection=True, **options)
        else:
            self._pub = node.session.declare_publisher(self._entity.key, **options)
        self._deadline = time.monotonic() + 1.0

    @property
    def key(self) -> str:
        """The data key."""
        return self._entity.key

    def send(self, value: Any) -> None:
        """Encode and put ``value``; the first sends wait (up to 1 s) for a subscriber to match.

        The CDR is written into this publisher's buffer, kept from one value to the next (Zenoh copies it on
        ``put``, so it is free again when ``put`` returns)."""
        while self._deadline and time.monotonic() < self._deadline:
            status = getattr(self._pub, "matching_status", True)
            if getattr(status, "matching", status):
                break
            time.sleep(0.002)
        self._deadline = 0.0
        with self._lock:
            self._buffer = payload = self._codec.encode_into(value, self._buffer)
            try:
                self._pub.put(payload, attachment=self._entity.attachment())
            except zenoh.ZError as exc:
                raise TransportError(f"publishing on {self._entity.key!r} failed: {exc}") from exc

    def close(self) -> None:
        """Undeclare publisher and token."""
        self._entity.close()
        _undeclare(self._pub)


class Subscription:
    """Decodes one topic's samples into the core's sink; refuses (counts) foreign types, hashes and attachments."""

    def __init__(self, node: Node, topic: Topic, codec: RmwCodec, sink: Sink) -> None:
        self._codec = codec
        self._sink = sink
        self._closed = False
        self._entity = node.entity("MS", absolute(topic.name), codec.ros_type, codec.type_hash, qos_of(topic))
        self._expected = self._entity.key
        # The whole topic, whatever type and hash: a sample of another one is refused and counted, not unseen.
        wide = f"{node.domain_id}/{topic.name.strip('/')}/*/*"
        self._sub: Any
        if topic.qos_profile.durability == "transient_local":
            history = zenoh.ext.HistoryConfig(detect_late_publishers=True, max_samples=topic.qos_profile.depth)
            self._sub = zenoh.ext.declare_advanced_subscriber(node.session, wide, self._on_sample, history=history)
        else:
            self._sub = node.session.declare_subscriber(wide, self._on_sample)

    def _on_sample(self, sample: zenoh.Sample) -> None:
        if self._closed or sample.kind != zenoh.SampleKind.PUT:
            return
        try:
            key = str(sample.key_expr)
            if key != self._expected:
                raise TransportError(f"sample on {key!r}: not the type and hash this subscription reads "
                                     f"({self._expected.rsplit('/', 2)[-2:]})")
            attachment = sample.attachment
            decode_attachment(attachment.to_bytes() if attachment is not None else None)
            value = self._codec.decode(sample.payload.to_bytes())
        except Exception as exc:
            self._sink.reject(exc)
            return
        self._sink.offer(value)

    def close(self) -> None:
        """Undeclare subscriber and token."""
        self._closed = True
        self._entity.close()
        _undeclare(self._sub)


class ServiceServer:
    """A queryable answering one ROS service: request CDR in, response CDR out, seq and client GID echoed.

    ``serve(request_message, answer)`` is called on Zenoh's thread; it calls ``answer(response_message)``
    (now or later, from any thread) exactly once, or ``answer(None)`` to send no reply.
    """

    def __init__(self, node: Node, name: str, service_type: str,
                 serve: Callable[[Any, Callable[[Any], None]], None], on_refused: Callable[[object], None]) -> None:
        types = ros_types()
        self._types = types
        self._request = f"{service_type}_Request"
        self._response = f"{service_type}_Response"
        types.ensure(service_type)
        self._entity = node.entity("SS", name, service_type, types.type_hash(service_type), SERVICE_QOS)
        self._serve = serve
        self._on_refused = on_refused
        self._queryable = node.session.declare_queryable(self._entity.key, self._on_query, complete=True)

    @property
    def key(self) -> str:
        """The service's key."""
        return self._entity.key

    def _on_query(self, query: zenoh.Query) -> None:
        try:
            raw = query.attachment
            att = decode_attachment(raw.to_bytes() if raw is not None else None)
            payload = query.payload
            request = self._types.deserialize(payload.to_bytes() if payload is not None else b"", self._request)
        except Exception as exc:
            self._on_refused(exc)
            query.drop()  # type: ignore[no-untyped-call]
            return

        def answer(response: Any) -> None:
            try:
                if response is not None:
                    data = self._types.serialize(response, self._response)
                    query.reply(self._entity.key, data,
                                attachment=encode_attachment(att.sequence_number, time.time_ns(), att.gid))
            finally:
                query.drop()  # type: ignore[no-untyped-call]

        try:
            self._serve(request, answer)
        except Exception as exc:  # the handler failed before it took the query: the caller must not wait it out
            self._on_refused(exc)
            query.drop()  # type: ignore[no-untyped-call]

    def close(self) -> None:
        """Undeclare queryable and token."""
        self._entity.close()
        _undeclare(self._queryable)
