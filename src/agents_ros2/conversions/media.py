"""ROS 2 conversions of images, audio and video: ``sensor_msgs`` Image and CompressedImage, and
``agents_interfaces`` Audio, Video and RGBD."""

from __future__ import annotations

from typing import Any

import numpy as np
from sensor_msgs.msg import CompressedImage as RosCompressedImage
from sensor_msgs.msg import Image as RosImage

from agents_core import messages as m
from agents_core.errors import TypeValidationError

from .base import NATIVE_BIG_ENDIAN, RosConversion, ai, as_numpy, header_from_ros, header_to_ros, seq

__all__ = ["CONVERSIONS", "image_from_ros", "image_to_ros", "optional_image_from_ros", "optional_image_to_ros"]


def image_to_ros(v: m.ImageMsg, out: RosImage | None = None) -> RosImage:
    """An :class:`~agents_core.messages.ImageMsg` as ``sensor_msgs/Image`` (written into ``out`` when given)."""
    # check_fields: rclpy's checking setter keeps the array.array given for ``data`` (after an
    # isinstance and typecode check) where its unchecked one copies it (``array.array("B", value)``,
    # ~0.9 MB for a 640x480 image); the other fields come from a validated ImageMsg, so their checks pass.
    out = RosImage(check_fields=True) if out is None else out
    header_to_ros(v.header, out.header)
    data = np.ascontiguousarray(v.data)
    out.height, out.width = v.height, v.width
    out.encoding = v.encoding
    out.is_bigendian = int(NATIVE_BIG_ENDIAN and data.dtype.itemsize > 1)
    out.step = v.width * data.shape[2] * data.dtype.itemsize
    out.data = seq("B", data.reshape(-1).view(np.uint8), np.uint8)
    return out


def image_from_ros(msg: RosImage) -> m.ImageMsg:
    """A ``sensor_msgs/Image`` as an ImageMsg; TypeValidationError for an unsupported encoding or a bad size."""
    spec = m.IMAGE_ENCODINGS.get(msg.encoding)
    if spec is None:
        raise TypeValidationError(
            f"image encoding {msg.encoding!r} is not supported (supported: {', '.join(sorted(m.IMAGE_ENCODINGS))})"
        )
    dtype, channels = spec
    itemsize = np.dtype(dtype).itemsize
    height, width, step = int(msg.height), int(msg.width), int(msg.step)
    if height > m.MAX_IMAGE_SIDE or width > m.MAX_IMAGE_SIDE:
        # Refused before anything is sized from them (an empty image may claim any width).
        raise TypeValidationError(f"image of {width}x{height} exceeds MAX_IMAGE_SIDE ({m.MAX_IMAGE_SIDE} pixels "
                                  "a side)")
    row = width * channels * itemsize
    if step < row:
        raise TypeValidationError(f"image step {step} is smaller than width {width} x {channels} channel(s) "
                                  f"x {itemsize} byte(s) = {row}")
    raw = as_numpy(msg.data, np.uint8)
    if raw.size != step * height:
        raise TypeValidationError(f"image data has {raw.size} bytes; {msg.encoding} {width}x{height} with step "
                                  f"{step} needs {step * height}")
    rows = raw.reshape(height, step)
    if step != row:
        # Padded rows: keep only the pixels (this copies; unpadded images stay zero-copy).
        rows = np.ascontiguousarray(rows[:, :row])
    pixels = rows.view(dtype).reshape(height, width, channels)
    if itemsize > 1 and bool(msg.is_bigendian) != NATIVE_BIG_ENDIAN:
        pixels = pixels.byteswap()
    return m.ImageMsg(data=pixels, encoding=msg.encoding, header=header_from_ros(msg.header))


def optional_image_to_ros(image: m.ImageMsg | None, out: RosImage) -> None:
    # ROS has no optional fields: "no image" is an Image with an empty encoding.
    if image is not None:
        image_to_ros(image, out)


def optional_image_from_ros(msg: RosImage) -> m.ImageMsg | None:
    """The image of an optional ``sensor_msgs/Image`` field: None where its encoding is empty."""
    return None if msg.encoding == "" else image_from_ros(msg)


