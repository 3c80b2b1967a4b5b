"""The executor of :class:`~agents_ros2.transport.Ros2Transport`.

rclpy's single-threaded executor, except that marked services are answered on the core's request lanes.
"""

from __future__ import annotations

import logging
import weakref
from typing import Any

from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor

from agents_core.transport.driver import Lane

__all__ = ["OffloadingExecutor"]

logger = logging.getLogger(__name__)


class OffloadingExecutor(SingleThreadedExecutor):  # type: ignore[misc]  # rclpy is untyped
    """rclpy's single-threaded executor, but marked services are answered on request lanes.

    Messages are handled on the executor thread (converting and queueing them is quick). Service
    requests marked with :meth:`offload` (JsonCall handlers, lifecycle ``change_state``) may run
    for seconds, so the request is taken here and handled, and answered, on the owner's lane.

    Why not rclpy's ``MultiThreadedExecutor``: here (rclpy 7, two cores) it adds ~100 ms to a
    message round trip, against ~0.3 ms for the single-threaded one. Why not async callbacks:
    rclpy re-polls a pending coroutine task in a busy loop.
    """

    def __init__(self, context: Context) -> None:
        super().__init__(context=context)
        self._offloaded: weakref.WeakKeyDictionary[Any, Lane] = weakref.WeakKeyDictionary()

    def offload(self, service: Any, lane: Lane) -> None:
        """Answer ``service``'s requests on ``lane`` (the owner's request lane, the core's) from now on."""
        self._offloaded[service] = lane

    def _take_service(self, srv: Any) -> Any:
        # Overrides the base executor's hook that takes one request and returns the coroutine that
        # serves it; returning None leaves nothing to run on the executor thread.
        lane = self._offloaded.get(srv)
        if lane is None:
            return super()._take_service(srv)
        try:
            with srv.handle:
                request, header = srv.handle.service_take_request(srv.srv_type.Request)
        except Exception as exc:  # the service was destroyed meanwhile
            logger.debug("taking a request of %s: %s", getattr(srv, "srv_name", srv), exc)
            return None
        if header is not None:
            lane(lambda: self._serve(srv, request, header))
        return None

    @staticmethod
    def _serve(srv: Any, request: Any, header: Any) -> None:
        try:
            response = srv.callback(request, srv.srv_type.Response())
            srv.send_response(response, header)
        except Exception:
            logger.exception("serving a request of %s failed", getattr(srv, "srv_name", srv))

    def shutdown(self, timeout_sec: float | None = None) -> bool:
        """Stop the executor (the core shuts the request lanes down)."""
        return bool(super().shutdown(timeout_sec))
