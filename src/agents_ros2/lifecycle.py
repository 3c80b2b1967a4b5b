"""Components as ROS 2 lifecycle nodes.

Each declared component is an ``rclpy`` lifecycle node named after it (``"arm/planner"`` becomes
node ``planner`` in namespace ``/arm``), so ``ros2 lifecycle get/set`` and any ``lifecycle_msgs``
client see and drive it through the standard services (``~/get_state``, ``~/change_state``,
``~/get_available_states``, ``~/get_available_transitions``, ``~/get_transition_graph``) and the
``~/transition_event`` topic.

Two directions keep the node's state machine and the component's state in step:

* **from outside** (a ``change_state`` request, answered on the transport's service pool so that a
  slow transition does not stall message handling): the node's transition callback calls the
  component's ``on_transition(name)``; its True / False becomes ``SUCCESS`` / ``FAILURE``, so the
  node lands in the goal state or returns to where it was, exactly as a ROS user expects;
* **from the component** (:meth:`ComponentLifecycle.update`, called by the runtime after each
  transition it runs itself): the node is walked to the same state with internal transitions that
  do *not* call back into the component.

The core's ``errorprocessing`` state has no resting counterpart in the ROS 2 state machine (there
it is a transition state), so an errored component leaves its node where the failed transition
left it; the health on ``<component>/status`` then says ``errorprocessing``.

Health: the core publishes the component's :class:`~agents_interfaces.msg.ComponentStatus`
(reliable, transient local) on ``/<component>/status``, through a publisher on this node.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from typing import Any

import lifecycle_msgs.srv
from rclpy.context import Context
from rclpy.lifecycle import LifecycleNodeMixin, TransitionCallbackReturn
from rclpy.lifecycle.node import LifecycleState as RosLifecycleState
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from agents_core.status import HealthStatus, LifecycleState
from agents_core.transport.contract import TransitionHandler

__all__ = ["STATUS_QOS", "ComponentLifecycle", "absolute_name", "split_node_name"]

logger = logging.getLogger(__name__)

#: QoS of ``<component>/status``: what the core's runtime declares for its status topic
#: (reliable, transient local, 5 deep), so a late observer gets the current status at once.
STATUS_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=5, reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL)

_ROS_STATE = {
    LifecycleState.UNCONFIGURED: "unconfigured",
    LifecycleState.INACTIVE: "inactive",
    LifecycleState.ACTIVE: "active",
    LifecycleState.FINALIZED: "finalized",
}

#: Delay before a node whose component shut down from inside its own change_state request is
#: destroyed: the executor still has to send that request's reply through the node.
_DEFERRED_DESTROY_S = 0.5


def absolute_name(name: str) -> str:
    """A core topic / service / component name as an absolute ROS name (``a/b`` -> ``/a/b``)."""
    return name if name.startswith("/") else f"/{name}"


def split_node_name(component: str) -> tuple[str, str]:
    """``"arm/planner"`` -> (``"/arm"``, ``"planner"``): ROS node names cannot contain slashes."""
    full = absolute_name(component)
    namespace, _, node_name = full.rpartition("/")
    return namespace or "/", node_name


class _ComponentNode(LifecycleNodeMixin, Node):  # type: ignore[misc]  # rclpy is untyped
    """A lifecycle node whose transition callbacks are routed to its :class:`ComponentLifecycle`."""

    def __init__(self, component: str, context: Context, on_callback: Callable[[str], Any]) -> None:
        namespace, node_name = split_node_name(component)
        Node.__init__(self, node_name, namespace=namespace, context=context, enable_rosout=False,
                      start_parameter_services=False)
        self._on_callback = on_callback
        LifecycleNodeMixin.__init__(self, enable_communication_interface=True)

    def on_configure(self, state: RosLifecycleState) -> Any:
        return self._on_callback("configure")

    def on_activate(self, state: RosLifecycleState) -> Any:
        return self._on_callback("activate")

    def on_deactivate(self, state: RosLifecycleState) -> Any:
        return self._on_callback("deactivate")

    def on_cleanup(self, state: RosLifecycleState) -> Any:
        return self._on_callback("cleanup")

    def on_shutdown(self, state: RosLifecycleState) -> Any:
        return self._on_callback("shutdown")

    def on_error(self, state: RosLifecycleState) -> Any:
        # Reached only if a callback raised past our guard; SUCCESS returns the node to unconfigured.
        return TransitionCallbackReturn.SUCCESS

    def current_state_label(self) -> str:
        # rclpy offers no public getter; its own get_state service reads the same attribute.
        return str(self._state_machine.current_state[1])


class ComponentLifecycle:
    """A component's presence on ROS 2: its lifecycle node and its status publisher.

    Implements :class:`~agents_core.transport.driver.DriverPresence`. Created by
    :meth:`agents_ros2.transport.Ros2Driver.declare_presence`.
    """

    def __init__(self, name: str, context: Context, on_transition: TransitionHandler,
                 on_close: Callable[[ComponentLifecycle], None]) -> None:
        self.name = name
        self._on_transition = on_transition
        self._on_close = on_close
        self.node = _ComponentNode(name, context, self._transition_callback)
        # _machine_lock serialises every use of the node's state machine (outside requests and
        # internal syncs); _state_lock guards the small fields below and is never held while
        # calling out, so update() can never block on a transition in progress.
        self._machine_lock = threading.Lock()
        self._state_lock = threading.Lock()
        self._external = False
        self._external_thread: int | None = None
        self._reported_during_external = False
        self._pending: LifecycleState | None = None
        self._closed = False
        service = self.node._service_change_state
        service.callback = self._serve_change_state(service.callback)

    # -- ComponentPresence ------------------------------------------------------------------

    def update(self, state: LifecycleState, health: HealthStatus, message: str = "") -> None:
        """Bring the lifecycle node to ``state`` (the core publishes the status topic)."""
        with self._state_lock:
            if self._closed:
                return
            self._pending = state
            if self._external:
                self._reported_during_external = True
        self._sync()

    def close(self) -> None:
        """Withdraw the component: its node (and services, status publisher) is destroyed."""
        with self._state_lock:
            if self._closed:
                return
            self._closed = True
            inside_own_request = self._external and self._external_thread == threading.get_ident()
        self._on_close(self)
        if inside_own_request:
            # The component shut down from inside a change_state request to this very node: the
            # executor sends the reply through the node after this callback returns.
            timer = threading.Timer(_DEFERRED_DESTROY_S, self._destroy)
            timer.daemon = True
            timer.start()
        else:
            self._destroy()

    @property
    def closed(self) -> bool:
        """Whether :meth:`close` ran."""
        return self._closed

    def _destroy(self) -> None:
        try:
            self.node.destroy_node()
        except Exception as exc:  # destroying twice or after the context shut down
            logger.debug("destroying the node of %r: %s", self.name, exc)

    # -- outside requests -------------------------------------------------------------------

    def _serve_change_state(self, original: Callable[[Any, Any], Any]) -> Callable[[Any, Any], Any]:
        def serve(request: lifecycle_msgs.srv.ChangeState.Request,
                  response: lifecycle_msgs.srv.ChangeState.Response) -> Any:
            with self._machine_lock:
                with self._state_lock:
                    self._external, self._external_thread = True, threading.get_ident()
                    # A state reported just before this request took the machine is still owed.
                    self._reported_during_external = self._pending is not None
                try:
                    result = original(request, response)
                except Exception as exc:
                    # rclpy raises for a transition that is not available from the current state;
                    # for the caller that is a plain "not done".
                    logger.info("lifecycle request %r to %r refused: %s",
                                request.transition.label or request.transition.id, self.name, exc)
                    response.success = False
                    result = response
                finally:
                    with self._state_lock:
                        self._external, self._external_thread = False, None
                        if not self._reported_during_external:
                            # The handler accepted (or refused) without reporting a state: the
                            # node's outcome stands and nothing is left to sync.
                            self._pending = None
            # A state the component reported during the request (e.g. errorprocessing, or a
            # report racing with it) may still differ from where the node landed.
            self._sync()
            return result

        return serve

    def _transition_callback(self, transition: str) -> Any:
        if not self._external:
            # An internal sync: the component already is in the target state.
            return TransitionCallbackReturn.SUCCESS
        try:
            accepted = bool(self._on_transition(transition))
        except Exception:
            logger.exception("transition %r of %r raised", transition, self.name)
            accepted = False
        return TransitionCallbackReturn.SUCCESS if accepted else TransitionCallbackReturn.FAILURE

    # -- syncing the node to the component --------------------------------------------------

    def _sync(self) -> None:
        while True:
            if not self._machine_lock.acquire(blocking=False):
                # Whoever holds it re-checks _pending after releasing it.
                return
            try:
                with self._state_lock:
                    target, self._pending = self._pending, None
                    closed = self._closed
                if target is not None and not closed:
                    self._walk_to(target)
            finally:
                self._machine_lock.release()
            if not self._owes_sync():
                return

    def _owes_sync(self) -> bool:
        with self._state_lock:
            return self._pending is not None and not self._closed

    def _walk_to(self, target: LifecycleState) -> None:
        goal = _ROS_STATE.get(target)
        if goal is None:
            return  # errorprocessing: no resting ROS state (see the module docstring)
        node = self.node
        for _ in range(4):  # at most: deactivate, cleanup, shutdown -- bounded in any case
            current = node.current_state_label()
            if current in (goal, "finalized"):
                return
            try:
                if goal == "finalized":
                    node.trigger_shutdown()
                elif current == "unconfigured":
                    node.trigger_configure()
                elif current == "inactive":
                    node.trigger_activate() if goal == "active" else node.trigger_cleanup()
                elif current == "active":
                    node.trigger_deactivate()
                else:
                    return
            except Exception as exc:
                logger.warning("could not bring the lifecycle node of %r from %s to %s: %s", self.name,
                               current, goal, exc)
                return

