"""``GenericHTTPClient``: any server speaking the OpenAI HTTP API (OpenAI, vLLM, llama.cpp, LM Studio, ...).

What it sends depends on the model it serves:

- :class:`~agents_core.models.GenericLLM` / :class:`~agents_core.models.GenericMLLM`: chat
  completions (``POST {base_path}/chat/completions``), plain or streamed as server-sent events,
  with tools and images; embeddings through ``POST {base_path}/embeddings``.
- :class:`~agents_core.models.GenericTTS`: ``POST {base_path}/audio/speech``; the answer is the
  audio file's bytes.
- :class:`~agents_core.models.GenericSTT`: ``POST {base_path}/audio/transcriptions`` (multipart
  upload); the answer is the text.

Which of these a client does is decided once, by the model class's ``task``
(:attr:`agents_core.models.Model.task`), through ``GenericHTTPClient.task_handlers``.

The API key is sent as ``Authorization: Bearer <key>``. It comes from the ``api_key`` argument,
or, when that is None, from the ``OPENAI_API_KEY`` environment variable of the process making
the request (read when the connection is checked or opened, never in the constructor). Only an
explicit key is part of :meth:`serialize` (a component rebuilt in another process then reads the
variable from its own environment); ``repr()`` and logs never show it.
"""

from __future__ import annotations

import io
import json
import os
import wave
from collections.abc import Iterator, MutableMapping
from typing import Any, ClassVar

import numpy as np

from ..errors import ConfigError, InferenceError, ProtocolError
from ..models import OPENAI_CHAT_OPTIONS, Model
from .http_base import (
    HTTPClientBase,
    bearer,
    check_api_key,
    check_response,
    iter_sse_data,
    json_object,
    response_json,
    server_error_message,
    sse_data,
)
from .model_base import ModelClient
from .payloads import (
    ChunkStream,
    checked_messages,
    checked_tool_calls,
    image_to_data_uri,
    make_tool_call,
    message_text,
)

# check_response, iter_sse_data, response_json and server_error_message live in http_base now;
# they stay importable from here, where they were first.
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
#: What a chat request may carry from an inference input: the sampling options, and a few request fields.
_CHAT_PARAMS = frozenset(OPENAI_CHAT_OPTIONS) | {"tool_choice", "parallel_tool_calls", "user"}
#: Default sample rate assumed for audio given without one (what robot microphones usually give).
_DEFAULT_SAMPLE_RATE = 16000


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


