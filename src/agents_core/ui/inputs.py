"""``POST /api/inputs/<topic>``: turning a request body into a value of the topic's type.

What each type takes (anything else is refused with a 4xx and a message naming the topic):

- JSON ``{"value": ...}``: text for String / StreamingString, ``true``/``false`` for Bool, a
  number for Int32 / Int64 / Float32 / Float64, nested lists for the multi-arrays, a mapping of
  fields for other structured types; checked by the type's own validation.
- A multipart upload with a ``file`` field: a PNG or JPEG for Image (decoded to rgb8) and
  CompressedImage (kept encoded), a 16-bit PCM WAV for Audio.

Bodies are read with a byte limit (413 past it), images are checked for their pixel count before
they are decoded, and nothing is ever unpickled.
"""

from __future__ import annotations

import io
import json
import wave
from typing import TYPE_CHECKING, Any

import attrs
import numpy as np

from ..errors import AgentsError, TypeValidationError
from ..messages import AudioMsg, CompressedImageMsg, ImageMsg
from ..supported_types import Audio, Bool, CompressedImage, Float32, Image, Int32, String, SupportedType

if TYPE_CHECKING:
    from starlette.requests import Request

    from ..topics import Topic

__all__ = ["MAX_UPLOAD_PIXELS", "InputRejected", "input_widget", "read_bounded_body", "value_for_topic"]

#: The most pixels an uploaded image may have (a 50 MP photo); checked before decoding.
MAX_UPLOAD_PIXELS = 50_000_000


class InputRejected(Exception):
    """A request body that cannot become a value of the topic's type; ``status`` is the HTTP code."""

    def __init__(self, status: int, message: str) -> None:
        super().__init__(message)
        self.status = status
        self.message = message


def input_widget(msg_type: type[SupportedType]) -> str:
    """How a page asks for a value of ``msg_type``: text, bool, number, image, audio or json."""
    if issubclass(msg_type, String):
        return "text"
    if issubclass(msg_type, Bool):
        return "bool"
    if issubclass(msg_type, Int32 | Float32):
        return "number"
    if issubclass(msg_type, Image | CompressedImage):
        return "image"
    if issubclass(msg_type, Audio):
        return "audio"
    return "json"


async def read_bounded_body(request: Request, limit: int) -> bytes:
    """The request body, refused with 413 as soon as it is longer than ``limit`` bytes.

    A declared Content-Length over the limit is refused before anything is read; a body without
    one (chunked) is read until it passes the limit, never further.
    """
    declared = request.headers.get("content-length")
    if declared is not None:
        if not declared.isdigit():
            raise InputRejected(400, "Content-Length is not a number")
        if int(declared) > limit:
            raise InputRejected(413, f"the body is {int(declared)} bytes; the limit is {limit} bytes")
    chunks: list[bytes] = []
    size = 0
    async for chunk in request.stream():
        size += len(chunk)
        if size > limit:
            raise InputRejected(413, f"the body is longer than the limit of {limit} bytes")
        chunks.append(chunk)
    return b"".join(chunks)


def _image_format(data: bytes) -> str:
    if data.startswith(b"\x89PNG\r\n\x1a\n"):
        return "png"
    if data.startswith(b"\xff\xd8\xff"):
        return "jpeg"
    raise TypeValidationError("the file is not a PNG or JPEG image")


def decode_image(data: bytes) -> ImageMsg:
    """An uploaded PNG / JPEG as an rgb8 (or mono8) ImageMsg, refusing oversized images before decoding."""
    _image_format(data)
    from PIL import Image as PILImage  # noqa: PLC0415  (the ui extra's Pillow, only when an image comes)

    try:
        with PILImage.open(io.BytesIO(data)) as picture:
            width, height = picture.size
            if width * height > MAX_UPLOAD_PIXELS:
                raise TypeValidationError(f"the image is {width}x{height}; at most {MAX_UPLOAD_PIXELS} pixels")
            mode = "L" if picture.mode in ("L", "I;16", "I") else "RGB"
            pixels = np.asarray(picture.convert(mode))
    except TypeValidationError:
        raise
    except (OSError, ValueError, SyntaxError) as exc:  # Pillow's errors for a damaged file
        raise TypeValidationError(f"the image does not decode: {exc}") from exc
    return ImageMsg.from_array(pixels)


def decode_wav(data: bytes) -> AudioMsg:
    """An uploaded WAV (16-bit PCM) as an AudioMsg with its sample rate and channels."""
    try:
        with wave.open(io.BytesIO(data), "rb") as w:
            if w.getsampwidth() != 2:
                raise TypeValidationError(f"the WAV file has {8 * w.getsampwidth()}-bit samples; "
                                          "Audio inputs take 16-bit PCM")
            frames = w.readframes(w.getnframes())
            rate, channels = w.getframerate(), w.getnchannels()
    except (wave.Error, EOFError) as exc:
        raise TypeValidationError(f"the file is not a PCM WAV file: {exc}") from exc
    samples = np.frombuffer(frames, dtype="<i2").astype(np.int16)
    return AudioMsg(data=samples[: samples.size - samples.size % channels], sample_rate=rate, channels=channels)


def _from_file(msg_type: type[SupportedType], data: bytes) -> Any:
    if issubclass(msg_type, Image):
        return decode_image(data)
    if issubclass(msg_type, CompressedImage):
        return CompressedImageMsg(data=data, format=_image_format(data))
    if issubclass(msg_type, Audio):
        return decode_wav(data)
    raise TypeValidationError(f"{msg_type.type_name()} takes a JSON value, not a file")


def _from_json(msg_type: type[SupportedType], value: Any) -> Any:
    widget = input_widget(msg_type)
    if widget in ("image", "audio"):
        raise TypeValidationError(f"{msg_type.type_name()} takes an uploaded file (multipart field 'file')")
    if widget == "text" and not isinstance(value, str):
        raise TypeValidationError(f"{msg_type.type_name()} expects text, got {type(value).__name__}")
    message_class = msg_type.message_class()
    if isinstance(value, dict) and attrs.has(message_class):
        try:
            value = message_class(**value)
        except TypeError as exc:  # unknown or missing fields
            raise TypeValidationError(f"{msg_type.type_name()}: {exc}") from exc
    return msg_type.validate(value)


def value_for_topic(topic: Topic, content_type: str, body: bytes, form_file: bytes | None) -> Any:
    """The value to publish on ``topic`` from a request (JSON body, or the bytes of an uploaded file).

    Raises :class:`InputRejected` (415 for a content type the topic does not take, 422 for a value
    that does not fit its type) with a message naming the topic.
    """
    msg_type = topic.msg_type
    where = f"topic {topic.name!r} ({msg_type.type_name()})"
    try:
        if form_file is not None:
            return _from_file(msg_type, form_file)
        if not content_type.startswith("application/json"):
            raise InputRejected(415, f"{where}: send JSON {{\"value\": ...}} or a multipart upload with a 'file' "
                                     f"field, not {content_type or 'no content type'!r}")
        try:
            document = json.loads(body)
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise InputRejected(400, f"{where}: the body is not JSON ({exc})") from None
        if not isinstance(document, dict) or "value" not in document:
            raise InputRejected(422, f"{where}: send a JSON object with a 'value' field")
        return _from_json(msg_type, document["value"])
    except (AgentsError, ValueError, TypeError) as exc:  # InputRejected is none of these: it passes through
        raise InputRejected(422, f"{where}: {exc}") from None
