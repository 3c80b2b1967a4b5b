"""The WebSocket streaming flow of a :class:`~agents_core.components.model_component.ModelComponent`.

As the developer docs describe it (architecture.md, "Streaming"): when a component streams
(``config.stream``) through a WebSocket client (``RoboMLWSClient``) and implements
``_handle_websocket_streaming``, its configure sets up

- the *client loop*: a thread that takes each request ``_call_inference`` put in
  ``component.req_queue``, sends it to the model over the client's WebSocket, and puts the
  reply's parts in ``component.resp_queue`` as they come (each token of a streamed answer, or the
  whole output), then :data:`~agents_core.clients.roboml_protocol.RESPONSE_ENDED`;
- the *fast loop*: every millisecond while the component is active, it calls the component's
  ``_handle_websocket_streaming()``, which reads ``resp_queue`` and publishes what it finds.

A request that fails (the server went away, the reply never came within the client's
``inference_timeout``) is reported as an ALGORITHM_FAILURE, so ``on_algorithm_fail`` fallbacks
run, as upstream; nothing is put in ``resp_queue`` for it. Deactivate empties both queues;
cleanup and shutdown stop both loops.
"""

from __future__ import annotations

import logging
import queue
import threading
from collections.abc import Callable
from typing import Any, Protocol

from ..clients.payloads import ChunkStream
from ..clients.roboml_protocol import RESPONSE_ENDED
from ..errors import ModelClientError
from ..status import HealthStatus, LifecycleState

__all__ = ["RESPONSE_ENDED", "StreamingHost", "WebSocketStreaming"]


class StreamingHost(Protocol):
    """What the flow needs of its component (a :class:`~agents_core.components.model_component.ModelComponent`)."""

    component_name: str
    req_queue: queue.Queue[dict[str, Any]]
    resp_queue: queue.Queue[Any]
    model_client: Any
    runtime: Any

    @property
    def lifecycle_state(self) -> LifecycleState:
        """The component's lifecycle state."""
        ...

    @property
    def health_status(self) -> HealthStatus:
        """The component's health."""
        ...

    def get_logger(self) -> logging.Logger:
        """The component's logger."""
        ...

    def run_on_worker(self, func: Callable[[], Any], timeout: float = 30.0) -> Any:
        """Run ``func`` between steps."""
        ...

    def _handle_websocket_streaming(self) -> Any:
        """Publish what ``resp_queue`` holds."""
        ...

#: The fast loop's period (upstream's 1 ms timer).
FAST_LOOP_PERIOD = 0.001
#: How long the client loop waits for a request before looking at its stop flag again.
_REQUEST_POLL = 0.05


class WebSocketStreaming:
    """The two loops of the flow for ``component`` (see the module docstring)."""

    def __init__(self, component: StreamingHost) -> None:
        self._component = component
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        #: Requests served and failed so far.
        self.served = 0
        self.failed = 0

    @property
    def running(self) -> bool:
        """Whether the loops run (set up at configure, stopped at cleanup / shutdown)."""
        return bool(self._threads)

    def start(self) -> None:
        """Start both loops (at configure); nothing if they run already."""
        if self._threads:
            return
        self._stop.clear()
        name = self._component.component_name
        self._threads = [threading.Thread(target=self._client_loop, name=f"ws-client:{name}", daemon=True),
                         threading.Thread(target=self._fast_loop, name=f"ws-stream:{name}", daemon=True)]
        for thread in self._threads:
            thread.start()

    def stop(self, timeout: float = 5.0, wait: bool = True) -> None:
        """Stop both loops and empty the queues (idempotent); ``wait=False``: do not wait for them to end."""
        self._stop.set()
        for thread in self._threads if wait else ():
            if thread is not threading.current_thread():
                thread.join(timeout=timeout)
        self._threads = []
        self.drain()

    def drain(self) -> None:
        """Drop what is left in ``req_queue`` and ``resp_queue`` (at deactivate, as upstream)."""
        for q in (self._component.req_queue, self._component.resp_queue):
            while True:
                try:
                    q.get_nowait()
                except queue.Empty:
                    break

    # -- the loops ------------------------------------------------------------------------------

    def _active(self) -> bool:
        return self._component.lifecycle_state == LifecycleState.ACTIVE

    def _fast_loop(self) -> None:
        c = self._component
        while not self._stop.wait(FAST_LOOP_PERIOD):
            if not self._active():
                continue
            try:
                c._handle_websocket_streaming()
            except Exception:
                c.get_logger().exception("_handle_websocket_streaming raised")

    def _client_loop(self) -> None:
        c = self._component
        while not self._stop.is_set():
            try:
                request = c.req_queue.get(timeout=_REQUEST_POLL)
            except queue.Empty:
                continue
            client = c.model_client
            if client is None:
                c.get_logger().warning("a streaming request was dropped: the component has no model client now")
                continue
            try:
                output = client.inference(request)["output"]
                if isinstance(output, ChunkStream):
                    with output:
                        for chunk in output:
                            c.resp_queue.put(chunk)
                            if self._stop.is_set():
                                break
                else:
                    c.resp_queue.put(output)
                c.resp_queue.put(RESPONSE_ENDED)
            except ModelClientError as exc:
                self.failed += 1
                self._report(exc)
                continue
            self.served += 1
            self._report(None)

    def _report(self, exc: ModelClientError | None) -> None:
        """Health after a request, on the component's worker (between steps), fallbacks included."""
        c = self._component
        health = c.runtime.health

        def update() -> Any:
            if exc is None:
                if c.health_status != HealthStatus.HEALTHY:
                    health.step_succeeded()
                return None
            health.step_failed(HealthStatus.ALGORITHM_FAILURE, exc)
            return None

        try:
            c.run_on_worker(update, timeout=max(float(getattr(c.model_client, "inference_timeout", 30.0)), 30.0))
        except Exception as error:  # the component is going down
            c.get_logger().debug("streaming health not reported: %s", error)