class GenericHTTPClient(HTTPClientBase, ModelClient):
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

    #: The endpoint serving each model task (:attr:`agents_core.models.Model.task`).
    task_handlers: ClassVar[dict[str, str]] = {
        "chat": "_chat",
        "text_to_speech": "_speech",
        "speech_to_text": "_transcribe",
    }
    #: Only an ``api_key`` given explicitly is part of the spec (the environment's is read where it runs).
    spec_fields: ClassVar[tuple[str, ...]] = ("api_key", "base_path", "use_https")

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
        self.api_key = check_api_key(type(self).__name__, api_key)
        if not isinstance(base_path, str) or (base_path and not base_path.startswith("/")):
            raise ConfigError(f"{type(self).__name__}: base_path must be '' or start with '/', got {base_path!r}")
        self.base_path = base_path.rstrip("/")
        self.use_https = bool(use_https)
        self.checkpoint = str(self.model_init_params.get("checkpoint") or self.model_name)
        #: The ``usage`` object of the last answer that had one (token counts).
        self.last_usage: dict[str, Any] | None = None

    # -- settings -------------------------------------------------------------------------------------

    @property
    def kind(self) -> str:
        """``"chat"``, ``"tts"`` or ``"stt"``: the model's ``task`` under its older, shorter names."""
        return {"text_to_speech": "tts", "speech_to_text": "stt"}.get(self.task, "chat")

    @property
    def supports_tool_calls(self) -> bool:
        """Chat models take tools; speech models do not."""
        return self.task == "chat"

    def _key(self) -> str | None:
        # Read the variable per connection, so a client rebuilt in another process uses that
        # process's environment and a serialized spec never has to carry the key.
        return self.api_key if self.api_key is not None else os.environ.get(API_KEY_ENV) or None

    def _headers(self) -> dict[str, str]:
        return bearer(self._key())

    def _secrets(self) -> tuple[str, ...]:
        """The key sent: the explicit one, else the environment's."""
        key = self._key()
        return (key,) if key else ()

    # -- ModelClient ----------------------------------------------------------------------------------

    def _check_connection(self) -> None:
        """``GET {base_path}/models``; warns when the model id is not among those listed."""
        body = self._request_json("GET", "/models", "listing models", fresh=True)
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
        self._pool()
        self.logger.debug("%s: connection opened to %s", self._label(), self.base_url)

    def _deinitialize(self) -> None:
        """Close the connection pool."""
        self.close()

    def _inference(self, inference_input: dict[str, Any]) -> MutableMapping[str, Any] | None:
        return self._task_handler()(inference_input)

    def _embed(self, texts: list[str]) -> list[list[float]]:
        """``POST {base_path}/embeddings``; one vector per text, in input order."""
        context = self._context("embeddings")
        body = self._request_json("POST", "/embeddings", "embeddings", json={"model": self.checkpoint, "input": texts})
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
                                    "start it with a pooling type: llama_cpp.server --kv_overrides "
                                    "llama.pooling_type=int:1 (mean), llama.cpp's llama-server --pooling mean; "
                                    "`python -m agents_core.example_servers --print` shows the whole command")
            if not isinstance(vector, list) or not all(isinstance(x, int | float) for x in vector):
                raise ProtocolError(f"{context}: an embedding must be a list of numbers, got {str(vector)[:200]}")
            vectors.append([float(x) for x in vector])
        return vectors

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

    def _chat(self, inference_input: dict[str, Any]) -> MutableMapping[str, Any]:
        tools = inference_input.get("tools")
        body: dict[str, Any] = {"model": self.checkpoint, "messages": self._messages(inference_input.get("query")),
                                **self._call_options(inference_input, skip=_CHAT_CONTROL_KEYS,
                                                     known=_CHAT_PARAMS, max_tokens="max_tokens")}
        if tools:
            body["tools"] = tools
        # With tools the answer is read whole: tool-call arguments arrive in fragments when
        # streamed, and the contract lets a client answer a str then.
        if inference_input.get("stream") and not tools:
            body["stream"] = True
            return {"output": self._chat_stream(body)}
        context = self._context("chat")
        answer = self._request_json("POST", "/chat/completions", "chat", json=body)
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
            result["tool_calls"] = checked_tool_calls(message.get("tool_calls"), context, _tool_call)
        return result

    def _chat_stream(self, body: dict[str, Any]) -> ChunkStream[str]:
        context = self._context("chat stream")
        watch = self._watch("chat stream", stream=True)
        response = self._open_stream("POST", "/chat/completions", "chat stream", watch, json=body)

        def chunks() -> Iterator[str]:
            finished = False
            # Keep-alive comments are no events: they never count as chunks, and the watchdog
            # cuts a stream of nothing but them at its limit.
            for data in sse_data(response, context, watch):
                if data == "[DONE]":
                    return
                event = json_object(data, context, "an event")
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
        response = self._request("POST", "/audio/speech", "speech", json=body)
        if not response.content:
            raise InferenceError(f"{self._context('speech')}: the server returned no audio")
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
        body = self._request_json("POST", "/audio/transcriptions", "transcription", data=form,
                                  files={"file": (filename, data, mime)})
        if not isinstance(body, dict) or not isinstance(body.get("text"), str):
            raise ProtocolError(f"{self._context('transcription')}: expected {{'text': ...}}, got {str(body)[:200]}")
        return {"output": body["text"]}


def _tool_call(call: Any, index: int) -> dict[str, Any]:
    function = call.get("function") if isinstance(call, dict) else None
    if not isinstance(function, dict):
        raise ProtocolError(f"a tool call needs a 'function' object, got {str(call)[:200]}")
    name = function.get("name")
    call_id = call.get("id")
    return make_tool_call(name if isinstance(name, str) else "", function.get("arguments"),
                          call_id if isinstance(call_id, str) else None, index)
