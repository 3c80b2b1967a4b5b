"""``RoboMLRESPClient``: a model served by RoboML's RESP (Redis protocol) server.

Commands, argument and reply encodings are described in :mod:`agents_core.clients.roboml_protocol`. The
client uses redis-py (``pip install redis``), imported on first use so that agents_core imports
without it.
"""

from __future__ import annotations

import importlib
import threading
from collections.abc import MutableMapping
from types import SimpleNamespace
from typing import Any, ClassVar

from ..errors import (
    ClientConnectionError,
    ConfigError,
    InferenceError,
    InferenceTimeoutError,
    ModelClientError,
    ProtocolError,
)
from .deadline import CallWatch
from .roboml_protocol import (
    RoboMLNodeClient,
    build_roboml_input,
    normalize_result,
    packb,
    retry_connect,
    single_chunk_stream,
    unpackb,
)

__all__ = ["RoboMLRESPClient"]


def _import_redis() -> SimpleNamespace:
    # importlib keeps redis optional for mypy too: the typed API is not needed for four calls.
    try:
        return SimpleNamespace(
            Redis=importlib.import_module("redis").Redis,
            Retry=importlib.import_module("redis.retry").Retry,
            NoBackoff=importlib.import_module("redis.backoff").NoBackoff,
            errors=importlib.import_module("redis.exceptions"),
        )
    except ImportError as exc:
        raise ConfigError("RoboMLRESPClient needs the redis package: pip install redis") from exc


