"""``ModelComponent``: a component that calls a model through a client or a built-in local model.

Subclasses implement ``_execution_step``, ``_create_input``, ``_warmup`` and
``_handle_websocket_streaming``, and declare ``self.handled_outputs`` (the output types they can
produce) before ``super().__init__``.

Configure connects the client (``check_connection``, then ``initialize`` when
``init_on_activation``) or deploys the local model, then warms up if ``config.warmup``.

Which failure is which (as upstream's ``model_component.py`` and its ``model_client_fallback``
recipe):

- the model setup failing at configure (the server is down, the model does not load) is a
  COMPONENT_FAILURE: the ``on_component_fail`` / ``on_fail`` fallbacks run (``change_model_client``,
  ``fallback_to_local``, ...) and the setup is tried again with what they switched to. When nothing
  works the component still comes up, unhealthy, says so in one WARNING line, and each step tries
  the setup again. A database (``db_client``) that cannot be reached at configure is the same: the
  component comes up unhealthy and each use of the database (RAG, ``add_documents``) connects first;
- an inference that fails (an error answer, a timeout, an unreadable or empty answer) is an
  ALGORITHM_FAILURE, so ``on_algorithm_fail`` chains fire; a client that cannot reach its server
  at all (:class:`~agents_core.errors.ClientConnectionError`) and a component with neither a client
  nor a local model are COMPONENT_FAILURE (see
  :func:`~agents_core.runtime.component_runtime.is_algorithm_failure`).

A subclass that does not implement ``_create_input`` never builds a model input, so it may exist
without a client (upstream's ``SecurityCamera`` example); one that does needs a client or
``config.enable_local_model``.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable, Mapping, MutableMapping, Sequence
from typing import Any, cast

from ..actions import component_fallback
from ..clients.db_base import DBClient
from ..clients.model_base import ModelClient
from ..config import ModelComponentConfig
from ..errors import ComponentError, InferenceError, ModelClientError, RequestTimeoutError, WiringError
from ..runtime.run_type import ComponentRunType
from ..runtime.worker import control_deadline_passed
from ..status import HealthStatus
from ..supported_types import SupportedType
from ..topics import Topic
from .component_base import Component, TriggerType
from .ws_streaming import WebSocketStreaming

__all__ = ["ModelComponent"]

#: How many times configure tries the model setup, fallbacks in between, before it gives up.
_MAX_SETUP_ATTEMPTS = 5
#: The hooks a model-calling subclass must implement (checked at construction).
_MODEL_HOOKS = ("_execution_step", "_create_input", "_warmup")
#: A timer faster than this on a model component gets a warning at construction (the float trigger).
_MODEL_CALLS_PER_SECOND_WARNING = 1.0


class ModelComponent(Component):
    """A component whose steps call a model.

    :param model_client: the client to call (None with ``config.enable_local_model``).
    :param additional_model_clients: other clients by name, for :meth:`change_model_client`.
    Other parameters as :class:`~agents_core.components.component_base.Component`.
    """

    config_class = ModelComponentConfig
    #: The output types this component can produce (every output topic must be one of them).
    handled_outputs: Sequence[type[SupportedType]] = ()
    #: Whether an output of another type is allowed when a publisher pre-processor turns the
    #: component's output into it (checked at configure: the pre-processor is added after
    #: construction). False: such an output is refused at construction.
    converts_outputs_with_preprocessor: bool = False

    def __init__(
        self,
        inputs: Sequence[Topic] | None = None,
        outputs: Sequence[Topic] | None = None,
        model_client: ModelClient | None = None,
        config: ModelComponentConfig | None = None,
        trigger: TriggerType = 1.0,
        component_name: str = "model_component",
        additional_model_clients: Mapping[str, ModelClient] | None = None,
        db_client: DBClient | None = None,
        **kwargs: Any,
    ) -> None:
        super().__init__(inputs=inputs, outputs=outputs, config=config, trigger=trigger,
                         component_name=component_name, **kwargs)
        self.config: ModelComponentConfig
        self._check_model_hooks(model_client)
        if db_client is not None and not isinstance(db_client, DBClient):
            raise WiringError(f"component {self.component_name!r}: db_client must be a DBClient, "
                              f"got {type(db_client).__name__}")
        #: The vector database client, for components that use one (RAG, routing, maps).
        self.db_client = db_client
        if model_client is not None and not isinstance(model_client, ModelClient):
            raise WiringError(f"component {self.component_name!r}: model_client must be a ModelClient, "
                              f"got {type(model_client).__name__}")
        if model_client is None and not self.config.enable_local_model and not self._runs_without_model():
            raise WiringError(f"component {self.component_name!r} needs a model_client, or "
                              "config.enable_local_model=True to use the built-in local model")
        self.model_client = model_client
        self.additional_model_clients: dict[str, ModelClient] = dict(additional_model_clients or {})
        for key, client in self.additional_model_clients.items():
            if not isinstance(client, ModelClient):
                raise WiringError(f"component {self.component_name!r}: additional model client {key!r} "
                                  f"is a {type(client).__name__}, not a ModelClient")
        self._validate_handled_outputs()
        self._warn_fast_timer()
        # The client whose setup (check_connection, initialize) has succeeded; a step sets up a
        # client that is not it first (the setup failed at configure, the server may be back).
        self._ready_client: ModelClient | None = None
        # Whether the database client's setup has succeeded (the same for the database: see _ensure_db_ready).
        self._db_ready = False
        # Held while the database's setup is checked and done: a step's RAG and add_documents (an action's or
        # a service's thread) must not both set it up.
        self._db_lock = threading.Lock()
        self.local_model: Callable[..., Any] | None = None
        #: The WebSocket streaming flow's queues (architecture.md, "Streaming"): ``_call_inference``
        #: puts requests in ``req_queue``; the reply's parts arrive in ``resp_queue``.
        self.req_queue: queue.Queue[dict[str, Any]] = queue.Queue()
        self.resp_queue: queue.Queue[Any] = queue.Queue()
        self._ws_streaming = WebSocketStreaming(self)

    def _check_model_hooks(self, model_client: ModelClient | None) -> None:
        """A TypeError at construction naming the hooks a model-calling subclass has not implemented.

        A subclass that never calls a model (no client, no local model, no ``_create_input``:
        upstream's ``SecurityCamera``) needs only ``_execution_step``.
        """
        calls_model = model_client is not None or self.config.enable_local_model or not self._runs_without_model()
        hooks = _MODEL_HOOKS if calls_model else _MODEL_HOOKS[:1]
        cls = type(self)
        missing = [name for name in hooks
                   if getattr(cls, name) is getattr(Component if name == "_execution_step" else ModelComponent, name)]
        # A hook still marked @abstractmethod (as in custom_component.md's outline) is not implemented either.
        missing += [name for name in (*_MODEL_HOOKS, "_handle_websocket_streaming")
                    if name not in missing and getattr(getattr(cls, name), "__isabstractmethod__", False)]
        if missing:
            raise TypeError(f"{cls.__name__} (component {self.component_name!r}) must implement "
                            f"{', '.join(missing)}: every ModelComponent subclass that calls a model implements "
                            f"{', '.join(_MODEL_HOOKS)}")

    def _runs_without_model(self) -> bool:
        """Whether this component can work with neither a client nor a local model.

        By default: when its class does not implement ``_create_input``, so never calls a model
        (upstream's ``SecurityCamera``). Subclasses that can otherwise (a router in vector mode)
        override it.
        """
        return type(self)._create_input is ModelComponent._create_input

    def _warn_fast_timer(self) -> None:
        trigger = self.trigger
        if (self.run_type == ComponentRunType.TIMED and isinstance(trigger, int | float)
                and trigger > _MODEL_CALLS_PER_SECOND_WARNING):
            # Upstream's code reads a float trigger as a period in seconds, and its recipes are
            # written that way; here (and in the spec) it is a rate.
            self._logger.warning("component %r: trigger=%g means %g Hz here (%g model calls a second); upstream "
                                 "recipes meant every %g s: use trigger=1/%g", self.component_name, trigger,
                                 trigger, trigger, trigger, trigger)

    def _unhandled_outputs(self) -> list[Topic]:
        return [t for t in self.outputs if not any(issubclass(t.msg_type, h) for h in self.handled_outputs)]

    def _check_outputs_converted(self) -> None:
        """At configure: every output the component cannot produce itself has a pre-processor."""
        if not self.handled_outputs or not self.converts_outputs_with_preprocessor:
            return
        for t in self._unhandled_outputs():
            if not self.publishers_dict[t.name].has_preprocessors:
                raise WiringError(
                    f"component {self.component_name!r} produces {[h.type_name() for h in self.handled_outputs]}, "
                    f"not {t.type_name} for output {t.name!r}: add a pre-processor that turns its output into "
                    f"{t.type_name} with add_publisher_preprocessor({t.name!r}, func) before launching")

    def _validate_handled_outputs(self) -> None:
        if not self.handled_outputs or self.converts_outputs_with_preprocessor:
            return
        for t in self.outputs:
            if not any(issubclass(t.msg_type, h) for h in self.handled_outputs):
                raise WiringError(
                    f"component {self.component_name!r} cannot produce {t.type_name} for output {t.name!r}; "
                    f"it produces {[h.type_name() for h in self.handled_outputs]}"
                )

    @property
    def inference_params(self) -> dict[str, Any]:
        """The config's per-inference parameters (``config._get_inference_params()``)."""
        return self.config._get_inference_params()

    # -- lifecycle ----------------------------------------------------------------------------

    # The component owns its clients: connected here, at configure (database first, since a
    # warm-up may use it), released at shutdown, switched by change_model_client.

    def custom_on_configure(self) -> None:
        self._check_outputs_converted()
        database_down = self._set_up_database()  # before the model: a warm-up may use it
        self._set_up_model()
        if database_down is not None:  # after it: a model set up fine would report the component healthy
            # No fallback: they are the model's (change_model_client, ...), and the model is not what failed.
            self.runtime.health.mark_failed(HealthStatus.COMPONENT_FAILURE, database_down,
                                            "database setup at configure")
            self._logger.warning("component %r comes up unhealthy: its database is not reachable (%s); each use "
                                 "tries again", self.component_name, database_down)
        if self._streams_through_queues():
            self._ws_streaming.start()
            self._logger.info("streaming through the WebSocket client: requests in req_queue, replies in resp_queue")

    def _streams_through_queues(self) -> bool:
        """Whether inference goes through ``req_queue`` / ``resp_queue`` (architecture.md, "Streaming").

        So it does when the config streams, the client is a WebSocket one (``RoboMLWSClient``)
        and the component implements ``_handle_websocket_streaming`` (the built-in components
        that do not stream through the client's chunk iterator instead, on every client).
        """
        return (bool(getattr(self.config, "stream", False)) and bool(getattr(self.model_client, "is_websocket", False))
                and type(self)._handle_websocket_streaming is not ModelComponent._handle_websocket_streaming)

    def _set_up_database(self) -> ModelClientError | None:
        """Connect the database client; the error when it cannot be reached (not raised: as a model server
        that is down, a database that is down leaves the component up and unhealthy, and each use tries again)."""
        with self._db_lock:
            self._db_ready = False
        try:
            self._ensure_db_ready()
        except ModelClientError as exc:
            return exc
        return None

    def _ensure_db_ready(self) -> None:
        """Set up the database client unless that already succeeded (a ModelClientError if it fails): call it
        before each use of ``db_client``."""
        if self.db_client is None or self._db_ready:  # the common case, without the lock
            return
        with self._db_lock:
            if not self._db_ready:
                self._start_client(self.db_client)
                self._db_ready = True

    def _set_up_model(self) -> None:
        """Connect the model client (or deploy the local model) and warm up, running the fallbacks
        when the client fails (see the module docstring); never raises a client error."""
        for _ in range(_MAX_SETUP_ATTEMPTS):
            client, local = self.model_client, self.local_model
            try:
                self._start_model()
            except ModelClientError as exc:
                ran = self.runtime.health.failed(HealthStatus.COMPONENT_FAILURE, exc, "model setup at configure")
                if not ran:
                    break
                if self.model_client is not client or self.local_model is not local:
                    self._logger.info("trying the model setup again with what the fallback switched to")
                continue
            if self.health_status != HealthStatus.HEALTHY:
                self.runtime.health.step_succeeded()
            return
        self._logger.warning("component %r comes up unhealthy (%s): its model setup failed (%s); each step tries "
                             "it again", self.component_name, self.health_status.name, self.health_message)

    def _start_model(self) -> None:
        if self.model_client is None and self.local_model is None and self.config.enable_local_model:
            self._deploy_local_model()
        self._ensure_client_ready()
        if self.config.warmup and (self.model_client is not None or self.local_model is not None):
            self._logger.info("warming up")
            self._warmup()

    def _ensure_client_ready(self) -> None:
        """Set up the model client unless that already succeeded (a ModelClientError if it fails)."""
        client = self.model_client
        if client is not None and self._ready_client is not client:
            self._start_client(client)
            self._ready_client = client

    def _start_client(self, client: ModelClient | DBClient) -> None:
        client.check_connection()
        if client.init_on_activation:
            client.initialize()

    def custom_on_activate(self) -> None:
        if self._streams_through_queues() and not self._ws_streaming.running:
            self._ws_streaming.start()  # a component reactivated after cleanup, or whose client changed

    def custom_on_deactivate(self) -> None:
        # As upstream (custom_client.md: "_deinitialize ... called during the component's
        # deactivate"): the model is released on the server; the next step (or activate) sets it
        # up again. Pending streaming requests and replies are dropped.
        self._ws_streaming.drain()
        if self.model_client is not None:
            self._release_client(self.model_client)
            self._ready_client = None

    def custom_on_cleanup(self) -> None:
        self._ws_streaming.stop()

    def custom_on_shutdown(self) -> None:
        self._ws_streaming.stop()
        if self.model_client is not None:
            self._release_client(self.model_client)
            # A step still running at deactivate may have reopened the connection pool after the release
            # closed it (a client reconnects on next use): close it for good, or its sockets outlive us.
            close = getattr(self.model_client, "close", None)
            if callable(close):
                try:
                    close()
                except Exception as exc:
                    self._logger.debug("closing model client %r: %s", self.model_client, exc)
        if self.db_client is not None:
            with self._db_lock:
                self._db_ready = False
            try:
                self.db_client.deinitialize()
            except Exception as exc:
                self._logger.warning("database client did not deinitialize cleanly: %s", exc)

    # -- inference ----------------------------------------------------------------------------

    def _call_inference(self, inference_input: dict[str, Any], unpack: bool = False) -> MutableMapping[str, Any]:
        """Run inference on the client, or on the local model when there is no client.

        Raises a :class:`~agents_core.errors.ModelClientError` subclass on failure (never returns
        None for a failure; a ``None`` check after it is harmless). In the WebSocket streaming
        flow (:meth:`_streams_through_queues`) the request goes into ``req_queue`` and None is
        returned: the reply arrives in ``resp_queue``, for ``_handle_websocket_streaming``.
        """
        if self.model_client is not None:
            self._ensure_client_ready()
            if self._streams_through_queues() and self._ws_streaming.running:
                self.req_queue.put_nowait({**inference_input, "stream": True})
                return cast("MutableMapping[str, Any]", None)
            return self.model_client.inference(inference_input)
        if self.local_model is not None:
            result = self.local_model(**inference_input) if unpack else self.local_model(inference_input)
            if result is None or "output" not in result:
                raise InferenceError(f"component {self.component_name!r}: the local model returned no output")
            return dict(result)
        raise ComponentError(f"component {self.component_name!r} has neither a model client nor a local model")

    def _publish(self, result: Mapping[str, Any], **kwargs: Any) -> None:
        """Publish ``result["output"]`` on every output topic.

        Keyword arguments (``stream=``, ``done=``, ``frame_id=``, ...) reach each output type's
        ``convert(output, **kwargs)``, as upstream.
        """
        output = result["output"]
        for pub in self.publishers_dict.values():
            pub.publish(output, **kwargs)

    # -- switching models ---------------------------------------------------------------------

    @component_fallback(description={
        "description": "Switch to another of the component's model clients, by name.",
        "parameters": {"type": "object",
                       "properties": {"model_client_name": {"type": "string",
                                                            "description": "key in additional_model_clients"}},
                       "required": ["model_client_name"]},
    })
    def change_model_client(self, model_client_name: str) -> bool:
        """Switch to ``additional_model_clients[model_client_name]`` (connected and initialized first)."""
        client = self.additional_model_clients.get(model_client_name)
        if client is None:
            raise ComponentError(f"component {self.component_name!r} has no additional model client "
                                 f"{model_client_name!r} (has {sorted(self.additional_model_clients)})")
        self._start_client(client)
        if control_deadline_passed():
            # The caller (an action's or a request's timeout) gave up while the new client was
            # connecting: switching now would surprise it. Stay on the current client.
            self._release_client(client)
            raise RequestTimeoutError(f"component {self.component_name!r}: switching to {model_client_name!r} "
                                      "took longer than the caller waited; still using the previous client")
        old = self.model_client
        self.model_client = client
        self._ready_client = client
        if old is not None and old is not client:
            self._release_client(old)
        self._logger.info("now using model client %r", model_client_name)
        return True

    def _release_client(self, client: ModelClient) -> None:
        if not client.initialized:
            return
        try:
            client.deinitialize()
        except Exception as exc:  # the old server is often the one that failed
            self._logger.warning("model client %r did not deinitialize: %s", client, exc)

    @component_fallback(description={
        "description": "Stop using the remote model client and answer with the built-in local model.",
        "parameters": {"type": "object", "properties": {}, "required": []},
    })
    def fallback_to_local(self) -> bool:
        """Switch from the model client to the component's built-in local model."""
        if self.local_model is None:
            self.config.enable_local_model = True
            self._deploy_local_model()
        old, self.model_client = self.model_client, None
        self._ready_client = None
        if old is not None:
            # As upstream: the remote model is unloaded, not left loaded on its server.
            self._release_client(old)
        # Maybe called by the client loop's own failure report: do not wait for it.
        self._ws_streaming.stop(wait=False)
        self._logger.info("now using the local model")
        return True

    def _deploy_local_model(self) -> None:
        """Create ``self.local_model`` (components with a built-in local model override this)."""
        raise ComponentError(f"component {self.component_name!r} ({type(self).__name__}) has no built-in local model")

    # -- what subclasses implement --------------------------------------------------------------

    def _create_input(self, *args: Any, **kwargs: Any) -> dict[str, Any] | None:
        """Assemble the inference input from the callbacks (None: nothing to do this step)."""
        raise NotImplementedError(f"{type(self).__name__} must implement _create_input()")

    def _warmup(self, *args: Any, **kwargs: Any) -> None:
        """Run a dummy inference so the first real one is fast (called at configure if enabled)."""
        raise NotImplementedError(f"{type(self).__name__} must implement _warmup()")

    def _handle_websocket_streaming(self) -> Any:
        """Publish partial results from ``self.resp_queue`` (streaming WebSocket clients only)."""
        return None
