"""RoboML's wire protocol and node lifecycle, shared by the RoboML HTTP, WebSocket and RESP clients.

Written from the source of RoboML 0.6.1 (``roboml/ray/app_factory.py``, ``roboml/ray/node.py``,
``roboml/resp_server/server.py``, ``roboml/interfaces.py``, ``roboml/models/``). What the
clients rely on:

* **Nodes.** A model runs in a *node* named by the client (here: the model's ``name``) and built
  from one of RoboML's model classes (:data:`ROBOML_NODE_MODELS`). Lifecycle: add the node, then
  initialize it with the model's init parameters, run inferences, remove the node.
* **HTTP** (Ray Serve + FastAPI, default port 8000): ``GET /`` (server info);
  ``POST /add_node?node_name=..&node_model=..`` → 201 ``{"node": name}`` (a name already in use
  also answers 201, with a ``"warning"``; an unknown model class 400); ``POST
  /remove_node?node_name=..`` → 202; ``POST /<node>/initialize`` with the init parameters as the
  JSON body → 200 ``null`` when loaded, 500 ``{"detail": "Initialization Error: ..."}``;
  ``POST /<node>/inference`` with the input as the JSON body → 200 with the result dict, or a
  ``text/plain`` stream of tokens when the input asks to stream; errors are 400 (input
  validation, ``detail`` is pydantic's error list) or 500 (``detail`` is the message);
  ``GET /<node>/get_status`` → ``"READY"`` etc.
* **WebSocket** ``/<node>/ws_inference`` on the HTTP port: the client sends one binary frame per
  request, a msgpack map of the input. A streamed reply is text frames (tokens) followed by the
  text frame ``"<<Response Ended>>"``; any other reply is the result's ``output`` alone: a text
  frame for str, a binary frame of raw bytes for bytes, a binary frame of msgpack for anything
  else. Replies over 1 MiB (:data:`WS_CHUNK_SIZE`) are split into several frames with no end
  marker. There are no request ids: one connection serves one request at a time, in order. An
  invalid input or a failing model closes the connection with code 1007 and the error as reason.
* **RESP** (RoboML's own RESP2 server, default port 6379): commands ``PING``, ``CLIENT ..``
  (always ``+OK``), ``QUIT``, ``add_node``, ``remove_node``, and once a node exists
  ``<node>.initialize``, ``<node>.inference``, ``<node>.get_status``. The only argument is a
  msgpack map of keyword arguments (omitted for none: the server never answers an *empty* map).
  Replies: ``+OK`` for an empty result, else a bulk string of msgpack; errors ``-VALIDATION_ERROR
  ..``, ``-UNEXPECTED_ERROR "<json str>"``, ``-ERR Error loading the extension..`` (unknown model
  class), ``-INVALID_COMMAND``, ``-INVALID_ARGS``. The server does not speak RESP3 (``HELLO`` is an
  invalid command) and runs each command on a thread pool, so one connection must not pipeline.
* **Arrays.** Both msgpack paths are patched with msgpack-numpy: an ndarray is the map
  ``{b"nd": True, b"type": dtype.str, b"kind": b"", b"shape": [...], b"data": raw bytes}``
  (:func:`packb` / :func:`unpackb` here speak that format without the package; arrays of Python
  objects, which msgpack-numpy pickles, are refused both ways). Over JSON images go as base64
  PNG and audio as base64 16-bit PCM, which RoboML decodes. Audio
  arrays are sent as 16-bit PCM bytes on every transport (see :func:`build_roboml_input`).

The RoboML model classes and what their inputs hold (``roboml/interfaces.py``):
``TransformersLLM`` (query messages, max_new_tokens, temperature, stream), ``TransformersMLLM``
(the same plus images), ``RoboBrain2`` (the same plus task, enable_thinking; never streams),
``Whisper`` (query audio, language, initial_prompt, vad_filter, word_timestamps,
max_new_tokens), ``TransformersTTS`` (query text, voice, get_bytes), ``VisionModel`` (images,
threshold, get_dataset_labels, labels_to_track).
"""

