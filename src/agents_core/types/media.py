"""Images, audio and video: raw and compressed images, aligned colour + depth frames (RGBD), PCM audio, bundles
of frames; each value class beside its type."""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Any, ClassVar

from attrs import define, field

from ..errors import TypeValidationError
from ..support.lazy_numpy import is_ndarray, np, npt
from .base import SupportedType
from .fields import Header, Message, as_numeric_array, check_holds, header_field, instance_of, is_str, named, wire

__all__ = [
    "DEPTH_ENCODINGS",
    "IMAGE_ENCODINGS",
    "MAX_IMAGE_SIDE",
    "RGBD",
    "Audio",
    "AudioMsg",
    "CompressedImage",
    "CompressedImageMsg",
    "Image",
    "ImageMsg",
    "RGBDMsg",
    "Video",
    "VideoMsg",
    "image_array",
]


class _EncodingTable(Mapping[str, tuple["type[np.generic]", int]]):
    """A read-only table of encoding -> (numpy scalar type, channel count), the numpy type named in the
    table and looked up when an entry is read: the names can be listed and tested without numpy."""

    def __init__(self, entries: dict[str, tuple[str, int]]) -> None:
        self._entries = entries

    def __getitem__(self, encoding: str) -> tuple[type[np.generic], int]:
        dtype_name, channels = self._entries[encoding]
        return getattr(np, dtype_name), channels

    def __contains__(self, encoding: object) -> bool:
        return encoding in self._entries  # Mapping's own would read the entry, importing numpy

    def __iter__(self) -> Iterator[str]:
        return iter(self._entries)

    def __len__(self) -> int:
        return len(self._entries)

    def __repr__(self) -> str:
        return repr(dict(self))


#: Image encodings the core understands: name -> (numpy dtype, channel count).
IMAGE_ENCODINGS: Mapping[str, tuple[type[np.generic], int]] = _EncodingTable({
    "rgb8": ("uint8", 3),
    "bgr8": ("uint8", 3),
    "rgba8": ("uint8", 4),
    "bgra8": ("uint8", 4),
    "mono8": ("uint8", 1),
    "mono16": ("uint16", 1),
    "16UC1": ("uint16", 1),
    "32FC1": ("float32", 1),
})

#: The largest height or width an :class:`ImageMsg` may have (pixels). Far beyond any sensor or
#: stitched panorama, and small enough that a row of it fits ROS 2's uint32 ``step``.
MAX_IMAGE_SIDE = 1 << 20


def image_array(value: Any, name: str = "data") -> npt.NDArray[Any]:
    """Pixels as a numpy array: an array as is, an array-like (nested lists, as a model server's JSON
    reply gives them) converted, integers from 0 to 255 as uint8, other numbers as their numpy dtype."""
    if is_ndarray(value):
        return value
    if not isinstance(value, list | tuple):
        raise TypeValidationError(f"field {name!r}: expected a numpy array or nested lists, got {type(value).__name__}")
    arr = as_numeric_array(value, None, name)
    if arr.dtype.kind in "iub":
        return as_numeric_array(arr, np.uint8, name)
    return arr


def _image_data(value: Any) -> npt.NDArray[Any]:
    value = image_array(value)
    array: npt.NDArray[Any] = value[:, :, np.newaxis] if value.ndim == 2 else value
    if array.ndim != 3:
        raise TypeValidationError(f"field 'data': expected an HxWxC array, got shape {array.shape}")
    height, width = array.shape[:2]
    if height > MAX_IMAGE_SIDE or width > MAX_IMAGE_SIDE:
        raise TypeValidationError(
            f"field 'data': a {height}x{width} image exceeds MAX_IMAGE_SIDE ({MAX_IMAGE_SIDE} pixels a side)"
        )
    check_holds(array, "data")
    return array


