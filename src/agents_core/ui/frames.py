"""Output values as WebSocket frames: what ``WS /api/outputs`` sends for each type.

Every frame is one JSON object with ``"kind"``, ``"topic"``, ``"msg_type"`` and ``"stamp_ns"``
(when the value has a header), so any front end can dispatch on ``kind``:

==================  ==========================================================================
kind                fields
==================  ==========================================================================
``text``            ``text`` (String)
``stream``          ``text`` (this chunk), ``stream``, ``done`` (StreamingString)
``image``           ``mime`` (``image/jpeg`` or ``image/png``), ``data`` (base64), ``width``,
                    ``height``
``detections``      ``boxes`` ([[x1, y1, x2, y2], ...] in image pixels), ``labels``, ``scores``,
                    ``ids`` (Trackings only), ``image`` (an ``image`` frame's fields, or null)
``audio``           ``mime`` (``audio/wav``), ``data`` (base64 WAV), ``sample_rate``,
                    ``channels``, ``seconds``; ``sanitized`` (NaN / infinite samples sent as 0)
                    and ``note`` when there were any
``status``          ``component``, ``state``, ``health``, ``message``
``value``           ``value``: JSON of anything else (numbers, arrays, attrs messages), arrays
                    longer than :data:`MAX_LIST_ITEMS` cut and flagged with ``truncated``
``error``           ``message``: why a value could not be shown (instead of its frame, never
                    silently dropped)
==================  ==========================================================================

An image with a side past JPEG's limit (:data:`MAX_JPEG_SIDE`) is sent downscaled, its frame
carrying the original ``width`` / ``height`` and a ``note``.

Encoding runs once per value, on the subscription's delivery thread, whatever the number of
connected clients. Clients that ask for binary frames get images as binary WebSocket frames
instead (:mod:`.binary_frames`).
"""

from __future__ import annotations

import base64
import functools
import importlib
import io
import math
import wave
from typing import Any

import attrs
import numpy as np

from ..messages import (
    AudioMsg,
    ComponentStatusMsg,
    CompressedImageMsg,
    DetectionsMsg,
    ImageMsg,
    StreamingStringMsg,
    TrackingsMsg,
)
from ..runtime.figures import parse_stats

__all__ = ["JPEG_QUALITY", "MAX_AUDIO_CHANNELS", "MAX_JPEG_SIDE", "MAX_LIST_ITEMS", "RGB8_MIME", "FrameRefused",
           "encode_audio_wav", "encode_image", "encode_jpeg", "error_frame", "frame_for", "image_bytes", "jsonable"]

#: The longest array / list a ``value`` frame carries (a LaserScan or a map would be megabytes).
MAX_LIST_ITEMS = 4096
_MAX_DEPTH = 8
_MIME = {"jpeg": "image/jpeg", "jpg": "image/jpeg", "png": "image/png"}
#: Pillow's (and libjpeg's) largest JPEG side; wider images are downscaled to fit.
MAX_JPEG_SIDE = 65_500
#: Audio with more channels is not sent (a WAV header holds at most 65,535 bytes per frame, and no
#: browser plays it); its frame is an ``error`` frame that says so.
MAX_AUDIO_CHANNELS = 64
_MAX_AUDIO_RATE = 768_000


class FrameRefused(ValueError):
    """A value that cannot be shown; the message says why (it becomes an ``error`` frame)."""


def _b64(data: bytes) -> str:
    return base64.b64encode(data).decode("ascii")


#: The ``mime`` of raw pixels (``image_format="raw"``, binary frames only): rgb8, rows top-down.
RGB8_MIME = "application/x-rgb8"


