"""``GenericHTTPClient``: any server speaking the OpenAI HTTP API (OpenAI, vLLM, llama.cpp, LM Studio, ...).

What it sends depends on the model it serves:

- :class:`~agents_core.models.GenericLLM` / :class:`~agents_core.models.GenericMLLM`: chat
  completions (``POST {base_path}/chat/completions``), plain or streamed as server-sent events,
  with tools and images; embeddings through ``POST {base_path}/embeddings``.
- :class:`~agents_core.models.GenericTTS`: ``POST {base_path}/audio/speech``; the answer is the
  audio file's bytes.
- :class:`~agents_core.models.GenericSTT`: ``POST {base_path}/audio/transcriptions`` (multipart
  upload); the answer is the text.

The API key is sent as ``Authorization: Bearer <key>``. It comes from the ``api_key`` argument,
or, when that is None, from the ``OPENAI_API_KEY`` environment variable of the process making
the request (read when the connection is checked or opened, never in the constructor). Only an
explicit key is part of :meth:`serialize` (a component rebuilt in another process then reads the
variable from its own environment); ``repr()`` and logs never show it.

The module also holds the small HTTP helpers the Ollama client shares (server error messages,
status checks, JSON decoding).
"""

from __future__ import annotations

import io
import json
import os
import wave
from collections.abc import Iterator, MutableMapping
from typing import Any

import httpx
import numpy as np

from ..errors import ConfigError, HTTPStatusError, InferenceError, ProtocolError
from ..models import OPENAI_CHAT_OPTIONS, GenericSTT, GenericTTS, Model, model_types
from .deadline import BoundedHTTP
from .model_base import ModelClient
from .payloads import ChunkStream, checked_messages, image_to_data_uri, make_tool_call, message_text

__all__ = [
    "GenericHTTPClient",
    "audio_to_upload",
    "check_response",
    "iter_sse_data",
    "response_json",
    "server_error_message",
]

#: The environment variable read when no ``api_key`` is given.
API_KEY_ENV = "OPENAI_API_KEY"

#: Keys of a chat inference input that are not sampling parameters.
_CHAT_CONTROL_KEYS = frozenset({"query", "stream", "tools"})
#: Request fields beyond the model's sampling options that a chat request may carry.
_CHAT_EXTRA_KEYS = frozenset({"tool_choice", "parallel_tool_calls", "user"})
#: Default sample rate assumed for audio given without one (what robot microphones usually give).
_DEFAULT_SAMPLE_RATE = 16000


# -- HTTP helpers shared with the Ollama client ------------------------------------------------------


def server_error_message(response: httpx.Response) -> str:
    """The server's own error text from an error response.

    Understands OpenAI's ``{"error": {"message": ...}}``, Ollama's ``{"error": "..."}`` and
    FastAPI's ``{"detail": ...}``; anything else is returned as (shortened) text.
    """
    try:
        text = response.text
    except httpx.ResponseNotRead:
        try:
            response.read()
            text = response.text
        except Exception:  # the connection failed while reading the error body
            return "(no body)"
    try:
        body = json.loads(text)
    except ValueError:
        return text[:500] or response.reason_phrase
    if isinstance(body, dict):
        error = body.get("error")
        if isinstance(error, dict) and isinstance(error.get("message"), str):
            return str(error["message"])
        if isinstance(error, str):
            return error
        detail = body.get("detail")
        if isinstance(detail, str):
            return detail
        if detail is not None:
            return json.dumps(detail)[:500]
    return text[:500]


def check_response(response: httpx.Response, context: str) -> None:
    """Raise :class:`~agents_core.errors.HTTPStatusError` (with the server's message) unless 2xx.

    ``context`` names the client and operation ("GenericHTTPClient at h:p: chat").
    """
    if response.is_success:
        return
    message = server_error_message(response)
    raise HTTPStatusError(f"{context}: server answered {response.status_code} {response.reason_phrase}: {message}",
                          status=response.status_code)