from __future__ import annotations

import base64
import binascii
import logging
import re
import time
from collections.abc import Callable, Iterable, Iterator
from typing import Any, ClassVar, Final, TypeVar

import msgpack  # type: ignore[import-untyped]  # msgpack ships no type information
import numpy as np

from ..errors import ConfigError, InferenceError, ProtocolError
from ..models import (
    Model,
    RoboBrain2,
    TransformersLLM,
    TransformersMLLM,
    TransformersTTS,
    VisionModel,
    Whisper,
    model_types,
)
from .model_base import ModelClient
from .payloads import ChunkStream, image_to_base64_png

__all__ = [
    "RESPONSE_ENDED",
    "ROBOML_NODE_MODELS",
    "STREAMING_NODE_MODELS",
    "WS_CHUNK_SIZE",
    "RoboMLNodeClient",
    "build_roboml_input",
    "check_node_name",
    "normalize_result",
    "packb",
    "resolve_node_model",
    "retry_connect",
    "single_chunk_stream",
    "unpackb",
]

#: RoboML 0.6.1's model classes (``roboml.models.__all__``), each with the task of the model class of
#: the same name here (:attr:`agents_core.models.Model.task`): the kind of input its node takes.
ROBOML_NODE_MODELS: Final[dict[str, str]] = {
    cls.__name__: cls.task
    for cls in (TransformersLLM, TransformersMLLM, RoboBrain2, Whisper, TransformersTTS, VisionModel)
}

#: Node models whose inference streams tokens when the input says ``stream: true``.
STREAMING_NODE_MODELS: Final[frozenset[str]] = frozenset({"TransformersLLM", "TransformersMLLM"})

#: The text frame that ends a streamed WebSocket reply.
RESPONSE_ENDED: Final[str] = "<<Response Ended>>"

#: RoboML splits a WebSocket reply larger than this into several frames (bytes, or characters for text).
WS_CHUNK_SIZE: Final[int] = 1024 * 1024

# A node name is a URL path prefix over HTTP and the part before "." of RESP command names.
_NODE_NAME = re.compile(r"^[A-Za-z0-9_-]+$")

T = TypeVar("T")

_CHAT_OPTIONS = ("max_new_tokens", "temperature")
_PLANNING_OPTIONS = ("task", "enable_thinking")
_STT_OPTIONS = ("max_new_tokens", "initial_prompt", "language", "vad_filter", "word_timestamps")
_DETECTION_OPTIONS = ("threshold", "get_dataset_labels", "labels_to_track")


# -- node identity ------------------------------------------------------------------------------


def check_node_name(client: str, name: str) -> str:
    """The node name for a model name, or :class:`ConfigError` if RoboML could not route it."""
    if not _NODE_NAME.match(name):
        raise ConfigError(f"{client}: model name {name!r} cannot name a RoboML node; use letters, digits, "
                          "'_' and '-' only (it becomes a URL path prefix and a RESP command prefix)")
    return name


def resolve_node_model(client: str, model_type: str) -> str:
    """The RoboML model class that serves ``model_type`` (a class of :mod:`agents_core.models`).

    A subclass of a RoboML model (a user's ``TransformersLLM`` with other defaults) is served by
    that RoboML class. Raises :class:`ConfigError` for models RoboML does not serve.
    """
    if model_type in ROBOML_NODE_MODELS:
        return model_type
    cls = model_types().get(model_type)
    if cls is not None:
        for base in cls.__mro__:
            if base.__name__ in ROBOML_NODE_MODELS:
                return base.__name__
        raise ConfigError(f"{client}: RoboML cannot serve a {model_type}; use one of {sorted(ROBOML_NODE_MODELS)} "
                          "or a client for that model's platform")
    raise ConfigError(f"{client}: unknown model type {model_type!r}; import the module that defines it first "
                      f"(RoboML serves {sorted(ROBOML_NODE_MODELS)})")


