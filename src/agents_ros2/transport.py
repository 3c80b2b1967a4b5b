"""The ROS 2 transport: agents_core components as rclpy lifecycle nodes on ROS 2 Jazzy.

``Ros2Transport(**options)`` is the core's :class:`~agents_core.transport.core.DriverTransport`
around :class:`Ros2Driver`, which maps:

* **nodes**: one plain node per transport (for publishers, subscriptions and services that belong
  to no component, and for observer clients), plus one lifecycle node per declared component
  (see :mod:`agents_ros2.lifecycle`); a publisher, subscription or service created with
  ``owner=<component>`` lives on that component's node;
* **one executor** per transport, spun on a background thread: rclpy's single-threaded executor,
  except that service requests (JsonCall handlers, lifecycle ``change_state``) are answered on the
  owner's request lane (the core's), because they may take seconds (a component loading a model
  on configure) and would otherwise stall every subscription of the transport meanwhile;
* **topics**: names as given (relative names are made absolute: ``camera/image`` is
  ``/camera/image``), values converted by :mod:`agents_ros2.conversions`, QoS mapped by
  :mod:`agents_ros2.qos`. Received values go to the core's sink from the executor thread (a
  bounded delivery thread for user callbacks, the component's worker for component inputs). A
  message that cannot be converted is
  counted (``SubscriptionStatistics.decode_errors``), logged once per subscription with the
  reason, and skipped; the subscription keeps serving;
* **request/reply**: services of type ``agents_interfaces/srv/JsonCall`` (JSON text in, JSON text
  or the handler's error out);
* **presence**: lifecycle services of the component's node; the core publishes
  ``/<component>/status`` through a publisher on that node;
* **discovery**: the rclpy graph API (:mod:`agents_ros2.graph`).
* **long-running goals**: a real rclpy action server of the action type's ROS 2 type on the
  owner's node, and rclpy action clients (see :mod:`agents_ros2.goals`).

Options (all keyword): ``domain_id`` (default: ``ROS_DOMAIN_ID``), ``shared_memory`` (the 16 MB
Fast DDS shared-memory profile; default on, ``AGENTS_ROS2_SHM=0`` turns it off),
``executor`` (``"single"`` or ``"events"``), ``executor_threads``,
``reader_depth_floor``, ``first_publish_wait`` and ``node_name``.
"""

from __future__ import annotations

import itertools
import json
import logging
import os
import threading
import time
from typing import TYPE_CHECKING, Any, Literal

import rclpy

from agents_core.errors import TransportNotAvailableError

try:
    from agents_interfaces.srv import JsonCall
except ImportError as _exc:  # rclpy is there (the extra), the interface package is not built yet
    raise TransportNotAvailableError(
        f"the 'ros2' transport needs the agents_interfaces package ({_exc}); with the ros2 extra installed, "
        "build it into this environment with: pip install --no-build-isolation ./interfaces"
    ) from _exc
from lifecycle_msgs.srv import ChangeState, GetState
from rclpy.action import ActionClient
from rclpy.context import Context
from rclpy.exceptions import InvalidHandle
from rclpy.executors import Executor, ExternalShutdownException, ShutdownException
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from agents_core.errors import (
    ConfigError,
    RequestTimeoutError,
    ServiceUnavailableError,
    TransportClosedError,
)
from agents_core.messages import ComponentStatusMsg
from agents_core.support import bounded_json
from agents_core.support.bounded_json import REQUEST_JSON_LIMITS
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
from agents_core.transport.requests import json_call_reply

from .conversions import RosConversion, conversion_for
from .executor import OffloadingExecutor
from .goals import Ros2ActionServer, Ros2Goal, ros_action_class
from .graph import discover_graph
from .lifecycle import STATUS_QOS, ComponentLifecycle, absolute_name
from .qos import (
    READER_DEPTH_FLOOR,
    enable_shared_memory_profile,
    publisher_qos,
    shared_memory_wanted,
    subscription_qos,
)

if TYPE_CHECKING:
    from rclpy.client import Client
    from rclpy.task import Future

__all__ = ["Ros2Driver", "Ros2Transport"]

logger = logging.getLogger(__name__)

ExecutorKind = Literal["single", "events"]

_transport_ids = itertools.count()
#: How often a waiting request checks whether its server has been discovered.
_DISCOVERY_POLL_S = 0.02
#: Health reported for a lifecycle node that has published no ComponentStatus (not ours, or not yet).
UNKNOWN_HEALTH = "UNKNOWN"