def response_json(response: httpx.Response, context: str) -> Any:
    """The decoded JSON body, or :class:`~agents_core.errors.ProtocolError` when it is not JSON."""
    try:
        return response.json()
    except ValueError as exc:
        raise ProtocolError(f"{context}: the answer is not JSON: {response.text[:200]!r}") from exc


def iter_sse_data(lines: Iterator[str]) -> Iterator[str]:
    """The ``data`` of each server-sent event in ``lines`` (the text/event-stream format).

    Consecutive ``data:`` lines of one event are joined with newlines; comment lines (``:``,
    used for keep-alive pings) and the ``event``/``id``/``retry`` fields are skipped, since the
    OpenAI protocol carries everything in ``data``.
    """
    data: list[str] = []
    for line in lines:
        if not line:
            if data:
                yield "\n".join(data)
                data = []
            continue
        if line.startswith(":"):
            continue
        name, _, value = line.partition(":")
        if name == "data":
            data.append(value[1:] if value.startswith(" ") else value)
    if data:
        yield "\n".join(data)


_AUDIO_MAGIC: tuple[tuple[bytes, int, str, str], ...] = (
    (b"RIFF", 0, "audio.wav", "audio/wav"),
    (b"ID3", 0, "audio.mp3", "audio/mpeg"),
    (b"OggS", 0, "audio.ogg", "audio/ogg"),
    (b"fLaC", 0, "audio.flac", "audio/flac"),
    (b"\x1aE\xdf\xa3", 0, "audio.webm", "audio/webm"),
    (b"ftyp", 4, "audio.m4a", "audio/mp4"),
)


def _wav_bytes(pcm: np.ndarray, sample_rate: int) -> bytes:
    channels = 1 if pcm.ndim == 1 else int(pcm.shape[1])
    buffer = io.BytesIO()
    with wave.open(buffer, "wb") as wav:
        wav.setnchannels(channels)
        wav.setsampwidth(2)
        wav.setframerate(sample_rate)
        wav.writeframes(np.ascontiguousarray(pcm, dtype="<i2").tobytes())
    return buffer.getvalue()


def audio_to_upload(audio: Any, sample_rate: int = _DEFAULT_SAMPLE_RATE) -> tuple[str, bytes, str]:
    """``(filename, data, mime type)`` for uploading ``audio`` to a transcription endpoint.

    Bytes that start like a known audio file (WAV, MP3, Ogg, FLAC, WebM, MP4) are sent as they
    are. Other bytes are taken as raw 16-bit little-endian mono PCM (what microphone topics carry)
    and wrapped in a WAV header. A numpy array of int16, or of floats in [-1, 1], shaped
    ``(frames,)`` or ``(frames, channels)``, becomes a 16-bit WAV file.
    """
    if isinstance(sample_rate, bool) or not isinstance(sample_rate, int) or sample_rate <= 0:
        raise InferenceError(f"sample_rate must be a positive int, got {sample_rate!r}")
    if isinstance(audio, bytes | bytearray | memoryview):
        data = bytes(audio)
        for magic, offset, filename, mime in _AUDIO_MAGIC:
            if data[offset:offset + len(magic)] == magic:
                return filename, data, mime
        if len(data) % 2:
            raise InferenceError("audio bytes are neither a known audio file nor 16-bit PCM (odd length)")
        return "audio.wav", _wav_bytes(np.frombuffer(data, dtype="<i2"), sample_rate), "audio/wav"
    array = np.asarray(audio)
    if array.ndim not in (1, 2) or array.size == 0:
        raise InferenceError(f"audio must be a non-empty (frames,) or (frames, channels) array, "
                             f"got shape {array.shape}")
    if array.dtype == np.int16:
        pcm = array
    elif np.issubdtype(array.dtype, np.floating):
        pcm = np.round(np.clip(array, -1.0, 1.0) * 32767.0).astype(np.int16)
    else:
        raise InferenceError(f"audio arrays must be int16 or float in [-1, 1], got {array.dtype}")
    return "audio.wav", _wav_bytes(pcm, sample_rate), "audio/wav"