def _compressed_to_ros(v: m.CompressedImageMsg) -> RosCompressedImage:
    out = RosCompressedImage(format=v.format, check_fields=True)  # keeps data uncopied (see image_to_ros)
    header_to_ros(v.header, out.header)
    out.data = seq("B", np.frombuffer(v.data, np.uint8), np.uint8)
    return out


def _compressed_from_ros(msg: RosCompressedImage) -> m.CompressedImageMsg:
    return m.CompressedImageMsg(data=as_numpy(msg.data, np.uint8).tobytes(), format=msg.format,
                                header=header_from_ros(msg.header))


_AUDIO_FORMATS: dict[str, np.dtype[Any]] = {"S16LE": np.dtype("<i2"), "F32LE": np.dtype("<f4")}


def _audio_to_ros(v: m.AudioMsg) -> Any:
    fmt = "S16LE" if v.data.dtype == np.int16 else "F32LE"
    out = ai.Audio(sample_rate=v.sample_rate, channels=v.channels, format=fmt,
                   check_fields=True)  # keeps data uncopied (see image_to_ros)
    header_to_ros(v.header, out.header)
    out.data = seq("B", np.ascontiguousarray(v.data, _AUDIO_FORMATS[fmt]).view(np.uint8), np.uint8)
    return out


def _audio_from_ros(msg: Any) -> m.AudioMsg:
    dtype = _AUDIO_FORMATS.get(msg.format)
    if dtype is None:
        raise TypeValidationError(f"audio format {msg.format!r} is not supported (supported: S16LE, F32LE)")
    raw = as_numpy(msg.data, np.uint8)
    if raw.size % dtype.itemsize:
        raise TypeValidationError(f"audio data has {raw.size} bytes, not a whole number of {msg.format} samples")
    samples = raw.view(dtype).astype(dtype.newbyteorder("="), copy=False)
    return m.AudioMsg(data=samples, sample_rate=int(msg.sample_rate), channels=int(msg.channels),
                      header=header_from_ros(msg.header))


def _video_to_ros(v: m.VideoMsg) -> Any:
    out = ai.Video()
    header_to_ros(v.header, out.header)
    for frame in v.frames:
        if isinstance(frame, m.ImageMsg):
            out.frames.append(image_to_ros(frame))
        else:
            out.compressed_frames.append(_compressed_to_ros(frame))
    out.frame_is_compressed = [isinstance(f, m.CompressedImageMsg) for f in v.frames]
    return out


def _video_from_ros(msg: Any) -> m.VideoMsg:
    raw = [image_from_ros(f) for f in msg.frames]
    compressed = [_compressed_from_ros(f) for f in msg.compressed_frames]
    order = list(msg.frame_is_compressed)
    if not order:
        frames: list[m.ImageMsg | m.CompressedImageMsg] = [*raw, *compressed]
    else:
        if sum(order) != len(compressed) or len(order) - sum(order) != len(raw):
            raise TypeValidationError(f"video frame_is_compressed lists {len(order)} frames; the message has "
                                      f"{len(raw)} raw and {len(compressed)} compressed")
        raw_iter, comp_iter = iter(raw), iter(compressed)
        frames = [next(comp_iter) if is_c else next(raw_iter) for is_c in order]
    return m.VideoMsg(frames=frames, header=header_from_ros(msg.header))


def _rgbd_to_ros(v: m.RGBDMsg) -> Any:
    out = ai.RGBD()
    header_to_ros(v.header, out.header)
    image_to_ros(v.image, out.rgb)
    image_to_ros(v.depth, out.depth)
    return out


def _rgbd_from_ros(msg: Any) -> m.RGBDMsg:
    return m.RGBDMsg(image=image_from_ros(msg.rgb), depth=image_from_ros(msg.depth),
                     header=header_from_ros(msg.header))


#: The built-in conversions of this family.
CONVERSIONS: dict[str, RosConversion] = {
    "Image": RosConversion(RosImage, image_to_ros, image_from_ros),
    "CompressedImage": RosConversion(RosCompressedImage, _compressed_to_ros, _compressed_from_ros),
    "Audio": RosConversion(ai.Audio, _audio_to_ros, _audio_from_ros),
    "Video": RosConversion(ai.Video, _video_to_ros, _video_from_ros),
    "RGBD": RosConversion(ai.RGBD, _rgbd_to_ros, _rgbd_from_ros),
}