@named
@define(eq=False)
class ImageMsg(Message):
    """An image: an HxWxC numpy array with an encoding from :data:`IMAGE_ENCODINGS`."""

    data: npt.NDArray[Any] = field(converter=_image_data,
                                   metadata=wire("HxWxC (|u1; <u2 for mono16 and 16UC1; <f4 for 32FC1)"))
    encoding: str = field(default="rgb8", metadata=wire("str (rgb8, bgr8, rgba8, bgra8, mono8, mono16, 16UC1, 32FC1)"))
    header: Header = header_field()

    def __attrs_post_init__(self) -> None:
        spec = IMAGE_ENCODINGS.get(self.encoding)
        if spec is None:
            raise TypeValidationError(
                f"field 'encoding': {self.encoding!r} is not supported; use one of {sorted(IMAGE_ENCODINGS)}"
            )
        dtype, channels = spec
        if self.data.dtype != dtype or self.data.shape[2] != channels:
            raise TypeValidationError(
                f"field 'data': encoding {self.encoding!r} needs {dtype.__name__} with {channels} "
                f"channel(s), got {self.data.dtype} with shape {self.data.shape}"
            )

    @property
    def height(self) -> int:
        return int(self.data.shape[0])

    @property
    def width(self) -> int:
        return int(self.data.shape[1])

    def to_rgb(self) -> npt.NDArray[Any]:
        """The pixels as HxWx3 RGB (a view where possible); mono and depth stay single-channel."""
        if self.encoding in ("bgr8", "bgra8"):
            return self.data[:, :, 2::-1]
        if self.encoding == "rgba8":
            return self.data[:, :, :3]
        return self.data

    @classmethod
    def from_array(cls, array: Any, header: Header | None = None) -> ImageMsg:
        """Wrap an array (or nested lists: integers 0-255 as uint8), guessing the encoding from dtype and
        channels (rgb8, rgba8, mono8, 16UC1, 32FC1)."""
        array = image_array(array)
        channels = 1 if array.ndim == 2 else (array.shape[2] if array.ndim == 3 else -1)
        guesses = {(np.dtype(np.uint8), 3): "rgb8", (np.dtype(np.uint8), 4): "rgba8",
                   (np.dtype(np.uint8), 1): "mono8", (np.dtype(np.uint16), 1): "16UC1",
                   (np.dtype(np.float32), 1): "32FC1"}
        encoding = guesses.get((array.dtype, channels))
        if encoding is None:
            raise TypeValidationError(
                f"cannot guess an image encoding for dtype {array.dtype} and shape {array.shape}; "
                "pass an ImageMsg with an explicit encoding"
            )
        return cls(data=array, encoding=encoding, header=header or Header())


@named
@define(eq=False)
class CompressedImageMsg(Message):
    """An encoded image (``format`` such as ``"jpeg"`` or ``"png"``) kept as bytes."""

    data: bytes = field(validator=instance_of(bytes))
    format: str = field(default="jpeg", validator=is_str, metadata=wire("str (jpeg, png, ...)"))
    header: Header = header_field()


def _pcm(value: Any) -> npt.NDArray[Any]:
    if isinstance(value, bytes | bytearray):
        value = np.frombuffer(bytes(value), dtype=np.int16)
    if not is_ndarray(value) or value.dtype not in (np.int16, np.float32):
        raise TypeValidationError("field 'data': expected PCM as a numpy int16 or float32 array (or int16 bytes)")
    if value.ndim != 1:
        raise TypeValidationError(f"field 'data': expected interleaved 1-D samples, got shape {value.shape}")
    check_holds(value, "data")
    return value