# -- the client -------------------------------------------------------------------------------------


class GenericHTTPClient(ModelClient):
    """Client for any OpenAI-compatible HTTP server.

    :param model: a :class:`~agents_core.models.GenericLLM`, ``GenericMLLM``, ``GenericTTS`` or
        ``GenericSTT`` (or its serialized dict); its ``checkpoint`` is the ``model`` id sent.
    :param host: server host name or address.
    :param port: server port.
    :param inference_timeout: seconds a whole call may take, connect to last byte (a streamed
        answer included); see :class:`~agents_core.clients.model_base.ModelClient` for
        ``stream_first_chunk_timeout`` and ``stream_chunk_timeout``, also accepted here.
    :param api_key: sent as a Bearer token; None reads ``OPENAI_API_KEY`` at request time (and an
        empty or unset variable sends no ``Authorization`` header, as local servers expect).
    :param base_path: the path the API lives under (``"/v1"`` for OpenAI and most servers).
    :param use_https: talk HTTPS instead of HTTP (hosted APIs).
    :param init_on_activation: open the connection during configure.
    :param logging_level: ``"debug"``, ``"info"``, ...
    """

    def __init__(
        self,
        model: Model | dict[str, Any],
        host: str = "127.0.0.1",
        port: int = 8000,
        inference_timeout: int | float = 30,
        api_key: str | None = None,
        base_path: str = "/v1",
        use_https: bool = False,
        init_on_activation: bool = True,
        logging_level: str = "info",
        **kwargs: Any,
    ) -> None:
        super().__init__(model=model, host=host, port=port, inference_timeout=inference_timeout,
                         init_on_activation=init_on_activation, logging_level=logging_level, **kwargs)
        if api_key is not None and (not isinstance(api_key, str) or not api_key):
            raise ConfigError(f"{type(self).__name__}: api_key must be a non-empty str or None")
        if not isinstance(base_path, str) or (base_path and not base_path.startswith("/")):
            raise ConfigError(f"{type(self).__name__}: base_path must be '' or start with '/', got {base_path!r}")
        self.api_key = api_key
        self.base_path = base_path.rstrip("/")
        self.use_https = bool(use_https)
        self.checkpoint = str(self.model_init_params.get("checkpoint") or self.model_name)
        #: The ``usage`` object of the last answer that had one (token counts).
        self.last_usage: dict[str, Any] | None = None
        self._client: BoundedHTTP | None = None

    # -- settings -------------------------------------------------------------------------------------

    @property
    def base_url(self) -> str:
        """``http(s)://host:port/base_path``."""
        scheme = "https" if self.use_https else "http"
        return f"{scheme}://{self.host}:{self.port}{self.base_path}"

    @property
    def kind(self) -> str:
        """``"chat"``, ``"tts"`` or ``"stt"``, from the model's class."""
        cls = model_types().get(self.model_type)
        if cls is not None and issubclass(cls, GenericTTS):
            return "tts"
        if cls is not None and issubclass(cls, GenericSTT):
            return "stt"
        return "chat"

    @property
    def supports_tool_calls(self) -> bool:
        """Chat models take tools; speech models do not."""
        return self.kind == "chat"

    def _headers(self) -> dict[str, str]:
        # Read the variable per connection, so a client rebuilt in another process uses that
        # process's environment and a serialized spec never has to carry the key.
        key = self.api_key if self.api_key is not None else os.environ.get(API_KEY_ENV) or None
        return {"Authorization": f"Bearer {key}"} if key else {}

    def _secrets(self) -> tuple[str, ...]:
        """The key sent: the explicit one, else the environment's."""
        key = self.api_key if self.api_key is not None else os.environ.get(API_KEY_ENV) or None
        return (key,) if key else ()

    def _http(self) -> BoundedHTTP:
        # Created lazily too: with init_on_activation=False inference must still work.
        if self._client is None:
            self._client = BoundedHTTP(self.base_url, headers=self._headers())
        return self._client

    def _request(self, method: str, path: str, context: str, **kwargs: Any) -> httpx.Response:
        """One request, its whole answer read within ``inference_timeout``."""
        return self._http().request(method, path, seconds=float(self.inference_timeout), label=context, **kwargs)

    def _context(self, what: str) -> str:
        return f"{self._label()}: {what}"

    # -- ModelClient ----------------------------------------------------------------------------------

    def _check_connection(self) -> None:
        """``GET {base_path}/models``; warns when the model id is not among those listed."""
        http = BoundedHTTP(self.base_url, headers=self._headers())
        try:
            response = http.request("GET", "/models", seconds=float(self.inference_timeout),
                                    label=self._context("listing models"))
            check_response(response, self._context("listing models"))
            body = response_json(response, self._context("listing models"))
        finally:
            http.close()
        data = body.get("data") if isinstance(body, dict) else None
        if not isinstance(data, list):
            raise ProtocolError(f"{self._context('listing models')}: expected {{'data': [...]}}, got {str(body)[:200]}")
        served = [item.get("id") for item in data if isinstance(item, dict)]
        if self.checkpoint not in served:
            # Some servers answer for any id (llama.cpp's uses its one model), so only warn.
            self.logger.warning("%s: model %r is not among the served models %s", self._label(), self.checkpoint,
                                served[:20])
        else:
            self.logger.info("%s: server reachable, model %r served", self._label(), self.checkpoint)

    def _initialize(self) -> None:
        """Open the HTTP connection pool (the server loads its models itself)."""
        self.close()
        self._http()
        self.logger.debug("%s: connection opened to %s", self._label(), self.base_url)

    def _deinitialize(self) -> None:
        """Close the connection pool."""
        self.close()

    def close(self) -> None:
        """Close the connection pool now (without telling the server anything); reopened on next use."""
        if self._client is not None:
            self._client.close()
            self._client = None

    def _inference(self, inference_input: dict[str, Any]) -> MutableMapping[str, Any] | None:
        kind = self.kind
        if kind == "tts":
            return self._speech(inference_input)
        if kind == "stt":
            return self._transcribe(inference_input)
        return self._chat(inference_input)

    def _embed(self, texts: list[str]) -> list[list[float]]:
        """``POST {base_path}/embeddings``; one vector per text, in input order."""
        context = self._context("embeddings")
        response = self._request("POST", "/embeddings", context, json={"model": self.checkpoint, "input": texts})
        check_response(response, context)
        body = response_json(response, context)
        data = body.get("data") if isinstance(body, dict) else None
        if not isinstance(data, list):
            raise ProtocolError(f"{context}: expected {{'data': [...]}}, got {str(body)[:200]}")
        self.last_usage = body.get("usage") if isinstance(body.get("usage"), dict) else None
        ordered = sorted(data, key=lambda item: item.get("index", 0) if isinstance(item, dict) else 0)
        vectors: list[list[float]] = []
        for item in ordered:
            vector = item.get("embedding") if isinstance(item, dict) else None
            if isinstance(vector, list) and vector and isinstance(vector[0], list):
                # llama.cpp does this for models without pooling: one vector per token.
                raise ProtocolError(f"{context}: the server sent one vector per token, not one per text; "
                                    f"start it with a pooling type (mean, cls, last)")
            if not isinstance(vector, list) or not all(isinstance(x, int | float) for x in vector):
                raise ProtocolError(f"{context}: an embedding must be a list of numbers, got {str(vector)[:200]}")
            vectors.append([float(x) for x in vector])
        return vectors

    def serialize(self) -> dict[str, Any]:
        """The base spec plus ``api_key`` (only one given explicitly), ``base_path`` and ``use_https``."""
        spec = super().serialize()
        spec["api_key"] = self.api_key
        spec["base_path"] = self.base_path
        spec["use_https"] = self.use_https
        return spec

    # -- chat -----------------------------------------------------------------------------------------

    def _messages(self, query: Any) -> list[dict[str, Any]]:
        messages: list[dict[str, Any]] = []
        for message in checked_messages(query, self._label()):
            role, content = message["role"], message_text(message)
            out: dict[str, Any] = {"role": role}
            images = message.get("images")
            if images:
                # OpenAI takes images as content parts holding data URIs, next to the text part.
                parts: list[dict[str, Any]] = [{"type": "text", "text": content}] if content else []
                parts += [{"type": "image_url", "image_url": {"url": image_to_data_uri(image)}} for image in images]
                out["content"] = parts
            else:
                out["content"] = content
            if role == "assistant" and message.get("tool_calls"):
                # The protocol carries arguments as a JSON string; the contract holds them as a dict.
                out["tool_calls"] = [
                    {"id": call["id"], "type": "function",
                     "function": {"name": call["function"]["name"],
                                  "arguments": json.dumps(call["function"].get("arguments") or {})}}
                    for call in message["tool_calls"]]
            if role == "tool":
                if not message.get("tool_call_id"):
                    raise InferenceError(f"{self._label()}: a tool message needs the 'tool_call_id' it answers")
                out["tool_call_id"] = str(message["tool_call_id"])
            messages.append(out)
        return messages

    def _chat_params(self, inference_input: dict[str, Any]) -> dict[str, Any]:
        params: dict[str, Any] = dict(self.model_init_params.get("options") or {})
        ignored: list[str] = []
        for key, value in inference_input.items():
            if key in _CHAT_CONTROL_KEYS or value is None:
                continue
            if key == "max_new_tokens":
                params["max_tokens"] = value
            elif key in OPENAI_CHAT_OPTIONS or key in _CHAT_EXTRA_KEYS:
                params[key] = value
            else:
                ignored.append(key)
        if ignored:
            self.logger.debug("%s: inference parameters not part of the protocol, not sent: %s", self._label(),
                              sorted(ignored))
        return params

    def _chat(self, inference_input: dict[str, Any]) -> MutableMapping[str, Any]:
        tools = inference_input.get("tools")
        body: dict[str, Any] = {"model": self.checkpoint, "messages": self._messages(inference_input.get("query")),
                                **self._chat_params(inference_input)}
        if tools:
            body["tools"] = tools
        # With tools the answer is read whole: tool-call arguments arrive in fragments when
        # streamed, and the contract lets a client answer a str then.
        if inference_input.get("stream") and not tools:
            body["stream"] = True
            return {"output": self._chat_stream(body)}
        context = self._context("chat")
        response = self._request("POST", "/chat/completions", context, json=body)
        check_response(response, context)
        answer = response_json(response, context)
        choices = answer.get("choices") if isinstance(answer, dict) else None
        if not isinstance(choices, list) or not choices or not isinstance(choices[0], dict) \
                or not isinstance(choices[0].get("message"), dict):
            raise ProtocolError(f"{context}: expected choices[0].message in the answer, got {str(answer)[:200]}")
        self.last_usage = answer.get("usage") if isinstance(answer.get("usage"), dict) else None
        message = choices[0]["message"]
        content = message.get("content")
        if content is not None and not isinstance(content, str):
            raise ProtocolError(f"{context}: message content must be a string, got {str(content)[:200]}")
        result: dict[str, Any] = {"output": content or ""}
        if tools:
            calls = message.get("tool_calls") or []
            if not isinstance(calls, list):
                raise ProtocolError(f"{context}: tool_calls must be a list, got {str(calls)[:200]}")
            result["tool_calls"] = [_tool_call(call, index) for index, call in enumerate(calls)]
        return result

    def _chat_stream(self, body: dict[str, Any]) -> ChunkStream[str]:
        context = self._context("chat stream")
        watch = self._watch("chat stream", stream=True)
        try:
            response = self._http().open("POST", "/chat/completions", watch, json=body)
        except BaseException:
            watch.close()
            raise
        try:
            check_response(response, context)
        except Exception as exc:
            watch.close()
            response.close()
            if watch.fired is not None:
                raise watch.error() from exc
            raise

        def lines() -> Iterator[str]:
            # Keep-alive comments and blank lines arrive here too: the deadline is checked on
            # every line, so they cannot keep the call alive.
            for line in response.iter_lines():
                watch.check()
                yield line

        def chunks() -> Iterator[str]:
            finished = False
            for data in iter_sse_data(lines()):
                if data == "[DONE]":
                    return
                try:
                    event = json.loads(data)
                except ValueError as exc:
                    raise ProtocolError(f"{context}: an event is not JSON: {data[:200]!r}") from exc
                if not isinstance(event, dict):
                    raise ProtocolError(f"{context}: an event is not a JSON object: {data[:200]!r}")
                if "error" in event:
                    # Servers report failures after the 200 status as an error event.
                    error = event["error"]
                    message = error.get("message") if isinstance(error, dict) else error
                    raise InferenceError(f"{context}: the server failed mid-stream: {message}")
                if isinstance(event.get("usage"), dict):
                    self.last_usage = event["usage"]
                for choice in event.get("choices") or []:
                    delta = choice.get("delta") or {}
                    text = delta.get("content")
                    if text:
                        yield str(text)
                    if choice.get("finish_reason"):
                        finished = True
            if not finished:
                # The body ended cleanly but the answer did not: a proxy or server cut it short.
                raise ProtocolError(f"{context}: the stream ended before the answer finished (no [DONE])")

        return self._chunk_stream(chunks(), watch, context, on_close=response.close)

    # -- speech -------------------------------------------------------------------------------------

    def _speech(self, inference_input: dict[str, Any]) -> MutableMapping[str, Any]:
        text = inference_input.get("query")
        if not isinstance(text, str) or not text.strip():
            raise InferenceError(f"{self._label()}: speech synthesis needs a non-empty str 'query'")
        params = self.model_init_params
        body = {
            "model": self.checkpoint,
            "input": text,
            "voice": inference_input.get("voice") or params.get("voice", "alloy"),
            "response_format": inference_input.get("response_format") or params.get("response_format", "wav"),
            "speed": inference_input.get("speed") or params.get("speed", 1.0),
        }
        context = self._context("speech")
        response = self._request("POST", "/audio/speech", context, json=body)
        check_response(response, context)
        if not response.content:
            raise InferenceError(f"{context}: the server returned no audio")
        return {"output": response.content}

    def _transcribe(self, inference_input: dict[str, Any]) -> MutableMapping[str, Any]:
        audio = inference_input.get("query")
        if audio is None:
            raise InferenceError(f"{self._label()}: transcription needs audio bytes or an array in 'query'")
        filename, data, mime = audio_to_upload(audio, inference_input.get("sample_rate", _DEFAULT_SAMPLE_RATE))
        params = self.model_init_params
        form: dict[str, str] = {"model": self.checkpoint, "response_format": "json",
                                "temperature": str(inference_input.get("temperature", params.get("temperature", 0.0)))}
        language = inference_input.get("language") or params.get("language")
        if language:
            form["language"] = str(language)
        if inference_input.get("prompt"):
            form["prompt"] = str(inference_input["prompt"])
        context = self._context("transcription")
        response = self._request("POST", "/audio/transcriptions", context, data=form,
                                 files={"file": (filename, data, mime)})
        check_response(response, context)
        body = response_json(response, context)
        if not isinstance(body, dict) or not isinstance(body.get("text"), str):
            raise ProtocolError(f"{context}: expected {{'text': ...}}, got {str(body)[:200]}")
        return {"output": body["text"]}


def _tool_call(call: Any, index: int) -> dict[str, Any]:
    function = call.get("function") if isinstance(call, dict) else None
    if not isinstance(function, dict):
        raise ProtocolError(f"a tool call needs a 'function' object, got {str(call)[:200]}")
    name = function.get("name")
    call_id = call.get("id")
    return make_tool_call(name if isinstance(name, str) else "", function.get("arguments"),
                          call_id if isinstance(call_id, str) else None, index)
