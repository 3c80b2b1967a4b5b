"""``POST /api/inputs/<topic>``: turning a request body into a value of the topic's type.

What each type takes (anything else is refused with a 4xx and a message naming the topic):

- JSON ``{"value": ...}``: text for String / StreamingString, ``true``/``false`` for Bool, a
  number for Int32 / Int64 / Float32 / Float64, nested lists for the multi-arrays, a mapping of
  fields for other structured types; checked by the type's own validation.
- A multipart upload with a ``file`` field: a PNG or JPEG for Image (decoded to rgb8) and
  CompressedImage (kept encoded), a 16-bit PCM WAV for Audio.

Bodies are read with a byte limit (413 past it), JSON is parsed with bounds on depth, items and
numbers (:mod:`.json_body`), images are checked for their size from their header before they are
decoded, and nothing is ever unpickled.
"""

from __future__ import annotations

import io
import wave
from typing import TYPE_CHECKING, Any

import attrs
import numpy as np

from ..errors import AgentsError, TypeValidationError
from ..messages import AudioMsg, CompressedImageMsg, ImageMsg
from ..supported_types import Audio, Bool, CompressedImage, Float32, Image, Int32, String, SupportedType
from .json_body import BadJSON, parse_json_body

if TYPE_CHECKING:
    from starlette.requests import Request

    from ..topics import Topic

__all__ = ["MAX_UPLOAD_PIXELS", "MAX_UPLOAD_SIDE", "InputRejected", "check_image_size", "compressed_image",
           "decode_image", "decode_wav", "header_size", "input_widget", "read_bounded_body", "value_for_topic"]

#: The most pixels an uploaded image may have by default (``UISettings.max_upload_pixels``); checked
#: from the file's header before decoding, since a 143 KB PNG can claim 49 MP (147 MB of rgb8).
MAX_UPLOAD_PIXELS = 24_000_000
#: The longest side an uploaded image may have (a 50,000,000 x 1 PNG is refused by its header).
MAX_UPLOAD_SIDE = 16_384
#: The most channels and the highest sample rate an uploaded WAV may have.
MAX_UPLOAD_CHANNELS = 32
MAX_UPLOAD_RATE = 384_000


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


#: JPEG start-of-frame markers (they carry the size); C4, C8 and CC are other segments.
_SOF = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}


def header_size(data: bytes) -> tuple[int, int] | None:
    """(width, height) read from a PNG's IHDR or a JPEG's start-of-frame, without decoding; None if not found."""
    if data.startswith(b"\x89PNG\r\n\x1a\n"):
        if len(data) < 24 or data[12:16] != b"IHDR":
            return None
        return int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")
    at = 2
    while at + 9 <= len(data):  # walk the JPEG segments up to the first start-of-frame
        if data[at] != 0xFF:
            return None
        marker = data[at + 1]
        if marker == 0xFF:  # fill byte
            at += 1
            continue
        if marker in _SOF:
            return int.from_bytes(data[at + 7:at + 9], "big"), int.from_bytes(data[at + 5:at + 7], "big")
        if marker in (0xD9, 0xDA):  # end of image, or the scan began without a frame header
            return None
        at += 2 + int.from_bytes(data[at + 2:at + 4], "big")
    return None


def check_image_size(width: int, height: int, max_pixels: int) -> None:
    """Refuse (413) an image larger than ``max_pixels`` or :data:`MAX_UPLOAD_SIDE` a side."""
    if width <= 0 or height <= 0:
        raise InputRejected(422, f"the image claims to be {width}x{height}")
    if width > MAX_UPLOAD_SIDE or height > MAX_UPLOAD_SIDE:
        raise InputRejected(413, f"the image is {width}x{height}; at most {MAX_UPLOAD_SIDE} pixels a side")
    if width * height > max_pixels:
        raise InputRejected(413, f"the image is {width}x{height} ({width * height} pixels); "
                                 f"at most {max_pixels} pixels")


