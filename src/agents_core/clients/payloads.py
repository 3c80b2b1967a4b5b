"""The shapes every model client and local model agrees on, and helpers to build them.

Components build an *inference input* dict and clients translate it to their server's protocol;
this module is the one place those shapes are written down.

Chat (LLM / MLLM) input::

    {
        "query": [                                 # the conversation, oldest first
            {"role": "system", "content": "You are a robot."},
            {"role": "user", "content": "What do you see?",
             "images": [ndarray(H, W, 3) uint8 RGB, ...]},     # optional, MLLM only
            {"role": "assistant", "content": "", "tool_calls": [ToolCall dict, ...]},
            {"role": "tool", "content": "42", "tool_call_id": "call_0", "name": "add"},
        ],
        "stream": False,                           # True: "output" is a ChunkStream of str
        "tools": [{"type": "function", "function": {"name", "description", "parameters"}}],  # optional
        "temperature": 0.7, "max_new_tokens": 500, ...  # the component's inference params
    }

Chat output::

    {"output": str | ChunkStream, "tool_calls": [ToolCall dict, ...]}   # tool_calls only when asked for

A *ToolCall dict* is ``{"id": str, "type": "function", "function": {"name": str, "arguments": dict}}``:
arguments are always a parsed dict (clients parse the JSON string some servers send, and raise
:class:`~agents_core.errors.ProtocolError` when it is not JSON). When ``tools`` are given, a
client may answer without streaming: ``output`` is then a str.

Other inputs: speech synthesis ``{"query": str, "voice": ...}`` → ``{"output": bytes}`` (an
audio file, WAV unless the server says otherwise); transcription ``{"query": bytes | ndarray}``
→ ``{"output": str}``; embeddings go through :meth:`ModelClient.embed`.

Streaming: ``output`` is a :class:`ChunkStream`, an iterator of chunks that turns any failure
while reading into a typed error and releases the connection when closed early (a component
cancelling a stream calls ``close()``). A stream runs under its client's limits
(:class:`~agents_core.clients.deadline.CallWatch`): the whole stream within ``inference_timeout``,
the first chunk within ``stream_first_chunk_timeout`` and each later one within
``stream_chunk_timeout``; passing one raises :class:`~agents_core.errors.InferenceTimeoutError`
from ``next()``. Error messages never show the client's secrets.
"""

from __future__ import annotations

import base64
import contextlib
import json
import struct
import zlib
from collections.abc import Callable, Iterable, Iterator
from typing import Any, Generic, TypeVar

import httpx
import numpy as np

from ..errors import ClientConnectionError, InferenceConnectionError, InferenceError, ModelClientError, ProtocolError
from ..support.concurrency import CloseOnce
from .client_base import map_client_exception, scrub_exception
from .deadline import CallWatch

__all__ = [
    "CHAT_ROLES",
    "ChunkStream",
    "checked_messages",
    "checked_tool_calls",
    "encode_png",
    "image_to_base64_png",
    "image_to_data_uri",
    "make_tool_call",
    "message_text",
    "parse_tool_arguments",
]

#: The roles a chat message may have.
CHAT_ROLES = ("system", "user", "assistant", "tool")

T = TypeVar("T")


class ChunkStream(Generic[T]):
    """An iterator of streamed chunks (text or audio) with clean cancellation.

    :param chunks: the iterator producing chunks (typically a generator reading the response).
    :param on_close: called once when the stream ends, fails or is closed early (releases the
        connection).
    :param label: names the client and operation in error messages.
    :param watch: the call's limits (whole-call deadline, first-chunk and between-chunk timers);
        None: the stream is not timed here.
    :param secrets: values masked with ``***`` in the errors raised (the client's API key...).

    Each item the iterator yields is a chunk: the chunk timers run while the consumer waits in
    ``next()``, and only a yielded chunk stops them.
    """

    def __init__(self, chunks: Iterator[T], on_close: Callable[[], None] | None = None,
                 label: str = "stream", watch: CallWatch | None = None, secrets: Iterable[str] = ()) -> None:
        self._chunks = chunks
        self._on_close = on_close
        self._label = label
        self._watch = watch
        self._secrets = tuple(secrets)
        self._close_once = CloseOnce()
        self.chunk_count = 0

    def __iter__(self) -> ChunkStream[T]:
        return self

    def __next__(self) -> T:
        if self._close_once.closed:
            raise StopIteration
        watch = self._watch
        try:
            if watch is not None:
                watch.before_chunk()
            chunk = next(self._chunks)
        except StopIteration:
            self.close()
            if watch is not None and watch.fired is not None:
                # The watchdog cut a body delimited by the connection's close: its end is the cut,
                # not the answer's (the stream is truncated).
                raise scrub_exception(watch.error(), self._secrets) from None
            raise
        except Exception as exc:
            self.close()
            error = self._error(exc)
            if error is exc:
                raise
            raise error from exc
        if watch is not None:
            watch.after_chunk()
        self.chunk_count += 1
        return chunk

    def _error(self, exc: Exception) -> ModelClientError:
        watch = self._watch
        if watch is not None and (watch.fired is not None or (isinstance(exc, TimeoutError | httpx.TimeoutException)
                                                            and watch.passed())):
            # The watchdog cut the connection (the read then fails in any way), or a read timed
            # out at the limit: say which limit, not what the cut looked like.
            error: ModelClientError = watch.error()
        elif isinstance(exc, ModelClientError):
            error = exc
        else:
            error = map_client_exception(f"{self._label}: reading the stream", exc)
        if isinstance(error, ClientConnectionError):
            # A stream is an inference: the server going away under it is an inference's failure.
            error = InferenceConnectionError.from_connection_error(error)
        if error is not exc:
            error.__cause__ = exc
        return scrub_exception(error, self._secrets)

    def close(self) -> None:
        """Stop reading and release the connection (idempotent)."""
        if not self._close_once.claim():
            return
        if self._watch is not None:
            # First: a limit passing now must not cut a connection being handed back.
            self._watch.close()
        close = getattr(self._chunks, "close", None)
        try:
            if callable(close):
                close()
        finally:
            if self._on_close is not None:
                self._on_close()

    @property
    def closed(self) -> bool:
        return self._close_once.closed

    def __enter__(self) -> ChunkStream[T]:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:
        # A stream dropped half-read must not keep a socket open.
        with contextlib.suppress(Exception):
            self.close()