def image_bytes(image: ImageMsg | CompressedImageMsg, image_format: str = "jpeg",
                max_side: int | None = None) -> tuple[str, bytes, int | None, int | None, str | None]:
    """``image`` ready to send: ``(mime, data, width, height, note)``.

    Compressed images are passed as they are (``width`` / ``height`` None); raw ones are encoded as
    JPEG or PNG, or (``image_format="raw"``) sent as their rgb8 pixels. Depth and 16-bit images are
    scaled to 8 bits for display (the frame is for eyes, not for maths). ``note`` says when the image
    was downscaled (a side past JPEG's limit). ``max_side`` (JPEG and PNG only): a larger image is
    sent downscaled by the smallest whole step that brings its longest side within it (every
    step-th pixel: the UI's preview), ``width`` / ``height`` still the image's own.
    """
    if isinstance(image, CompressedImageMsg):
        fmt = image.format.lower()
        return _MIME.get(fmt, f"image/{fmt}"), bytes(image.data), None, None, None
    limit = MAX_JPEG_SIDE if image_format == "jpeg" else None
    if max_side is not None and image_format != "raw":
        limit = max_side if limit is None else min(limit, max_side)
    longest = max(image.data.shape[:2])
    step = -(-longest // limit) if limit is not None and longest > limit else 1  # ceil: every side within
    note = None
    if step > 1 and image_format == "jpeg" and longest > MAX_JPEG_SIDE:
        height, width = image.data.shape[:2]
        note = (f"downscaled 1:{step} to {-(-width // step)}x{-(-height // step)} for display "
                f"(JPEG allows {MAX_JPEG_SIDE} pixels a side)")
    if image_format == "jpeg" and (native := _native_jpeg(image, step)) is not None:
        return "image/jpeg", native, image.width, image.height, note
    pixels = image.to_rgb()
    if step > 1:
        pixels = pixels[::step, ::step]
    if pixels.dtype != np.uint8:
        finite = pixels[np.isfinite(pixels)] if pixels.dtype.kind == "f" else pixels
        top = float(finite.max()) if finite.size else 1.0
        pixels = np.clip(np.nan_to_num(pixels.astype(np.float32)) * (255.0 / (top or 1.0)), 0, 255).astype(np.uint8)
    if image_format == "raw":
        if pixels.ndim == 2 or pixels.shape[2] == 1:
            pixels = np.repeat(pixels.reshape(pixels.shape[0], pixels.shape[1], 1), 3, axis=2)
        return RGB8_MIME, _contiguous(pixels[:, :, :3]).tobytes(), image.width, image.height, None
    if pixels.ndim == 3 and pixels.shape[2] == 1:
        pixels = pixels[:, :, 0]
    if image_format != "png":
        return "image/jpeg", encode_jpeg(pixels), image.width, image.height, note
    from PIL import Image as PILImage  # noqa: PLC0415  (Pillow is the ui extra's; imported when an image comes)

    out = io.BytesIO()
    PILImage.fromarray(_contiguous(pixels)).save(out, format="PNG", compress_level=1)
    return "image/png", out.getvalue(), image.width, image.height, note


#: The quality of the JPEGs sent to clients (colour subsampled 4:2:0, Pillow's default at this quality).
JPEG_QUALITY = 85


@functools.cache  # a failed import is looked up on disk each time: once is enough
def _simplejpeg() -> Any:
    """The ``simplejpeg`` module (the ui extra's libjpeg-turbo binding), or None when it is not installed."""
    try:  # by name: optional, so the type check does not need it installed
        return importlib.import_module("simplejpeg")
    except ImportError:
        return None


def encode_jpeg(pixels: np.ndarray[Any, Any], quality: int = JPEG_QUALITY, *, fast: bool = True) -> bytes:
    """``pixels`` (HxW grey or HxWx3 RGB, uint8) as a JPEG.

    With ``simplejpeg`` installed (and ``fast``), it encodes: 20 % less time than Pillow's save for a
    640x480 frame here (no PIL image or file object in between; benchmarks/README.md); otherwise, or for
    another shape or dtype, Pillow does, with the same quality and subsampling.
    """
    encoder = _simplejpeg() if fast else None
    if encoder is not None and pixels.dtype == np.uint8 and (pixels.ndim == 2 or pixels.shape[2:] == (3,)):
        grey = pixels.ndim == 2
        data = _contiguous(pixels.reshape(*pixels.shape[:2], 1) if grey else pixels)
        return bytes(encoder.encode_jpeg(data, quality=quality, colorspace="GRAY" if grey else "RGB",
                                         colorsubsampling="420"))
    from PIL import Image as PILImage  # noqa: PLC0415  (Pillow is the ui extra's; imported when an image comes)

    out = io.BytesIO()
    PILImage.fromarray(_contiguous(pixels)).save(out, format="JPEG", quality=quality)
    return out.getvalue()


#: ImageMsg encodings whose pixels simplejpeg encodes as they are: (its colorspace, channels).
_NATIVE_JPEG = {"rgb8": ("RGB", 3), "bgr8": ("BGR", 3), "rgba8": ("RGBX", 4), "bgra8": ("BGRX", 4),
                "mono8": ("GRAY", 1)}


def _native_jpeg(image: ImageMsg, step: int = 1) -> bytes | None:
    """``image`` as a JPEG straight from its own pixels by simplejpeg (None: not installed, or an encoding,
    dtype or size it does not take that way). A camera's bgr8 frame skips the copy to RGB that
    :meth:`ImageMsg.to_rgb` would need: that copy took as long as the encode for 640x480. ``step`` > 1:
    every step-th pixel of every step-th row (the preview)."""
    encoder, layout, data = _simplejpeg(), _NATIVE_JPEG.get(image.encoding), image.data
    if step > 1:
        data = data[::step, ::step]
    if encoder is None or layout is None or data.dtype != np.uint8 or data.ndim not in (2, 3):
        return None
    space, channels = layout
    if (1 if data.ndim == 2 else data.shape[2]) != channels or max(data.shape[:2]) > MAX_JPEG_SIDE:
        return None
    return bytes(encoder.encode_jpeg(_contiguous(data.reshape(*data.shape[:2], channels)), quality=JPEG_QUALITY,
                                     colorspace=space, colorsubsampling="420"))


def _contiguous(pixels: np.ndarray[Any, Any]) -> np.ndarray[Any, Any]:
    """``pixels`` C-contiguous. A colour view (BGR reversed, RGBA's first three channels) is copied a
    channel at a time: numpy copies such a view a pixel at a time, 4x slower for 640x480 here."""
    if pixels.flags.c_contiguous:
        return pixels
    if pixels.ndim == 3 and pixels.shape[2] <= 4:
        out = np.empty(pixels.shape, pixels.dtype)
        for channel in range(pixels.shape[2]):
            out[:, :, channel] = pixels[:, :, channel]
        return out
    return np.ascontiguousarray(pixels)


def encode_image(image: ImageMsg | CompressedImageMsg, image_format: str = "jpeg") -> dict[str, Any]:
    """An ``image`` frame's fields for ``image``: compressed images as they are, raw ones as JPEG or PNG
    (``image_format="raw"`` is for binary frames: a JSON frame carries a JPEG then)."""
    mime, data, width, height, note = image_bytes(image, "jpeg" if image_format == "raw" else image_format)
    fields: dict[str, Any] = {"mime": mime, "data": _b64(data), "width": width, "height": height}
    if note is not None:
        fields["note"] = note
    return fields


def _audio_samples(audio: AudioMsg) -> tuple[np.ndarray[Any, Any], int]:
    """The samples as int16 (float ones in [-1, 1] scaled) and how many were NaN / infinite (sent as 0)."""
    if not 1 <= audio.channels <= MAX_AUDIO_CHANNELS:
        raise FrameRefused(f"audio with {audio.channels} channels is not sent (at most {MAX_AUDIO_CHANNELS})")
    if not 1 <= audio.sample_rate <= _MAX_AUDIO_RATE:
        raise FrameRefused(f"audio at {audio.sample_rate} Hz is not sent (at most {_MAX_AUDIO_RATE} Hz)")
    samples = audio.data
    bad = 0
    if samples.dtype.kind == "f":
        finite = np.isfinite(samples)
        bad = int(samples.size - np.count_nonzero(finite))
        if bad:
            samples = np.where(finite, samples, 0.0)
    if samples.dtype != np.int16:
        samples = (np.clip(samples, -1.0, 1.0) * 32767.0).astype(np.int16)
    return samples, bad


def encode_audio_wav(audio: AudioMsg) -> bytes:
    """``audio`` as a 16-bit PCM WAV file (float samples in [-1, 1] are scaled, NaN / infinite ones are 0).

    Raises :class:`FrameRefused` for a channel count or a sample rate no WAV player takes.
    """
    samples, _ = _audio_samples(audio)
    return _wav(audio, samples)


def _wav(audio: AudioMsg, samples: np.ndarray[Any, Any]) -> bytes:
    out = io.BytesIO()
    with wave.open(out, "wb") as w:
        w.setnchannels(audio.channels)
        w.setsampwidth(2)
        w.setframerate(audio.sample_rate)
        w.writeframes(samples.astype("<i2").tobytes())
    return out.getvalue()


def jsonable(value: Any, depth: int = 0) -> Any:
    """``value`` as JSON-ready data: attrs messages as mappings, arrays as (bounded) lists, NaN as null."""
    if depth > _MAX_DEPTH:
        return "..."
    if value is None or isinstance(value, bool | int | str):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, np.generic):
        return jsonable(value.item(), depth)
    if isinstance(value, bytes | bytearray):
        return {"bytes": len(value)}
    if isinstance(value, np.ndarray):
        flat = value.reshape(-1)[:MAX_LIST_ITEMS]
        items = [jsonable(v, depth + 1) for v in flat.tolist()]
        out: dict[str, Any] = {"shape": list(value.shape), "dtype": str(value.dtype), "data": items}
        if value.size > MAX_LIST_ITEMS:
            out["truncated"] = True
        return out
    if attrs.has(type(value)):
        return {f.name: jsonable(getattr(value, f.name), depth + 1) for f in attrs.fields(type(value))}
    if isinstance(value, dict):
        return {str(k): jsonable(v, depth + 1) for k, v in list(value.items())[:MAX_LIST_ITEMS]}
    if isinstance(value, list | tuple):
        return [jsonable(v, depth + 1) for v in value[:MAX_LIST_ITEMS]]
    return repr(value)[:1000]