def _pixels(picture: Any) -> np.ndarray[Any, Any]:
    """The decoded pixels of an "L" or "RGB" picture, copied strip by strip into one array.

    ``np.asarray(picture)`` goes through ``tobytes()``, which joins the whole image from pieces:
    three copies at its peak. Strips of about 4 MB keep the peak at the picture plus the array.
    """
    width, height = picture.size
    channels = 1 if picture.mode == "L" else 3
    out = np.empty((height, width, channels) if channels == 3 else (height, width), dtype=np.uint8)
    rows = max(1, (4 << 20) // (width * channels))
    for top in range(0, height, rows):
        bottom = min(height, top + rows)
        out[top:bottom] = np.asarray(picture.crop((0, top, width, bottom)))
    return out


def decode_image(data: bytes, max_pixels: int = MAX_UPLOAD_PIXELS) -> ImageMsg:
    """An uploaded PNG / JPEG as an rgb8 (or mono8) ImageMsg.

    The size is read from the file's header and checked (:func:`check_image_size`) before Pillow
    opens it, and again from Pillow's own reading of the header before anything is decoded: a
    small file that claims a huge image is refused without allocating its pixels.
    """
    _image_format(data)
    claimed = header_size(data)
    if claimed is not None:
        check_image_size(*claimed, max_pixels)
    from PIL import Image as PILImage  # noqa: PLC0415  (the ui extra's Pillow, only when an image comes)

    try:
        with PILImage.open(io.BytesIO(data)) as picture:
            check_image_size(*picture.size, max_pixels)
            mode = "L" if picture.mode in ("L", "I;16", "I") else "RGB"
            # Already in the mode: no converted copy (it would double the peak of a large image).
            pixels = _pixels(picture if picture.mode == mode else picture.convert(mode))
    except InputRejected:
        raise
    except PILImage.DecompressionBombError as exc:  # our bound is stricter; kept in case Pillow reads more
        raise InputRejected(413, f"the image is too large to decode: {exc}") from None
    except (OSError, ValueError, SyntaxError) as exc:  # Pillow's errors for a damaged file
        raise TypeValidationError(f"the image does not decode: {exc}") from exc
    return ImageMsg.from_array(pixels)


def compressed_image(data: bytes, max_pixels: int = MAX_UPLOAD_PIXELS) -> CompressedImageMsg:
    """An uploaded PNG / JPEG kept encoded, its header size checked (whoever decodes it later is protected)."""
    fmt = _image_format(data)
    claimed = header_size(data)
    if claimed is None:
        raise TypeValidationError(f"the {fmt.upper()} file has no readable size in its header")
    check_image_size(*claimed, max_pixels)
    return CompressedImageMsg(data=data, format=fmt)


def decode_wav(data: bytes) -> AudioMsg:
    """An uploaded WAV (16-bit PCM) as an AudioMsg with its sample rate and channels."""
    try:
        with wave.open(io.BytesIO(data), "rb") as w:
            if w.getsampwidth() != 2:
                raise TypeValidationError(f"the WAV file has {8 * w.getsampwidth()}-bit samples; "
                                          "Audio inputs take 16-bit PCM")
            rate, channels = w.getframerate(), w.getnchannels()
            if not 1 <= channels <= MAX_UPLOAD_CHANNELS:
                raise TypeValidationError(f"the WAV file has {channels} channels; at most {MAX_UPLOAD_CHANNELS}")
            if not 1 <= rate <= MAX_UPLOAD_RATE:
                raise TypeValidationError(f"the WAV file's sample rate is {rate} Hz; at most {MAX_UPLOAD_RATE}")
            frames = w.readframes(w.getnframes())
    except (wave.Error, EOFError) as exc:
        raise TypeValidationError(f"the file is not a PCM WAV file: {exc}") from exc
    samples = np.frombuffer(frames, dtype="<i2").astype(np.int16)
    return AudioMsg(data=samples[: samples.size - samples.size % channels], sample_rate=rate, channels=channels)


def _from_file(msg_type: type[SupportedType], data: bytes, max_pixels: int) -> Any:
    if issubclass(msg_type, Image):
        return decode_image(data, max_pixels)
    if issubclass(msg_type, CompressedImage):
        return compressed_image(data, max_pixels)
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


def value_for_topic(topic: Topic, content_type: str, body: bytes, form_file: bytes | None, *,
                    max_pixels: int = MAX_UPLOAD_PIXELS, max_json_bytes: int = 1024 * 1024) -> Any:
    """The value to publish on ``topic`` from a request (JSON body, or the bytes of an uploaded file).

    Raises :class:`InputRejected` (415 for a content type the topic does not take, 413 for an image
    or a JSON body past the limits, 400 for a body that is not JSON, 422 for a value that does not
    fit its type) with a message naming the topic. Decoding is CPU and memory heavy: the server
    calls this on a worker thread, a bounded number at a time.
    """
    msg_type = topic.msg_type
    where = f"topic {topic.name!r} ({msg_type.type_name()})"
    try:
        if form_file is not None:
            return _from_file(msg_type, form_file, max_pixels)
        if not content_type.startswith("application/json"):
            raise InputRejected(415, f"send JSON {{\"value\": ...}} or a multipart upload with a 'file' "
                                     f"field, not {content_type or 'no content type'!r}")
        if len(body) > max_json_bytes:
            raise InputRejected(413, f"the JSON body is {len(body)} bytes; at most {max_json_bytes} "
                                     "(files go as multipart uploads)")
        try:
            document = parse_json_body(body, max_bytes=max_json_bytes)
        except BadJSON as exc:
            raise InputRejected(400, str(exc)) from None
        if not isinstance(document, dict) or "value" not in document:
            raise InputRejected(422, "send a JSON object with a 'value' field")
        return _from_json(msg_type, document["value"])
    except InputRejected as exc:
        raise InputRejected(exc.status, f"{where}: {exc.message}") from None
    except (AgentsError, ValueError, TypeError, OverflowError, RecursionError) as exc:
        raise InputRejected(422, f"{where}: {exc}") from None