def checked_messages(query: Any, label: str) -> list[dict[str, Any]]:
    """The chat messages of an inference input's ``query``, each checked to have a known role.

    A str is taken as one user message. ``label`` names the client in the error.
    """
    if isinstance(query, str):
        query = [{"role": "user", "content": query}]
    if not isinstance(query, list) or not query:
        raise InferenceError(f"{label}: 'query' must be a non-empty list of chat messages or a str")
    for message in query:
        role = message.get("role") if isinstance(message, dict) else None
        if role not in CHAT_ROLES:
            raise InferenceError(f"{label}: a chat message needs a role in {CHAT_ROLES}, got {message!r:.200}")
    return query


def message_text(message: dict[str, Any]) -> str:
    """A message's text content ("" when it has none)."""
    content = message.get("content")
    return "" if content is None else str(content)


def _check_image(image: Any) -> np.ndarray:
    array = np.asarray(image)
    if array.dtype != np.uint8 or array.ndim not in (2, 3) or (array.ndim == 3 and array.shape[2] not in (1, 3, 4)):
        raise InferenceError(f"an image must be a uint8 array (H, W), (H, W, 3) or (H, W, 4); "
                             f"got dtype {array.dtype} shape {array.shape}")
    return array


def encode_png(image: Any) -> bytes:
    """Encode a uint8 RGB / RGBA / grayscale array as PNG (lossless, no imaging library needed)."""
    array = np.ascontiguousarray(_check_image(image))
    if array.ndim == 3 and array.shape[2] == 1:
        array = array[:, :, 0]
    height, width = array.shape[:2]
    color_type = {2: 0, 3: {3: 2, 4: 6}.get(array.shape[-1], 2)}[array.ndim]
    # Filter byte 0 (none) before each row; zlib level 1 keeps a 640x480 image around 10 ms.
    rows = np.concatenate([np.zeros((height, 1), np.uint8), array.reshape(height, -1)], axis=1)
    raw = zlib.compress(rows.tobytes(), 1)

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", width, height, 8, color_type, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", raw) + chunk(b"IEND", b"")


def image_to_base64_png(image: Any) -> str:
    """Base64 text of the PNG encoding (what Ollama and RoboML take)."""
    return base64.b64encode(encode_png(image)).decode("ascii")


def image_to_data_uri(image: Any) -> str:
    """A ``data:image/png;base64,...`` URI (what OpenAI-compatible servers take)."""
    return "data:image/png;base64," + image_to_base64_png(image)


def parse_tool_arguments(arguments: Any, tool_name: str = "?") -> dict[str, Any]:
    """Tool-call arguments as a dict, whether the server sent a dict or a JSON string."""
    if arguments is None or arguments == "":
        return {}
    if isinstance(arguments, dict):
        return arguments
    if isinstance(arguments, str):
        try:
            parsed = json.loads(arguments)
        except json.JSONDecodeError as exc:
            raise ProtocolError(f"tool call {tool_name!r}: arguments are not JSON: {arguments[:200]!r}") from exc
        if isinstance(parsed, dict):
            return parsed
    raise ProtocolError(f"tool call {tool_name!r}: arguments must be a JSON object, got {arguments!r:.200}")


def checked_tool_calls(calls: Any, context: str, parse: Callable[[Any, int], dict[str, Any]]) -> list[dict[str, Any]]:
    """The ToolCall dicts of a server's ``tool_calls`` list (None: none), each made by ``parse(call, index)``.

    Anything but a list raises :class:`~agents_core.errors.ProtocolError`; ``context`` names the
    client and operation.
    """
    calls = calls or []
    if not isinstance(calls, list):
        raise ProtocolError(f"{context}: tool_calls must be a list, got {str(calls)[:200]}")
    return [parse(call, index) for index, call in enumerate(calls)]


def make_tool_call(name: str, arguments: Any, call_id: str | None, index: int = 0) -> dict[str, Any]:
    """A ToolCall dict; servers that send no id (Ollama) get ``call_<index>``."""
    if not isinstance(name, str) or not name:
        raise ProtocolError(f"a tool call needs a function name, got {name!r}")
    return {"id": call_id or f"call_{index}", "type": "function",
            "function": {"name": name, "arguments": parse_tool_arguments(arguments, name)}}