@named
@define(eq=False)
class AudioMsg(Message):
    """PCM audio: interleaved int16 or float32 samples at ``sample_rate`` Hz."""

    data: npt.NDArray[Any] = field(converter=_pcm, metadata=wire("1-D interleaved samples (<i2 or <f4)"))
    sample_rate: int = field(default=16000, metadata=wire("int (Hz)"))
    channels: int = field(default=1)
    header: Header = header_field()

    def __attrs_post_init__(self) -> None:
        # The bounds are ROS 2's field types (uint32 sample_rate, uint16 channels in agents_interfaces/Audio).
        for name, most in (("sample_rate", 2**32 - 1), ("channels", 2**16 - 1)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or not 0 < value <= most:
                raise TypeValidationError(f"field {name!r}: expected an int from 1 to {most}, got {value!r}")
        if self.data.size % self.channels:
            raise TypeValidationError(
                f"field 'data': {self.data.size} samples do not divide into {self.channels} channels"
            )

    @property
    def duration(self) -> float:
        """Length in seconds."""
        return self.data.size / self.channels / self.sample_rate


def _frames(value: Any) -> list[ImageMsg | CompressedImageMsg]:
    frames = list(value)
    for i, frame in enumerate(frames):
        if not isinstance(frame, ImageMsg | CompressedImageMsg):
            raise TypeValidationError(f"field 'frames[{i}]': expected ImageMsg or CompressedImageMsg")
    return frames


@named
@define(eq=False)
class VideoMsg(Message):
    """A sequence of frames bundled as one message."""

    frames: list[ImageMsg | CompressedImageMsg] = field(factory=list, converter=_frames)
    header: Header = header_field()


#: Encodings a depth image may have: millimetres as uint16, or metres as float32.
DEPTH_ENCODINGS = ("16UC1", "mono16", "32FC1")


@named
@define(eq=False)
class RGBDMsg(Message):
    """An aligned colour image and depth image of the same size (a depth camera's frame).

    It behaves as its colour image where an image is expected (``data``, ``encoding``, ``to_rgb``):
    the RGBD type is accepted wherever Image is.
    """

    image: ImageMsg = field(validator=instance_of(ImageMsg))
    depth: ImageMsg = field(validator=instance_of(ImageMsg))
    header: Header = header_field()

    def __attrs_post_init__(self) -> None:
        if self.depth.encoding not in DEPTH_ENCODINGS:
            raise TypeValidationError(f"field 'depth': encoding {self.depth.encoding!r} is not a depth encoding "
                                      f"(use one of {', '.join(DEPTH_ENCODINGS)})")
        if (self.image.height, self.image.width) != (self.depth.height, self.depth.width):
            raise TypeValidationError(f"field 'depth': {self.depth.height}x{self.depth.width} depth does not match "
                                      f"the {self.image.height}x{self.image.width} image")

    @property
    def data(self) -> npt.NDArray[Any]:
        """The colour image's pixels."""
        return self.image.data

    @property
    def encoding(self) -> str:
        return self.image.encoding

    @property
    def height(self) -> int:
        return self.image.height

    @property
    def width(self) -> int:
        return self.image.width

    def to_rgb(self) -> npt.NDArray[Any]:
        """The colour image as HxWx3 RGB (see :meth:`ImageMsg.to_rgb`)."""
        return self.image.to_rgb()


class Image(SupportedType):
    """A raw image (:class:`~agents_core.messages.ImageMsg`); a bare numpy array is wrapped.

    ``get_output()`` gives the pixels as a numpy array, RGB for colour encodings. Nested lists
    (a model server's JSON reply) are converted: integers from 0 to 255 as uint8.
    """

    value_class: ClassVar[type[Any]] = ImageMsg

    @classmethod
    def validate(cls, value: Any) -> Any:
        if isinstance(value, list) or is_ndarray(value):
            try:
                return ImageMsg.from_array(value)
            except TypeValidationError as exc:
                raise TypeValidationError(f"Image {exc}") from exc
        return super().validate(value)

    @classmethod
    def to_output(cls, value: Any) -> Any:
        return value.to_rgb()

    @classmethod
    def example(cls) -> Any:
        pixels = np.arange(4 * 5 * 3, dtype=np.uint8).reshape(4, 5, 3)
        return ImageMsg(data=pixels, encoding="rgb8", header=Header(stamp_ns=1_700_000_000_123_456_789,
                                                                    frame_id="camera"))


class RGBD(Image):
    """An aligned colour + depth frame (:class:`~agents_core.messages.RGBDMsg`).

    A subtype of Image, so it is accepted wherever Image is (a VLM, Vision or VLA input): there
    ``get_output()`` gives the colour pixels, as for an Image; ``callback.msg`` keeps the depth.
    A pair ``(image, depth)`` of arrays or ImageMsgs is wrapped.
    """

    value_class = RGBDMsg

    @classmethod
    def validate(cls, value: Any) -> Any:
        if isinstance(value, RGBDMsg):
            return value
        if isinstance(value, tuple) and len(value) == 2:
            image, depth = (v if isinstance(v, ImageMsg) else ImageMsg.from_array(v) for v in value)
            return RGBDMsg(image=image, depth=depth, header=image.header)
        raise TypeValidationError(f"RGBD expects RGBDMsg or an (image, depth) pair, got {type(value).__name__}")

    @classmethod
    def example(cls) -> Any:
        header = Header(stamp_ns=1_700_000_000_000_000_021, frame_id="camera_color_optical_frame")
        depth = ImageMsg(data=np.arange(20, dtype=np.uint16).reshape(4, 5) * 100, encoding="16UC1",
                         header=header)
        image = Image.example()
        return RGBDMsg(image=ImageMsg(data=image.data, encoding="rgb8", header=header), depth=depth,
                       header=header)


class CompressedImage(SupportedType):
    """An encoded image (:class:`~agents_core.messages.CompressedImageMsg`)."""

    value_class = CompressedImageMsg

    @classmethod
    def example(cls) -> Any:
        return CompressedImageMsg(data=b"\x89PNG\r\n\x1a\n-not-really", format="png")


class Audio(SupportedType):
    """PCM audio (:class:`~agents_core.messages.AudioMsg`); int16 bytes or a 1-D array are wrapped at 16 kHz."""

    value_class = AudioMsg

    @classmethod
    def validate(cls, value: Any) -> Any:
        if isinstance(value, bytes | bytearray) or is_ndarray(value):
            return AudioMsg(data=value)
        return super().validate(value)

    @classmethod
    def example(cls) -> Any:
        return AudioMsg(data=np.array([0, 1000, -1000, 32767], dtype=np.int16), sample_rate=16000)


class Video(SupportedType):
    """A bundle of frames (:class:`~agents_core.messages.VideoMsg`)."""

    value_class = VideoMsg

    @classmethod
    def example(cls) -> Any:
        return VideoMsg(frames=[Image.example(), Image.example()])