def _detections(value: DetectionsMsg | TrackingsMsg, image_format: str) -> dict[str, Any]:
    frame: dict[str, Any] = {
        "kind": "detections",
        "boxes": np.asarray(value.boxes, dtype=np.float64).round(2).tolist(),
        "labels": list(value.labels),
        "scores": np.asarray(getattr(value, "scores", np.zeros(0)), dtype=np.float64).round(4).tolist(),
        "image": encode_image(value.image, image_format) if value.image is not None else None,
    }
    if isinstance(value, TrackingsMsg):
        frame["ids"] = value.ids.tolist()
    return frame


def frame_for(topic: str, msg_type: str, value: Any, image_format: str = "jpeg") -> dict[str, Any]:
    """The frame sent to clients for ``value`` received on ``topic`` (see the module docstring)."""
    frame: dict[str, Any]
    if isinstance(value, StreamingStringMsg):
        frame = {"kind": "stream", "text": value.data, "stream": value.stream, "done": value.done}
    elif isinstance(value, str):
        frame = {"kind": "text", "text": value}
    elif isinstance(value, ImageMsg | CompressedImageMsg):
        frame = {"kind": "image", **encode_image(value, image_format)}
    elif isinstance(value, DetectionsMsg | TrackingsMsg):
        frame = _detections(value, image_format)
    elif isinstance(value, list) and value and all(isinstance(v, DetectionsMsg | TrackingsMsg) for v in value):
        # The multi-source types: one frame per source would interleave; the first source is shown,
        # the others are counted so the front end can say so.
        frame = {**_detections(value[0], image_format), "sources": len(value)}
    elif isinstance(value, AudioMsg):
        samples, bad = _audio_samples(value)
        frame = {"kind": "audio", "mime": "audio/wav", "data": _b64(_wav(value, samples)),
                 "sample_rate": value.sample_rate, "channels": value.channels, "seconds": round(value.duration, 3)}
        if bad:
            frame.update(sanitized=bad, note=f"{bad} NaN or infinite samples were sent as silence")
    elif isinstance(value, ComponentStatusMsg):
        frame = {"kind": "status", "component": value.component, "state": value.lifecycle_state,
                 "health": value.health, "message": value.message, "stats": parse_stats(value.stats)}
    else:
        frame = {"kind": "value", "value": jsonable(value)}
    header = getattr(value, "header", None)
    frame.update(topic=topic, msg_type=msg_type, stamp_ns=getattr(header, "stamp_ns", None))
    return frame


def error_frame(topic: str, msg_type: str, value: Any, message: str) -> dict[str, Any]:
    """The ``error`` frame sent in place of a value of ``topic`` that could not be shown."""
    header = getattr(value, "header", None)
    return {"kind": "error", "message": message[:500], "topic": topic, "msg_type": msg_type,
            "stamp_ns": getattr(header, "stamp_ns", None)}