# -- msgpack with msgpack-numpy's array format ----------------------------------------------------


def _encode_numpy(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        if obj.dtype.kind in "OV":
            raise InferenceError(f"arrays of dtype {obj.dtype} cannot be sent to RoboML (numbers only)")
        array = np.ascontiguousarray(obj)
        return {b"nd": True, b"type": array.dtype.str, b"kind": b"", b"shape": list(array.shape),
                b"data": array.tobytes()}
    if isinstance(obj, np.bool_ | np.number):
        return {b"nd": False, b"type": obj.dtype.str, b"data": obj.tobytes()}
    raise InferenceError(f"a {type(obj).__name__} cannot be sent to RoboML")


def _decode_numpy(obj: dict[Any, Any]) -> Any:
    if b"nd" not in obj:
        if obj.get(b"complex") is True:
            return complex(obj[b"data"].decode() if isinstance(obj[b"data"], bytes) else obj[b"data"])
        return obj
    try:
        if obj.get(b"kind", b"") not in (b"", ""):
            # 'O' would be a pickle (never loaded from a server), 'V' a structured array.
            raise ProtocolError(f"RoboML sent an array of kind {obj[b'kind']!r}, which this client does not load")
        dtype = np.dtype(obj[b"type"])
        if obj[b"nd"] is True:
            return np.frombuffer(obj[b"data"], dtype=dtype).reshape(obj[b"shape"]).copy()
        return np.frombuffer(obj[b"data"], dtype=dtype)[0]
    except (KeyError, TypeError, ValueError) as exc:
        raise ProtocolError(f"RoboML sent a malformed array: {exc}") from exc


def packb(obj: Any) -> bytes:
    """msgpack bytes of ``obj``, ndarrays and numpy scalars in msgpack-numpy's format."""
    data: bytes = msgpack.packb(obj, default=_encode_numpy, use_bin_type=True)
    return data


def unpackb(data: bytes) -> Any:
    """Decode msgpack from RoboML (arrays become ndarrays); :class:`ProtocolError` if it is not msgpack."""
    try:
        return msgpack.unpackb(data, object_hook=_decode_numpy, raw=False)
    except ProtocolError:
        raise
    except Exception as exc:
        raise ProtocolError(f"RoboML sent a payload that is not msgpack: {type(exc).__name__}: {exc}") from exc


# -- inference inputs -----------------------------------------------------------------------------


def _copy_options(source: dict[str, Any], target: dict[str, Any], keys: tuple[str, ...]) -> None:
    # Only values that are set: RoboML's input models give defaults, and None is not one of them.
    for key in keys:
        if source.get(key) is not None:
            target[key] = source[key]


def _encode_images(images: list[Any], binary: bool) -> list[Any]:
    # RoboML takes list[str] (base64 encoded image files) or list[ndarray], never a mix.
    if binary and all(isinstance(img, np.ndarray) for img in images):
        for img in images:
            if img.ndim not in (2, 3):
                raise InferenceError(f"an image must be an (H, W) or (H, W, C) array, got shape {img.shape}")
        return list(images)
    encoded = []
    for img in images:
        if isinstance(img, str):
            encoded.append(img)  # already base64 text
        elif isinstance(img, bytes | bytearray):
            encoded.append(base64.b64encode(bytes(img)).decode("ascii"))  # an encoded image file
        else:
            encoded.append(image_to_base64_png(img))
    return encoded


def _chat_input(node_model: str, inference_input: dict[str, Any], binary: bool) -> tuple[dict[str, Any], bool]:
    query = inference_input.get("query")
    if isinstance(query, str):
        query = [{"role": "user", "content": query}]
    if not isinstance(query, list) or not query:
        raise InferenceError(f"a {node_model} inference needs 'query': a non-empty list of chat messages")
    messages: list[dict[str, Any]] = []
    images: list[Any] = []
    for message in query:
        if not isinstance(message, dict) or not isinstance(message.get("role"), str):
            raise InferenceError(f"a chat message must be a dict with a 'role', got {message!r:.200}")
        content = message.get("content") or ""
        if not isinstance(content, str):
            raise InferenceError(f"a chat message's content must be str, got {type(content).__name__}")
        # RoboML hands the messages to the model's chat template: role and text only.
        messages.append({"role": message["role"], "content": content})
        images.extend(message.get("images") or [])
    images.extend(inference_input.get("images") or [])
    payload: dict[str, Any] = {"query": messages}
    _copy_options(inference_input, payload, _CHAT_OPTIONS)
    stream = bool(inference_input.get("stream")) and node_model in STREAMING_NODE_MODELS
    if node_model in STREAMING_NODE_MODELS:
        payload["stream"] = stream
    if node_model != "TransformersLLM":
        if not images:
            raise InferenceError(f"a {node_model} inference needs at least one image")
        payload["images"] = _encode_images(images, binary)
    if node_model == "RoboBrain2":
        _copy_options(inference_input, payload, _PLANNING_OPTIONS)
    return payload, stream


def _pcm16(audio: np.ndarray) -> bytes:
    if audio.dtype == np.int16:
        return np.ascontiguousarray(audio).tobytes()
    if audio.dtype.kind == "f":
        samples: np.ndarray = (np.clip(audio, -1.0, 1.0) * 32767).astype("<i2")
        return samples.tobytes()
    raise InferenceError(f"audio arrays must be int16 PCM or float in [-1, 1], got dtype {audio.dtype}")


def _speech_to_text_input(node_model: str, inference_input: dict[str, Any],
                          binary: bool) -> tuple[dict[str, Any], bool]:
    audio = inference_input.get("query")
    query: Any
    if isinstance(audio, bytes | bytearray):
        # RoboML reads bytes as 16 kHz mono 16-bit PCM; JSON carries them as base64.
        query = bytes(audio) if binary else base64.b64encode(bytes(audio)).decode("ascii")
    elif isinstance(audio, np.ndarray):
        # Sent as PCM bytes, not as an array: RoboML's WebSocket handler compares the query with
        # its b"\r\n" end-of-audio signal, which raises for an array under numpy 2.
        pcm = _pcm16(audio)
        query = pcm if binary else base64.b64encode(pcm).decode("ascii")
    elif isinstance(audio, str) and audio:
        query = audio
    else:
        raise InferenceError("a Whisper inference needs 'query': audio as bytes (16 kHz 16-bit PCM) or an array")
    if len(query) == 0:
        raise InferenceError("a Whisper inference got empty audio")
    payload: dict[str, Any] = {"query": query}
    _copy_options(inference_input, payload, _STT_OPTIONS)
    return payload, False


def _text_to_speech_input(node_model: str, inference_input: dict[str, Any],
                          binary: bool) -> tuple[dict[str, Any], bool]:
    text = inference_input.get("query")
    if not isinstance(text, str) or not text:
        raise InferenceError(f"a {node_model} inference needs 'query': the text to speak")
    # Raw WAV bytes travel in msgpack; JSON cannot hold them, so RoboML sends base64 there.
    payload: dict[str, Any] = {"query": text, "get_bytes": binary}
    if inference_input.get("voice") is not None:
        payload["voice"] = inference_input["voice"]
    return payload, False


def _detection_input(node_model: str, inference_input: dict[str, Any],
                     binary: bool) -> tuple[dict[str, Any], bool]:
    images = inference_input.get("images")
    if not isinstance(images, list | tuple) or not images:
        raise InferenceError(f"a {node_model} inference needs 'images': a non-empty list of images")
    payload = {"images": _encode_images(list(images), binary)}
    _copy_options(inference_input, payload, _DETECTION_OPTIONS)
    return payload, False


#: The input builder of each task a RoboML node serves.
_INPUT_BUILDERS: Final[dict[str, Callable[[str, dict[str, Any], bool], tuple[dict[str, Any], bool]]]] = {
    "chat": _chat_input,
    "speech_to_text": _speech_to_text_input,
    "text_to_speech": _text_to_speech_input,
    "detection": _detection_input,
}


def build_roboml_input(node_model: str, inference_input: dict[str, Any], *,
                       binary: bool) -> tuple[dict[str, Any], bool]:
    """Translate a component's inference input (:mod:`.payloads`) into the RoboML node's input.

    :param node_model: the RoboML model class of the node.
    :param binary: True for the msgpack transports (WebSocket, RESP), which carry arrays and
        bytes as they are; False for JSON (images become base64 PNG, audio base64 PCM).
    :returns: the input, and whether the reply will be a token stream.
    """
    return _INPUT_BUILDERS[ROBOML_NODE_MODELS[node_model]](node_model, inference_input, binary)


def normalize_result(node_model: str, result: Any, label: str) -> dict[str, Any]:
    """Check a RoboML result dict and bring it to the payload contract (TTS audio as bytes)."""
    if not isinstance(result, dict) or "output" not in result:
        raise ProtocolError(f"{label}: RoboML answered {result!r:.200} instead of a dict with 'output'")
    if ROBOML_NODE_MODELS.get(node_model) == "text_to_speech" and isinstance(result["output"], str):
        try:
            result["output"] = base64.b64decode(result["output"], validate=True)
        except (binascii.Error, ValueError) as exc:
            raise ProtocolError(f"{label}: the speech audio is not base64: {exc}") from exc
    return result


def single_chunk_stream(text: Any, label: str, on_close: Callable[[], None] | None = None,
                        secrets: Iterable[str] = ()) -> ChunkStream[Any]:
    """A stream of one chunk, for a transport that cannot stream when the caller asked it to."""
    def chunks() -> Iterator[Any]:
        yield text

    return ChunkStream(chunks(), on_close=on_close, label=label, secrets=secrets)


class RoboMLNodeClient(ModelClient):
    """What the RoboML clients share: a node named after the model, the RoboML model class serving
    it, connection retries and the model's load timeout. Parameters as ModelClient; ``port``
    defaults to the transport's own (``default_port``)."""

    #: The port RoboML listens on for this transport.
    default_port: ClassVar[int] = 8000
    #: Attempts of a connection check (and of opening a connection) before giving up.
    connect_attempts: ClassVar[int] = 3
    #: Seconds before the second attempt; doubled for each one after.
    connect_retry_delay: ClassVar[float] = 0.2
    #: Seconds a model may take to load when its ``init_timeout`` is None (RoboML's own default).
    default_init_timeout: ClassVar[float] = 600.0

    def __init__(self, model: Model | dict[str, Any], host: str = "127.0.0.1", port: int | None = None,
                 *args: Any, **kwargs: Any) -> None:
        # The other arguments (inference_timeout, ...; positional ones too) are ModelClient's, in its order.
        super().__init__(model, host, self.default_port if port is None else port, *args, **kwargs)
        self.node_name = check_node_name(type(self).__name__, self.model_name)
        self.node_model = resolve_node_model(type(self).__name__, self.model_type)

    @property
    def _init_seconds(self) -> float:
        return float(self.init_timeout) if self.init_timeout else self.default_init_timeout


def retry_connect(func: Callable[[], T], *, attempts: int, delay: float,
                  retry_on: tuple[type[BaseException], ...], logger: logging.Logger, what: str) -> T:
    """Run an idempotent connection step, retrying ``attempts`` times in all when it raises ``retry_on``.

    Waits ``delay``, then twice that, ... between attempts. Only for steps that are safe to repeat
    (a ping, opening a connection); never for an inference.
    """
    for attempt in range(1, attempts + 1):
        try:
            return func()
        except retry_on as exc:
            if attempt >= attempts:
                raise
            logger.debug("%s failed (attempt %d of %d): %s", what, attempt, attempts, exc)
            time.sleep(delay * 2 ** (attempt - 1))
    raise ConfigError(f"{what}: attempts must be >= 1, got {attempts}")
