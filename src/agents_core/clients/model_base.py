"""``ModelClient``: the base of every client that reaches a model serving platform.

Implement ``_check_connection``, ``_initialize``, ``_inference`` and ``_deinitialize``. The
public methods of the same names without the underscore are what components call: they turn
any failure into a typed :class:`~agents_core.errors.ModelClientError` and check the result,
so a failed inference is never a silent ``None``.

Deadlines: ``inference_timeout`` bounds the whole inference, from connecting to the last byte of
the answer (for a stream: to its last chunk), whatever the server does meanwhile (keep-alive
comments, one byte per second). Streams also have a time to the first chunk
(``stream_first_chunk_timeout``) and between chunks (``stream_chunk_timeout``). Clients build a
:class:`~agents_core.clients.deadline.CallWatch` per call with :meth:`ModelClient._watch` and
hand streams out through :meth:`ModelClient._chunk_stream`.

Tasks: what a model does is declared once, by its class (:attr:`agents_core.models.Model.task`).
A client serving several tasks maps each to the method handling it in ``task_handlers`` and
calls :meth:`ModelClient._task_handler` from ``_inference``; a model whose task is not in the
table is refused when the client is built.
"""

from __future__ import annotations

import time
from abc import abstractmethod
from collections.abc import Callable, Collection, Iterator, Mapping, MutableMapping, Sequence
from typing import Any, ClassVar, TypeVar

from ..errors import ClientConnectionError, ConfigError, InferenceConnectionError, InferenceError, ProtocolError
from ..models import Model, model_types
from ..telemetry import switch as _telemetry
from .client_base import BaseClient
from .deadline import CallWatch, check_seconds
from .payloads import ChunkStream
from .reply_limit import DEFAULT_MAX_REPLY_BYTES, check_max_reply_bytes

__all__ = ["ModelClient"]

_MODEL_SPEC_KEYS = {"model_name", "model_type", "init_timeout", "model_init_params"}

#: Default seconds a stream may go without a chunk once it has started.
DEFAULT_STREAM_CHUNK_TIMEOUT = 10.0

T = TypeVar("T")