def _destroy(destroy: Any, entity: Any, what: str) -> None:
    """Destroy an rclpy entity, tolerating a node that is already gone."""
    try:
        destroy(entity)
    except Exception as exc:  # the node is already gone
        logger.debug("destroying %s: %s", what, exc)


class _Ros2Publisher:
    """Publishes one topic's values as ROS messages."""

    def __init__(self, topic: Topic, node: Node, conversion: RosConversion, publisher: Any,
                 first_publish_wait: float = 0.0) -> None:
        self.topic = topic
        self._first_publish_wait = first_publish_wait
        self._node = node
        self._conversion = conversion
        self._publisher = publisher
        self._closed = False

    def send(self, value: Any) -> None:
        """Convert and send ``value`` (validated by the core)."""
        if self._closed:
            raise TransportClosedError(f"publisher on {self.topic.name!r} is closed")
        message = self._conversion.to_ros(value)
        if self._first_publish_wait > 0:
            self._wait_for_match()
        try:
            self._publisher.publish(message)
        except InvalidHandle as exc:
            # Its node was destroyed (transport closed, or the owning component withdrawn).
            raise TransportClosedError(f"publisher on {self.topic.name!r} is closed") from exc

    def _wait_for_match(self) -> None:
        # DDS matches a new writer with existing readers asynchronously, and a reliable writer
        # drops what it publishes before that. Waiting (once, bounded) on the first publish makes
        # "create a publisher, publish" reach subscriptions that already exist.
        deadline = time.monotonic() + self._first_publish_wait
        self._first_publish_wait = 0.0
        while self._publisher.get_subscription_count() == 0 and time.monotonic() < deadline:
            time.sleep(_DISCOVERY_POLL_S / 2)

    def close(self) -> None:
        """Stop publishing; idempotent."""
        if not self._closed:
            self._closed = True
            _destroy(self._node.destroy_publisher, self._publisher, f"the publisher on {self.topic.name!r}")


