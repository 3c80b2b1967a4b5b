"""``OllamaClient``: chat, generation and embeddings over Ollama's REST API.

Ollama's endpoints used: ``GET /api/version`` (connection check), ``POST /api/show`` (is the
model there?), ``POST /api/pull`` (download it, progress streamed as NDJSON), ``POST
/api/generate`` (load / unload / plain generation), ``POST /api/chat`` and ``POST /api/embed``.
Streamed answers are NDJSON: one JSON object per line, the last one with ``"done": true``; a
failure after the 200 status arrives as a ``{"error": "..."}`` line and raises a typed error.

Ollama itself has no authentication, but it is often reached through an authenticating proxy
(or a hosted Ollama): ``api_key`` is then sent as ``Authorization: Bearer <key>`` with every
request. Like GenericHTTPClient's key it is part of :meth:`OllamaClient.serialize` (specs travel
in memory or over a pipe) and never appears in ``repr()``, logs, errors or status messages.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, MutableMapping
from typing import Any, ClassVar

import httpx

from ..errors import ConfigError, InferenceError, ProtocolError
from ..models import OLLAMA_OPTIONS, Model, OllamaModel
from .deadline import CallWatch, check_seconds
from .http_base import HTTPClientBase, bearer, check_api_key, iter_ndjson
from .model_base import ModelClient
from .payloads import (
    ChunkStream,
    checked_messages,
    checked_tool_calls,
    image_to_base64_png,
    make_tool_call,
    message_text,
)

__all__ = ["OllamaClient"]

_DEFAULT_PORT = 11434
#: Keys of an inference input that are not model options.
_CONTROL_KEYS = frozenset({"query", "stream", "tools", "keep_alive", "format", "images", "system"})
#: A pull streams a few lines per progress update; this bounds a server that never says "success".
_MAX_PULL_LINES = 1_000_000
#: The timing fields of Ollama's final answer object (durations in nanoseconds).
_STAT_KEYS = ("done_reason", "total_duration", "load_duration", "prompt_eval_count", "prompt_eval_duration",
              "eval_count", "eval_duration")
#: Seconds a model load may take when the model gives no ``init_timeout`` (big models, slow disks).
_DEFAULT_LOAD_TIMEOUT = 300.0


class OllamaClient(HTTPClientBase, ModelClient):
    """Client for an Ollama server.

    :param model: an :class:`~agents_core.models.OllamaModel` (or its serialized dict); its
        ``checkpoint`` is the Ollama tag, its ``options`` and ``keep_alive`` go with every request.
    :param host: Ollama's host.
    :param port: Ollama's port (None: the model's ``port``, else 11434).
    :param inference_timeout: seconds a whole call may take, connect to last byte (a streamed
        answer included); see :class:`~agents_core.clients.model_base.ModelClient` for
        ``stream_first_chunk_timeout`` and ``stream_chunk_timeout``, also accepted here.
    :param pull_timeout: seconds a missing model may take to download during initialize (a
        download that sends no progress for ``max(inference_timeout, 60)`` s fails sooner).
    :param api_key: a token sent as ``Authorization: Bearer <key>`` (a proxy in front of Ollama,
        a hosted Ollama); None (default) sends no ``Authorization`` header.
    :param use_https: talk HTTPS (a TLS proxy in front of Ollama).
    :param init_on_activation: check, pull and load the model during configure.
    :param logging_level: ``"debug"``, ``"info"``, ...
    """

    #: Ollama serves chat models (and their ``generate`` and ``embed``).
    task_handlers: ClassVar[dict[str, str]] = {"chat": "_chat"}
    spec_fields: ClassVar[tuple[str, ...]] = ("pull_timeout", "api_key", "use_https")

    def __init__(
        self,
        model: Model | dict[str, Any],
        host: str = "127.0.0.1",
        port: int | None = None,
        inference_timeout: int | float = 30,
        pull_timeout: int | float = 3600,
        init_on_activation: bool = True,
        logging_level: str = "info",
        api_key: str | None = None,
        use_https: bool = False,
        **kwargs: Any,
    ) -> None:
        if port is None:
            port = model.port if isinstance(model, OllamaModel) and model.port is not None else _DEFAULT_PORT
        super().__init__(model=model, host=host, port=port, inference_timeout=inference_timeout,
                         init_on_activation=init_on_activation, logging_level=logging_level, **kwargs)
        check_seconds(type(self).__name__, "pull_timeout", pull_timeout)
        self.pull_timeout = pull_timeout
        self.api_key = check_api_key(type(self).__name__, api_key)
        self.use_https = bool(use_https)
        self.checkpoint = str(self.model_init_params.get("checkpoint") or self.model_name)
        #: The Ollama version seen by the last connection check.
        self.server_version: str | None = None
        #: Timing and token counts of the last finished answer (``eval_count``, ``eval_duration``...).
        self.last_stats: dict[str, Any] | None = None

    # -- settings -------------------------------------------------------------------------------------

    @property
    def supports_tool_calls(self) -> bool:
        """Ollama's chat endpoint takes tools."""
        return True

    @property
    def keep_alive(self) -> Any:
        """How long Ollama keeps the model loaded after a request (the model's setting)."""
        return self.model_init_params.get("keep_alive")

    def _headers(self) -> dict[str, str]:
        return bearer(self.api_key)

    def _request_body(self, params: dict[str, Any], **fields: Any) -> dict[str, Any]:
        body: dict[str, Any] = {"model": self.checkpoint, **fields}
        options = self._call_options(params, skip=_CONTROL_KEYS, known=OLLAMA_OPTIONS, max_tokens="num_predict")
        if options:
            body["options"] = options
        keep_alive = params.get("keep_alive", self.keep_alive)
        if keep_alive is not None:
            body["keep_alive"] = keep_alive
        if params.get("format") is not None:
            body["format"] = params["format"]
        return body

    # -- ModelClient ----------------------------------------------------------------------------------

    def _check_connection(self) -> None:
        """``GET /api/version``."""
        body = self._request_json("GET", "/api/version", "version", fresh=True)
        if not isinstance(body, dict) or not isinstance(body.get("version"), str):
            raise ProtocolError(f"{self._context('version')}: expected {{'version': ...}}, got {str(body)[:200]}")
        self.server_version = body["version"]
        self.logger.info("%s: Ollama %s reachable", self._label(), self.server_version)

    def _initialize(self) -> None:
        """Pull the model if Ollama does not have it, then load it (so the first answer is fast)."""
        response = self._request("POST", "/api/show", "show", check=False, json={"model": self.checkpoint})
        if response.status_code == httpx.codes.NOT_FOUND:
            self.logger.info("%s: model %r not present, pulling it", self._label(), self.checkpoint)
            self.pull()
        else:
            self._check_response(response, "show")
        self.load()

    def _deinitialize(self) -> None:
        """Unload the model from Ollama's memory and close the connection pool."""
        try:
            if self._http is not None:
                self._unload()
        finally:
            self.close()

    def _inference(self, inference_input: dict[str, Any]) -> MutableMapping[str, Any] | None:
        return self._task_handler()(inference_input)

    def _chat(self, inference_input: dict[str, Any]) -> MutableMapping[str, Any]:
        """``POST /api/chat``, streamed as NDJSON or read whole."""
        tools = inference_input.get("tools")
        body = self._request_body(inference_input, messages=self._messages(inference_input.get("query")))
        if tools:
            body["tools"] = tools
        # With tools the answer is read whole (older Ollama versions require it, and tool calls
        # arrive complete that way); the contract lets a client answer a str then.
        stream = bool(inference_input.get("stream")) and not tools
        body["stream"] = stream
        if stream:
            return {"output": self._stream("/api/chat", body, "chat stream", _message_text)}
        context = self._context("chat")
        answer = self._final_object(self._request("POST", "/api/chat", "chat", json=body), "chat")
        message = answer.get("message")
        if not isinstance(message, dict):
            raise ProtocolError(f"{context}: the answer has no 'message' object: {str(answer)[:200]}")
        result: dict[str, Any] = {"output": str(message.get("content") or "")}
        if tools:
            result["tool_calls"] = checked_tool_calls(message.get("tool_calls"), context, _tool_call)
        return result

    def _embed(self, texts: list[str]) -> list[list[float]]:
        """``POST /api/embed`` with every text at once."""
        context = self._context("embed")
        answer = self._request_json("POST", "/api/embed", "embed", json=self._request_body({}, input=texts))
        vectors = answer.get("embeddings") if isinstance(answer, dict) else None
        if not isinstance(vectors, list) or not all(
                isinstance(v, list) and all(isinstance(x, int | float) for x in v) for v in vectors):
            raise ProtocolError(f"{context}: expected {{'embeddings': [[...], ...]}}, got {str(answer)[:200]}")
        return [[float(x) for x in vector] for vector in vectors]

    # -- Ollama-specific operations -----------------------------------------------------------------

    def pull(self) -> None:
        """Download the model (``POST /api/pull``), logging progress; raises a typed error on failure."""
        self._guard("pull", self._pull)

    def load(self) -> None:
        """Load the model into memory (``POST /api/generate`` with no prompt)."""
        self._guard("load", self._load)

    def unload(self) -> None:
        """Unload the model from memory now (``keep_alive`` 0)."""
        self._guard("unload", self._unload)

    def generate(self, prompt: str, *, images: list[Any] | None = None, system: str | None = None,
                 stream: bool = False, **params: Any) -> str | ChunkStream[str]:
        """One completion of ``prompt`` (``POST /api/generate``), without chat formatting of history.

        :param images: uint8 image arrays for multimodal models.
        :param system: overrides the model's system prompt.
        :param stream: return a :class:`ChunkStream` of text pieces instead of the whole text.
        :param params: ``temperature``, ``max_new_tokens`` and other options, ``keep_alive``, ``format``.
        """
        if not isinstance(prompt, str):
            raise ConfigError(f"{type(self).__name__}.generate takes a str prompt")
        return self._guard("generate", lambda: self._generate(prompt, images, system, stream, params))

    def _generate(self, prompt: str, images: list[Any] | None, system: str | None, stream: bool,
                  params: dict[str, Any]) -> str | ChunkStream[str]:
        body = self._request_body(params, prompt=prompt, stream=stream)
        if images:
            body["images"] = [image_to_base64_png(image) for image in images]
        if system is not None:
            body["system"] = system
        if stream:
            return self._stream("/api/generate", body, "generate stream", _response_text)
        answer = self._final_object(self._request("POST", "/api/generate", "generate", json=body), "generate")
        return str(answer.get("response") or "")

    def _pull(self) -> None:
        what = f"pull {self.checkpoint}"
        context = self._context(what)
        # The whole download within pull_timeout, and some progress line at least every
        # max(inference_timeout, 60) s: a stalled download fails long before the hour is up.
        stall = max(float(self.inference_timeout), 60.0)
        watch = CallWatch(float(self.pull_timeout), context, first_chunk=stall, between_chunks=stall,
                          what="pull_timeout")
        response = self._open_stream("POST", "/api/pull", what, watch, json={"model": self.checkpoint, "stream": True})
        try:
            last_status, last_decile = "", -1
            for count, progress in enumerate(iter_ndjson(_timed_lines(response, watch), context)):
                if count >= _MAX_PULL_LINES:
                    raise InferenceError(f"{context}: not finished after {_MAX_PULL_LINES} progress lines")
                if "error" in progress:
                    raise InferenceError(f"{context} failed: {progress['error']}")
                status = str(progress.get("status", ""))
                if status == "success":
                    self.logger.info("%s: pulled %r", self._label(), self.checkpoint)
                    return
                total, completed = progress.get("total"), progress.get("completed")
                if isinstance(total, int) and total > 0 and isinstance(completed, int):
                    # One log line per 10 % per layer, not one per progress message (there are thousands).
                    decile = min(10, completed * 10 // total)
                    if status != last_status or decile != last_decile:
                        self.logger.info("%s: %s %d%% (%d/%d bytes)", self._label(), status,
                                         completed * 100 // total, completed, total)
                    last_decile = decile
                elif status != last_status:
                    self.logger.info("%s: %s", self._label(), status)
                last_status = status
        except Exception as exc:
            if watch.fired is not None:
                raise watch.error() from exc
            raise
        finally:
            watch.close()
            response.close()
        if watch.fired is not None:  # the stream "ended" because the watchdog cut its connection
            raise watch.error()
        raise ProtocolError(f"{context}: the progress stream ended without 'success'")

    def _load(self) -> None:
        load_timeout = float(self.init_timeout or _DEFAULT_LOAD_TIMEOUT)
        response = self._request("POST", "/api/generate", "load", seconds=load_timeout, setting="init_timeout",
                                 json=self._request_body({}, stream=False))
        self._final_object(response, "load")
        self.logger.info("%s: model %r loaded", self._label(), self.checkpoint)

    def _unload(self) -> None:
        response = self._request("POST", "/api/generate", "unload", json={"model": self.checkpoint, "keep_alive": 0,
                                                                          "stream": False})
        self._final_object(response, "unload")
        self.logger.info("%s: model %r unloaded", self._label(), self.checkpoint)

    # -- protocol details -----------------------------------------------------------------------------

    def _messages(self, query: Any) -> list[dict[str, Any]]:
        messages: list[dict[str, Any]] = []
        for message in checked_messages(query, self._label()):
            role = message["role"]
            out: dict[str, Any] = {"role": role, "content": message_text(message)}
            if message.get("images"):
                out["images"] = [image_to_base64_png(image) for image in message["images"]]
            if role == "assistant" and message.get("tool_calls"):
                # Ollama takes arguments as a JSON object (no ids): exactly the contract's dict.
                out["tool_calls"] = [{"function": {"name": call["function"]["name"],
                                                   "arguments": call["function"].get("arguments") or {}}}
                                     for call in message["tool_calls"]]
            if role == "tool" and message.get("name"):
                out["tool_name"] = str(message["name"])
            messages.append(out)
        return messages

    def _final_object(self, response: httpx.Response, what: str) -> dict[str, Any]:
        context = self._context(what)
        answer = self._json(response, what)
        if not isinstance(answer, dict):
            raise ProtocolError(f"{context}: expected a JSON object, got {str(answer)[:200]}")
        if "error" in answer:
            raise InferenceError(f"{context} failed: {answer['error']}")
        self._keep_stats(answer)
        return answer

    def _keep_stats(self, answer: dict[str, Any]) -> None:
        stats = {key: answer[key] for key in _STAT_KEYS if key in answer}
        if stats:
            self.last_stats = stats

    def _stream(self, path: str, body: dict[str, Any], what: str,
                text_of: Callable[[dict[str, Any]], str]) -> ChunkStream[str]:
        context = self._context(what)
        watch = self._watch(what, stream=True)
        response = self._open_stream("POST", path, what, watch, json=body)

        def chunks() -> Iterator[str]:
            # Blank lines (and anything else that is not an answer piece) do not reset the timers.
            for obj in iter_ndjson(response.iter_lines(), context, watch):
                if "error" in obj:
                    raise InferenceError(f"{context}: the server failed mid-stream: {obj['error']}")
                text = text_of(obj)
                if text:
                    yield text
                if obj.get("done"):
                    self._keep_stats(obj)
                    return
            # A clean end of body without "done": true means the answer was cut short.
            raise ProtocolError(f"{context}: the stream ended before the answer was done")

        return self._chunk_stream(chunks(), watch, context, on_close=response.close)


def _timed_lines(response: httpx.Response, watch: CallWatch) -> Iterator[str]:
    """The lines of a streamed body, each one a "chunk" of ``watch`` (a progress stream)."""
    lines = response.iter_lines()
    while True:
        watch.before_chunk()
        try:
            line = next(lines)
        except StopIteration:
            return
        watch.after_chunk()
        yield line


def _message_text(obj: dict[str, Any]) -> str:
    message = obj.get("message")
    return str(message.get("content") or "") if isinstance(message, dict) else ""


def _response_text(obj: dict[str, Any]) -> str:
    return str(obj.get("response") or "")


def _tool_call(call: Any, position: int) -> dict[str, Any]:
    function = call.get("function") if isinstance(call, dict) else None
    if not isinstance(function, dict):
        raise ProtocolError(f"an Ollama tool call needs a 'function' object, got {str(call)[:200]}")
    # Ollama sends no call id (recent versions send function.index); ids are made from the index.
    index = function.get("index")
    index = index if isinstance(index, int) and not isinstance(index, bool) else position
    name = function.get("name")
    return make_tool_call(name if isinstance(name, str) else "", function.get("arguments"), call.get("id"), index)