class ModelClient(BaseClient):
    """Connection to a model serving platform for one model.

    :param model: the :class:`~agents_core.models.Model`, or its serialized dict.
    :param host: server host name or address.
    :param port: server port.
    :param inference_timeout: seconds a whole inference may take, connect to last byte (for a
        stream: to its last chunk); then it fails with
        :class:`~agents_core.errors.InferenceTimeoutError`. Raise it for long streamed answers.
    :param stream_first_chunk_timeout: seconds from the start of a streamed inference to its first
        chunk (a model loading, a long prompt); None (default): only ``inference_timeout`` bounds it.
    :param max_reply_bytes: the most bytes one reply may hold, counted after decompression (a
        streamed answer's chunks together); past it the call fails with
        :class:`~agents_core.clients.reply_limit.ReplyTooLargeError` naming the server and the limit.
        64 MiB by default.
    :param stream_chunk_timeout: seconds a stream may go without a chunk after the first one
        (default 10; None: only ``inference_timeout``). Keep-alive comments do not count as chunks.
    :param init_on_activation: call ``_initialize()`` during configure.
    :param logging_level: ``"debug"``, ``"info"``, ...

    Every timeout is a finite number of seconds > 0 (not a bool); each is capped by the time left
    before ``inference_timeout``.
    """

    #: The method serving each model task, by name (``{"chat": "_chat"}``); empty: any model is
    #: accepted and ``_inference`` does not dispatch on the task.
    task_handlers: ClassVar[Mapping[str, str]] = {}

    def __init__(
        self,
        model: Model | dict[str, Any],
        host: str | None = None,
        port: int | None = None,
        inference_timeout: int | float = 30,
        init_on_activation: bool = True,
        logging_level: str = "info",
        stream_first_chunk_timeout: int | float | None = None,
        stream_chunk_timeout: int | float | None = DEFAULT_STREAM_CHUNK_TIMEOUT,
        max_reply_bytes: int = DEFAULT_MAX_REPLY_BYTES,
        **kwargs: Any,
    ) -> None:
        if kwargs:
            raise ConfigError(f"{type(self).__name__}: unexpected argument(s) {sorted(kwargs)}")
        super().__init__(host=host, port=port, init_on_activation=init_on_activation, logging_level=logging_level)
        if isinstance(model, Model):
            self.model_name = model.name
            self.model_type = type(model).__name__
            self.init_timeout = model.init_timeout
            self.model_init_params: dict[str, Any] = model._get_init_params()
        elif isinstance(model, dict):
            missing = _MODEL_SPEC_KEYS - set(model)
            if missing:
                raise ConfigError(f"{type(self).__name__}: model spec lacks {sorted(missing)}")
            self.model_name = str(model["model_name"])
            self.model_type = str(model["model_type"])
            self.init_timeout = model["init_timeout"]
            self.model_init_params = dict(model["model_init_params"])
        else:
            raise ConfigError(f"{type(self).__name__}: model must be a Model or its dict, got {type(model).__name__}")
        owner = type(self).__name__
        if self.task_handlers and self.task not in self.task_handlers:
            raise ConfigError(f"{owner}: a {self.model_type} is a {self.task!r} model; this client serves "
                              f"{sorted(self.task_handlers)} models")
        check_seconds(owner, "inference_timeout", inference_timeout)
        self.inference_timeout = inference_timeout
        self.stream_first_chunk_timeout = check_seconds(owner, "stream_first_chunk_timeout",
                                                        stream_first_chunk_timeout, optional=True)
        self.stream_chunk_timeout = check_seconds(owner, "stream_chunk_timeout", stream_chunk_timeout,
                                                  optional=True)
        self.max_reply_bytes = check_max_reply_bytes(owner, max_reply_bytes)
        self.initialized = False
        self.last_inference_seconds: float | None = None

    @property
    def task(self) -> str:
        """What the served model does: its class's ``task`` (a model type not imported here is a plain Model's)."""
        cls = model_types().get(self.model_type, Model)
        return cls.task

    def _task_handler(self) -> Callable[[dict[str, Any]], MutableMapping[str, Any] | None]:
        """The method ``task_handlers`` names for the model's task."""
        name = self.task_handlers.get(self.task)
        if name is None:
            raise ConfigError(f"{type(self).__name__} has no handler for {self.task!r} models")
        handler: Callable[[dict[str, Any]], MutableMapping[str, Any] | None] = getattr(self, name)
        return handler

    def _call_options(self, params: dict[str, Any], *, skip: Collection[str], known: Collection[str],
                      max_tokens: str) -> dict[str, Any]:
        """The model's ``options`` overridden by those of ``params`` (an inference input) the protocol knows.

        :param skip: keys of ``params`` that are not options (``query``, ``stream``...); None values
            are skipped too.
        :param known: the option names the protocol takes; other keys are logged (debug), not sent.
        :param max_tokens: the protocol's name for ``max_new_tokens``.
        """
        options: dict[str, Any] = dict(self.model_init_params.get("options") or {})
        ignored: list[str] = []
        for key, value in params.items():
            if key in skip or value is None:
                continue
            if key == "max_new_tokens":
                options[max_tokens] = value
            elif key in known:
                options[key] = value
            else:
                ignored.append(key)
        if ignored:
            self.logger.debug("%s: inference parameters the protocol does not take, not sent: %s", self._label(),
                              sorted(ignored))
        return options

    # -- deadlines, for subclasses ----------------------------------------------------------------

    def _watch(self, what: str, *, stream: bool = False, seconds: float | None = None,
               setting: str = "inference_timeout") -> CallWatch:
        """The limits of one call named ``what``: ``seconds`` (default ``inference_timeout``) for
        the whole call, plus the chunk timers when ``stream``. ``setting`` names ``seconds`` in errors."""
        return CallWatch(float(self.inference_timeout if seconds is None else seconds), f"{self._label()}: {what}",
                         first_chunk=self.stream_first_chunk_timeout if stream else None,
                         between_chunks=self.stream_chunk_timeout if stream else None, what=setting)

    def _chunk_stream(self, chunks: Iterator[T], watch: CallWatch | None, label: str,
                      on_close: Callable[[], None] | None = None) -> ChunkStream[T]:
        """A :class:`ChunkStream` timed by ``watch`` whose errors never show this client's secrets."""
        return ChunkStream(chunks, on_close=on_close, label=label, watch=watch, secrets=self._secrets())

    # -- what subclasses implement ------------------------------------------------------------

    @abstractmethod
    def _check_connection(self) -> None:
        """Raise if the platform cannot be reached."""

    @abstractmethod
    def _initialize(self) -> None:
        """Load the model on the platform (uses ``self.model_init_params``)."""

    @abstractmethod
    def _inference(self, inference_input: dict[str, Any]) -> MutableMapping[str, Any] | None:
        """Run one inference; return a dict with at least ``"output"`` (a generator when streaming)."""

    @abstractmethod
    def _deinitialize(self) -> None:
        """Release the model on the platform."""

    def _embed(self, texts: list[str]) -> list[list[float]]:
        """Embed texts (clients whose platform serves embeddings override this)."""
        raise ConfigError(f"{type(self).__name__} cannot compute embeddings")

    @property
    def supports_tool_calls(self) -> bool:
        """Whether the platform handles tool descriptions (components then send them)."""
        return False

    # -- what components call -----------------------------------------------------------------

    def check_connection(self) -> None:
        """Verify the platform is reachable (typed error otherwise)."""
        self._guard("connection check", self._check_connection)

    def initialize(self) -> None:
        """Load the model on the platform."""
        self._guard("initialize", self._initialize)
        self.initialized = True

    def inference(self, inference_input: dict[str, Any]) -> MutableMapping[str, Any]:
        """Run one inference; raises a typed error on failure or on a result without ``output``.

        With telemetry on, the call is a ``model <name>`` span (:mod:`agents_core.telemetry.otel`).
        """
        tel = _telemetry.hooks
        if tel is None:
            return self._timed_inference(inference_input)
        with tel.model_call(str(self.model_name), type(self).__name__) as call:
            result = self._timed_inference(inference_input)
            stream = result["output"]
            usage = getattr(self, "last_usage", None) or getattr(self, "last_stats", None)
            recorded: MutableMapping[str, Any] = call.record(result, usage if isinstance(usage, dict) else None)
            if isinstance(stream, ChunkStream) and not isinstance(recorded["output"], ChunkStream):
                # Still a ChunkStream to its reader (the streaming loops check the type), timed within.
                recorded["output"] = ChunkStream(recorded["output"], label=f"{type(self).__name__} stream")
            return recorded

    def _timed_inference(self, inference_input: dict[str, Any]) -> MutableMapping[str, Any]:
        start = time.monotonic()
        try:
            result = self._guard("inference", lambda: self._inference(inference_input))
        except InferenceConnectionError:
            raise
        except ClientConnectionError as exc:
            # The server went away under an inference: an algorithm failure at run time (as upstream).
            raise InferenceConnectionError.from_connection_error(exc) from (exc.__cause__ or exc)
        self.last_inference_seconds = time.monotonic() - start
        if result is None:
            raise InferenceError(f"{self._label()}: inference with model {self.model_name!r} returned nothing")
        if "output" not in result:
            raise ProtocolError(f"{self._label()}: inference result has no 'output' key: {sorted(result)}")
        return result

    def embed(self, texts: Sequence[str]) -> list[list[float]]:
        """One embedding vector per text, in order (typed error on failure or a count mismatch)."""
        if isinstance(texts, str) or not all(isinstance(t, str) for t in texts):
            raise ConfigError(f"{type(self).__name__}.embed takes a list of str")
        if type(self)._embed is ModelClient._embed:
            raise ConfigError(f"{type(self).__name__} cannot compute embeddings (its platform serves none)")
        vectors = self._guard("embed", lambda: self._embed(list(texts)))
        if len(vectors) != len(texts):
            raise ProtocolError(f"{self._label()}: asked for {len(texts)} embeddings, got {len(vectors)}")
        return vectors

    def deinitialize(self) -> None:
        """Release the model (errors are typed and raised)."""
        try:
            self._guard("deinitialize", self._deinitialize)
        finally:
            self.initialized = False

    def serialize(self) -> dict[str, Any]:
        spec = super().serialize()
        spec["model"] = {
            "model_name": self.model_name,
            "model_type": self.model_type,
            "init_timeout": self.init_timeout,
            "model_init_params": self.model_init_params,
        }
        spec["inference_timeout"] = self.inference_timeout
        spec["stream_first_chunk_timeout"] = self.stream_first_chunk_timeout
        spec["stream_chunk_timeout"] = self.stream_chunk_timeout
        spec["max_reply_bytes"] = self.max_reply_bytes
        return spec