class _Ros2Subscription:
    """Converts received ROS messages on the executor thread and hands them to the core's sink."""

    def __init__(self, topic: Topic, sink: Sink, node: Node, depth_floor: int) -> None:
        self.topic = topic
        self._node = node
        self._conversion = conversion_for(topic.msg_type)
        self._delivery = sink
        self._lock = threading.Lock()
        self._closed = False
        self._subscription = node.create_subscription(
            self._conversion.ros_type, absolute_name(topic.name), self._on_message,
            subscription_qos(topic.qos_profile, depth_floor))

    def _on_message(self, message: Any) -> None:
        try:
            value = self.topic.msg_type.validate(self._conversion.from_ros(message))
        except Exception as exc:
            self._delivery.reject(exc)
            return
        self._delivery.offer(value)
        # Let the thread the value went to (a component's worker, a delivery thread) take the GIL
        # now: otherwise it waits until this executor thread, back in spin_once, has rebuilt its
        # wait set in Python (~100 µs here), which was most of what a ROS 2 hop added.
        time.sleep(0)

    def close(self) -> None:
        """Stop receiving. Idempotent."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
        _destroy(self._node.destroy_subscription, self._subscription, f"the subscription on {self.topic.name!r}")


class _Ros2Service:
    """Serves ``JsonCall`` requests on one name with a JSON-dict handler."""

    def __init__(self, transport: Ros2Driver, name: str, handler: ServiceHandler, node: Node, lane: Lane) -> None:
        self.name = name
        self._handler = handler
        self._node = node
        self._closed = False
        self._service = node.create_service(JsonCall, absolute_name(name), self._serve)
        transport._offload(self._service, lane)

    def _serve(self, request: Any, response: Any) -> Any:
        try:
            payload = bounded_json.loads(request.request_json or "{}", REQUEST_JSON_LIMITS)
            if not isinstance(payload, dict):
                raise ConfigError(f"a request must be a JSON object, got {type(payload).__name__}")
            response.response_json = json.dumps(self._handler(payload))
            response.success = True
        except Exception as exc:
            response.success = False
            response.error = f"{type(exc).__name__}: {exc}"
        return response

    def close(self) -> None:
        """Stop serving; idempotent."""
        if not self._closed:
            self._closed = True
            _destroy(self._node.destroy_service, self._service, f"the service {self.name!r}")


class Ros2Driver(DriverBase):
    """The rclpy primitives under :class:`Ros2Transport` (options: see :class:`Ros2Transport`)."""

    name = "ros2"
    cross_process = True
    #: Each received value is validated as it is decoded (the codec / the conversion calls ``validate``).
    validates_incoming = True
    # DDS takes up to ~2 s to show a new participant the graph.
    discovery_settle_s = 4.0

    def __init__(self, *, domain_id: int | None = None, shared_memory: bool | None = None,
                 executor: ExecutorKind = "single", reader_depth_floor: int = READER_DEPTH_FLOOR,
                 first_publish_wait: float = 0.5, node_name: str | None = None) -> None:
        if executor not in ("single", "events"):
            raise ConfigError(f"executor must be 'single' or 'events', got {executor!r}")
        #: Whether large messages between processes on this host go through shared memory.
        self.shared_memory = shared_memory_wanted(shared_memory) and enable_shared_memory_profile()
        self._reader_depth_floor = reader_depth_floor
        self._first_publish_wait = first_publish_wait
        self._lock = threading.RLock()
        self._closed = False
        self._components: dict[str, ComponentLifecycle] = {}
        self._clients: dict[tuple[str, str], Client] = {}
        self._action_clients: dict[tuple[str, str], ActionClient] = {}
        self._status_watches: dict[str, Any] = {}
        self._latest_status: dict[str, ComponentStatusMsg] = {}
        self._context = Context()
        # Signals belong to the application (the Launcher handles SIGINT / SIGTERM), not to rclpy.
        rclpy.init(context=self._context, domain_id=domain_id, signal_handler_options=SignalHandlerOptions.NO)
        try:
            self.node = Node(node_name or f"agents_{os.getpid()}_{next(_transport_ids)}", context=self._context,
                             enable_rosout=False, start_parameter_services=False)
            self._executor: Executor = (OffloadingExecutor(self._context) if executor == "single"
                                        else EventsExecutor(context=self._context))
            self._executor.add_node(self.node)
        except BaseException:
            self._context.try_shutdown()
            raise
        self._stop = threading.Event()
        self._spin_thread = threading.Thread(target=self._spin, name=f"ros2-executor:{self.node.get_name()}",
                                             daemon=True)
        self._spin_thread.start()

    def _offload(self, service: Any, lane: Lane) -> None:
        if isinstance(self._executor, OffloadingExecutor):
            self._executor.offload(service, lane)

    def _spin(self) -> None:
        while not self._stop.is_set():
            try:
                self._executor.spin_once(timeout_sec=0.25)
            except (ExternalShutdownException, ShutdownException):
                return
            except Exception:
                # A raising callback must not end message handling for the whole transport.
                if self._stop.is_set():
                    return
                logger.exception("a ROS 2 callback raised; the executor keeps running")

    # -- helpers ----------------------------------------------------------------------------

    def _check_open(self) -> None:
        if self._closed:
            raise TransportClosedError("the ros2 transport is closed")

    def _node_for(self, owner: str | None) -> Node:
        if owner is not None:
            presence = self._components.get(owner)
            if presence is not None:
                return presence.node
        return self.node

    def _client(self, srv_type: Any, name: str) -> Client:
        key = (srv_type.__name__, name)
        with self._lock:
            client = self._clients.get(key)
            if client is None:
                # Clients are kept: a new one has to be discovered by its server before it works.
                client = self.node.create_client(srv_type, name)
                self._clients[key] = client
            return client

    def _wait_for_server(self, client: Client, deadline: float) -> bool:
        while not client.service_is_ready():
            if time.monotonic() >= deadline or self._closed:
                return bool(client.service_is_ready())
            time.sleep(_DISCOVERY_POLL_S)
        return True

    def _call(self, client: Client, request: Any, deadline: float, what: str) -> Any:
        future: Future = client.call_async(request)
        done = threading.Event()
        future.add_done_callback(lambda _f: done.set())
        if not done.wait(max(0.0, deadline - time.monotonic())):
            client.remove_pending_request(future)
            raise RequestTimeoutError(f"{what} got no reply in time")
        return future.result()

    # -- primitives -------------------------------------------------------------------------

    def open_publisher(self, topic: Topic, owner: str | None) -> _Ros2Publisher:
        """A publisher for ``topic`` on the owner's node (or the transport's)."""
        with self._lock:
            conversion = conversion_for(topic.msg_type)
            node = self._node_for(owner)
            rclpy_publisher = node.create_publisher(conversion.ros_type, absolute_name(topic.name),
                                                    publisher_qos(topic.qos_profile))
            # A transient_local topic replays to late joiners: nothing is lost to discovery, no wait.
            wait = 0.0 if topic.qos_profile.durability == "transient_local" else self._first_publish_wait
            return _Ros2Publisher(topic, node, conversion, rclpy_publisher, first_publish_wait=wait)

    def open_subscriber(self, topic: Topic, sink: Sink, owner: str | None) -> _Ros2Subscription:
        """Convert ``topic``'s messages on the executor thread into ``sink``."""
        with self._lock:
            return _Ros2Subscription(topic, sink, self._node_for(owner), self._reader_depth_floor)

    def serve(self, name: str, handler: ServiceHandler, owner: str | None, lane: Lane) -> _Ros2Service:
        """Serve ``JsonCall`` requests on ``name`` with ``handler``, on ``lane``."""
        with self._lock:
            return _Ros2Service(self, name, handler, self._node_for(owner), lane)

    def call(self, name: str, payload: dict[str, Any], timeout: float) -> dict[str, Any]:
        """Send ``payload`` to the service ``name`` and return its reply (see the contract for errors)."""
        body = json.dumps(payload)
        deadline = time.monotonic() + timeout
        client = self._client(JsonCall, absolute_name(name))
        if not self._wait_for_server(client, deadline):
            self._check_open()
            raise ServiceUnavailableError(f"no server for service {name!r} appeared within {timeout:g} s")
        try:
            response = self._call(client, JsonCall.Request(request_json=body), deadline, f"request to {name!r}")
        except RequestTimeoutError:
            raise RequestTimeoutError(f"request to {name!r} got no reply within {timeout:g} s") from None
        return json_call_reply(name, response.success, response.error, response.response_json)

    def serve_goals(self, name: str, definition: ActionType, hooks: GoalServerHooks, owner: str | None,
                    lane: Lane) -> Ros2ActionServer:
        """A real rclpy action server for ``name`` on the owner's node (the core runs the goals)."""
        with self._lock:
            self._check_open()
            return Ros2ActionServer(self._node_for(owner), name, definition, hooks, absolute_name(name))

    def send_goal(self, name: str, definition: ActionType, goal_id: str, goal: dict[str, Any], events: GoalEvents,
                  timeout: float) -> Ros2Goal:
        """Send a goal through an rclpy action client (kept per action name and type)."""
        key = (definition.ros_type, absolute_name(name))
        with self._lock:
            self._check_open()
            client = self._action_clients.get(key)
            if client is None:
                client = ActionClient(self.node, ros_action_class(definition), key[1])
                self._action_clients[key] = client
        sent = Ros2Goal(client, name, definition, goal_id, events)
        sent.send(goal, timeout)
        return sent

    def declare_presence(self, name: str, on_transition: TransitionHandler, lane: Lane) -> ComponentLifecycle:
        """Create the component's lifecycle node; outside change_state requests run ``on_transition`` on ``lane``."""
        with self._lock:
            presence = ComponentLifecycle(name, self._context, on_transition, self._forget_component)
            self._components[name] = presence
            self._offload(presence.node._service_change_state, lane)
            self._executor.add_node(presence.node)
            return presence

    def _forget_component(self, presence: ComponentLifecycle) -> None:
        with self._lock:
            if self._components.get(presence.name) is presence:
                del self._components[presence.name]
        self._executor.remove_node(presence.node)

    def _watch_status(self, name: str) -> None:
        with self._lock:
            if name in self._status_watches:
                return
            conversion = conversion_for(ComponentStatus)

            def on_status(message: Any) -> None:
                try:
                    value = conversion.from_ros(message)
                except Exception as exc:
                    logger.debug("unreadable status of %r: %s", name, exc)
                    return
                with self._lock:
                    self._latest_status[name] = value

            self._status_watches[name] = self.node.create_subscription(
                conversion.ros_type, absolute_name(f"{name}/status"), on_status, STATUS_QOS)

    def read_state(self, name: str, timeout: float) -> ComponentStatusMsg | None:
        """The lifecycle state via ``get_state``, the health from ``<name>/status``."""
        deadline = time.monotonic() + timeout
        self._watch_status(name)
        client = self._client(GetState, absolute_name(f"{name}/get_state"))
        if not self._wait_for_server(client, deadline):
            return None
        try:
            label = self._call(client, GetState.Request(), deadline, f"get_state of {name!r}").current_state.label
        except RequestTimeoutError:
            return None  # the node went away between discovery and the call
        status = self._latest_status.get(name)
        while status is None and time.monotonic() < deadline:
            time.sleep(_DISCOVERY_POLL_S)
            status = self._latest_status.get(name)
        if status is None:
            return ComponentStatusMsg(component=name, lifecycle_state=label, health=UNKNOWN_HEALTH)
        # The component's own view wins where ROS has no resting state for it (errorprocessing).
        state = status.lifecycle_state if status.lifecycle_state == "errorprocessing" else label
        return ComponentStatusMsg(component=name, lifecycle_state=state, health=status.health,
                                  message=status.message, header=status.header)

    def request_transition(self, name: str, transition: str, timeout: float) -> bool:
        """The transition via the lifecycle node's ``change_state`` service."""
        deadline = time.monotonic() + timeout
        client = self._client(ChangeState, absolute_name(f"{name}/change_state"))
        if not self._wait_for_server(client, deadline):
            self._check_open()
            raise ServiceUnavailableError(f"no lifecycle node {name!r} appeared within {timeout:g} s")
        request = ChangeState.Request()
        request.transition.label = transition
        try:
            response = self._call(client, request, deadline, f"{transition} of {name!r}")
        except RequestTimeoutError:
            raise RequestTimeoutError(f"{transition} of {name!r} got no reply within {timeout:g} s") from None
        return bool(response.success)

    def discover(self, timeout: float) -> Graph:
        """The ROS graph (plain ROS nodes' topics too) as this transport's node sees it (:mod:`agents_ros2.graph`)."""
        self._check_open()
        return discover_graph(self.node, timeout)

    def close(self) -> None:
        """Destroy the remaining component nodes, stop the executor, release the ROS context."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            components = list(self._components.values())
        for presence in components:
            presence.close()
        self._stop.set()
        self._executor.shutdown(timeout_sec=2.0)
        self._spin_thread.join(timeout=5.0)
        try:
            self.node.destroy_node()
        finally:
            self._context.try_shutdown()

    def __repr__(self) -> str:
        return f"<Ros2Driver node={self.node.get_name()!r}>"


class Ros2Transport(DriverTransport):
    """A transport on ROS 2 (rclpy, Fast DDS): a :class:`DriverTransport` around a :class:`Ros2Driver`.

    See the module docstring for what maps to what.

    :param domain_id: ROS domain id; None reads ``ROS_DOMAIN_ID`` (default 0).
    :param shared_memory: use the 16 MB Fast DDS shared-memory profile for large messages between
        processes on one host; None reads ``AGENTS_ROS2_SHM`` (default on). Fast DDS reads its
        profile once per process, so the first transport of a process decides.
    :param executor: ``"single"`` (default: rclpy's single-threaded executor, service requests
        answered on the owner's request lane) or ``"events"`` (rclpy's experimental
        EventsExecutor: lower latency, but service handlers and lifecycle transitions run on its
        one thread, so a slow one stalls message handling meanwhile).
    :param executor_threads: threads answering requests to services that belong to no component
        (each component's requests have a lane of their own).
    :param reader_depth_floor: smallest DDS history of a subscription (see :mod:`agents_ros2.qos`).
    :param first_publish_wait: on its first publish, a publisher that has matched no subscription
        yet waits up to this many seconds for discovery (0 turns it off), so a value published
        right after the publisher is created reaches subscriptions that already exist.
    :param node_name: name of the transport's own node (default ``agents_<pid>_<n>``).
    """

    driver: Ros2Driver

    def __init__(self, *, domain_id: int | None = None, shared_memory: bool | None = None,
                 executor: ExecutorKind = "single", executor_threads: int = 4,
                 reader_depth_floor: int = READER_DEPTH_FLOOR, first_publish_wait: float = 0.5,
                 node_name: str | None = None) -> None:
        if isinstance(executor_threads, bool) or not isinstance(executor_threads, int) or executor_threads < 1:
            raise ConfigError(f"executor_threads must be an int of at least 1, got {executor_threads!r}")
        driver = Ros2Driver(domain_id=domain_id, shared_memory=shared_memory, executor=executor,
                             reader_depth_floor=reader_depth_floor, first_publish_wait=first_publish_wait,
                             node_name=node_name)
        super().__init__(driver, request_workers=executor_threads)