class RoboMLRESPClient(RoboMLNodeClient):
    """A model served by RoboML's RESP server (``roboml-resp``), a lighter transport than HTTP.

    Parameters as :class:`~agents_core.clients.roboml_http.RoboMLHTTPClient`; ``port`` defaults
    to 6379, where ``roboml-resp`` listens. RoboML's RESP server cannot stream: an LLM inference
    with ``stream: True`` gets its whole answer as a single chunk.
    """

    default_port: ClassVar[int] = 6379

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._redis: Any = None  # for inference and pings: times out after inference_timeout
        self._admin: Any = None  # for node lifecycle: times out after the model's init timeout
        self._lock = threading.Lock()
        self._rd: SimpleNamespace | None = None

    def _connections(self) -> tuple[Any, Any]:
        # Connections open on first use (never in the constructor).
        with self._lock:
            if self._redis is None:
                rd = self._rd = _import_redis()
                common = {
                    "host": self.host, "port": self.port,
                    # RoboML's server speaks RESP2 only: redis-py 8 would open with HELLO 3.
                    "protocol": 2,
                    # redis-py retries timed-out commands by default; an inference must not run twice.
                    "retry": rd.Retry(rd.NoBackoff(), 0),
                    "socket_connect_timeout": min(float(self.inference_timeout), 10.0),
                }
                self._redis = rd.Redis(socket_timeout=float(self.inference_timeout), **common)
                self._admin = rd.Redis(socket_timeout=self._init_seconds, **common)
            return self._redis, self._admin

    def _call(self, connection: Any, what: str, command: str, arguments: dict[str, Any] | None = None, *,
              seconds: float | None = None, setting: str = "inference_timeout") -> Any:
        """Run one command within ``seconds`` (default ``inference_timeout``), connect to last byte.

        Returns the decoded reply (None for ``+OK``); raises typed errors.
        """
        # An empty map would never be answered (RoboML skips the reply for an empty argument map).
        args = (packb(arguments),) if arguments else ()
        label = f"{self._label()}: {what}"
        # redis-py's socket timeout bounds each read; a reply trickling in is cut by the watchdog,
        # which drops the pool's connections (shut down, so the blocked read returns at once).
        watch = CallWatch(float(self.inference_timeout if seconds is None else seconds), label, what=setting)
        watch.set_abort(connection.connection_pool.disconnect)
        try:
            raw = connection.execute_command(command, *args)
        except ModelClientError:
            raise
        except Exception as exc:
            if watch.fired is not None:
                raise watch.error() from exc
            raise self._redis_error(exc, label) from exc
        finally:
            watch.close()
        if raw is None or raw == b"OK" or raw is True:
            return None
        if not isinstance(raw, bytes):
            raise ProtocolError(f"{label}: unexpected reply {raw!r:.200}")
        return unpackb(raw)

    def _redis_error(self, exc: Exception, label: str) -> ModelClientError:
        errors = self._rd.errors if self._rd is not None else None
        if errors is None:
            return InferenceError(f"{label}: {type(exc).__name__}: {exc}")
        if isinstance(exc, errors.TimeoutError):
            return InferenceTimeoutError(f"{label}: no reply within the timeout: {exc}")
        if isinstance(exc, errors.ConnectionError):
            return ClientConnectionError(f"{label}: cannot reach RoboML at {self.host}:{self.port}: {exc}")
        if isinstance(exc, errors.ModuleError):
            # RoboML's answer to add_node with a model class it does not have.
            return InferenceError(f"{label}: RoboML has no model class {self.node_model!r}: {exc}")
        if isinstance(exc, errors.ResponseError):
            message = str(exc)
            if message.startswith("INVALID_COMMAND"):
                message += f" (is node {self.node_name!r} on the server? initialize() adds it)"
            return InferenceError(f"{label}: RoboML answered an error: {message}")
        if isinstance(exc, errors.InvalidResponse):
            return ProtocolError(f"{label}: not a RESP reply: {exc}")
        return InferenceError(f"{label}: {type(exc).__name__}: {exc}")

    # -- ModelClient ------------------------------------------------------------------------

    def _check_connection(self) -> None:
        redis, _ = self._connections()
        retry_connect(lambda: self._call(redis, "connection check", "PING"), attempts=self.connect_attempts,
                      delay=self.connect_retry_delay, retry_on=(ClientConnectionError,), logger=self.logger,
                      what=f"{self._label()}: connection check")

    def _initialize(self) -> None:
        _, admin = self._connections()
        answer = self._call(admin, f"add_node {self.node_name!r}", "add_node",
                            {"node_name": self.node_name, "node_model": self.node_model},
                            seconds=self._init_seconds, setting="init_timeout")
        if isinstance(answer, str):
            # A str is RoboML's name-duplication warning: the node exists and keeps its model.
            self.logger.warning("RoboML: %s", answer)
        self._call(admin, f"initialize node {self.node_name!r}", f"{self.node_name}.initialize",
                   self.model_init_params, seconds=self._init_seconds, setting="init_timeout")
        self.logger.info("RoboML node %r (%s) is ready", self.node_name, self.node_model)

    def _inference(self, inference_input: dict[str, Any]) -> MutableMapping[str, Any] | None:
        payload, stream = build_roboml_input(self.node_model, inference_input, binary=True)
        if stream:
            # RoboML's RESP server packs the whole result with msgpack, which cannot hold a generator.
            payload["stream"] = False
        redis, _ = self._connections()
        result = normalize_result(self.node_model, self._call(redis, "inference", f"{self.node_name}.inference",
                                                              payload), self._label())
        if stream:
            result["output"] = single_chunk_stream(result["output"], f"{self._label()}: inference",
                                                   secrets=self._secrets())
        return result

    def _deinitialize(self) -> None:
        try:
            _, admin = self._connections()
            self._call(admin, f"remove_node {self.node_name!r}", "remove_node", {"node_name": self.node_name},
                       seconds=self._init_seconds, setting="init_timeout")
        finally:
            self.close()

    # -- extras -----------------------------------------------------------------------------

    def node_status(self) -> str:
        """The node's status: ``"LOADED"``, ``"INITIALIZING"``, ``"READY"`` or ``"INITIALIZATION_ERROR"``."""
        redis, _ = self._connections()
        return str(self._call(redis, "node status", f"{self.node_name}.get_status"))

    def close(self) -> None:
        """Close the connections (idempotent; the next call opens new ones)."""
        with self._lock:
            clients, self._redis, self._admin = (self._redis, self._admin), None, None
        for client in clients:
            if client is not None:
                client.close()
