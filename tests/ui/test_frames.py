"""What WS /api/outputs sends for each type (agents_core.ui.frames), without a server."""

from __future__ import annotations

import base64
import io
import json
import wave

import numpy as np
import pytest

pytest.importorskip("PIL", reason="Pillow (the ui extra) is not installed")

from agents_core.messages import (
    AudioMsg,
    CompressedImageMsg,
    DetectionsMsg,
    ImageMsg,
    LaserScanMsg,
    StreamingStringMsg,
    TrackingsMsg,
)
from agents_core.ui import frames
from agents_core.ui.frames import MAX_LIST_ITEMS, encode_jpeg, frame_for, image_bytes


def _decoded(frame: dict) -> np.ndarray:
    from PIL import Image  # noqa: PLC0415

    return np.asarray(Image.open(io.BytesIO(base64.b64decode(frame["data"]))))


def test_streamed_chunks_keep_their_flags() -> None:
    frame = frame_for("answer", "StreamingString", StreamingStringMsg(data=" Paris", stream=True, done=False))
    assert (frame["kind"], frame["text"], frame["stream"], frame["done"]) == ("stream", " Paris", True, False)
    assert isinstance(frame["stamp_ns"], int)


def test_raw_images_become_jpeg_or_png_and_compressed_ones_pass_through() -> None:
    pixels = np.zeros((10, 12, 3), np.uint8)
    pixels[:, :, 2] = 255
    bgr = ImageMsg(data=pixels, encoding="bgr8")  # blue in BGR order is red in RGB
    png = frame_for("cam", "Image", bgr, image_format="png")
    assert png["mime"] == "image/png" and (png["width"], png["height"]) == (12, 10)
    assert _decoded(png)[0, 0].tolist() == [255, 0, 0]
    depth = frame_for("depth", "Image", ImageMsg(data=np.full((4, 4), 1000, np.uint16), encoding="16UC1"))
    assert depth["mime"] == "image/jpeg" and _decoded(depth).shape == (4, 4)
    packed = frame_for("c", "CompressedImage", CompressedImageMsg(data=b"\x89PNG....", format="png"))
    assert packed["mime"] == "image/png" and base64.b64decode(packed["data"]) == b"\x89PNG...."


@pytest.mark.parametrize("fast", [True, False], ids=["simplejpeg", "pillow"])
def test_both_jpeg_encoders_give_the_picture_back(fast: bool) -> None:
    """simplejpeg (the ui extra's, when its wheel installed) and the Pillow fallback: the same picture, colour
    and grey, in the same size class (quality 85, 4:2:0 both)."""
    if fast:
        pytest.importorskip("simplejpeg", reason="simplejpeg (the ui extra's fast JPEG) is not installed")
    from PIL import Image  # noqa: PLC0415

    ramp = np.linspace(0, 255, 160, dtype=np.uint8)
    colour = np.stack([np.tile(ramp, (120, 1)), np.tile(ramp[::-1], (120, 1)), np.full((120, 160), 60, np.uint8)],
                      axis=2)
    for pixels, mode in ((colour, "RGB"), (colour[:, :, 0], "L"), (colour[::2, ::3], "RGB")):  # a strided view too
        data = encode_jpeg(pixels, fast=fast)
        assert data[:2] == b"\xff\xd8"
        picture = Image.open(io.BytesIO(data))
        assert picture.mode == mode and picture.size == (pixels.shape[1], pixels.shape[0])
        assert np.abs(np.asarray(picture).astype(int) - pixels).mean() < 4
    if fast:  # the two encoders agree on what they were asked for
        slow = encode_jpeg(colour, fast=False)
        assert 0.7 < len(encode_jpeg(colour)) / len(slow) < 1.4


@pytest.mark.parametrize("fast", [True, False], ids=["simplejpeg", "pillow"])
def test_camera_encodings_keep_their_colours(fast: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    """bgr8 / bgra8 / rgba8 / mono8 frames: simplejpeg takes their pixels as they are, Pillow (the fallback,
    or simplejpeg absent) gets them as RGB; either way the picture is the same, and raw frames carry exact RGB."""
    if fast:
        pytest.importorskip("simplejpeg", reason="simplejpeg (the ui extra's fast JPEG) is not installed")
    else:
        monkeypatch.setattr(frames, "_simplejpeg", lambda: None)  # as if simplejpeg were not installed
    ramp = np.linspace(0, 255, 80, dtype=np.uint8)
    rgb = np.stack([np.tile(ramp, (60, 1)), np.full((60, 80), 200, np.uint8), np.tile(ramp[::-1], (60, 1))], axis=2)
    alpha = np.full((60, 80, 1), 7, np.uint8)
    cases = {"rgb8": rgb, "bgr8": rgb[:, :, ::-1].copy(), "rgba8": np.concatenate([rgb, alpha], axis=2),
             "bgra8": np.concatenate([rgb[:, :, ::-1], alpha], axis=2), "mono8": rgb[:, :, 1].copy()}
    for encoding, data in cases.items():
        image = ImageMsg(data=data, encoding=encoding)
        expected = rgb[:, :, 1] if encoding == "mono8" else rgb
        mime, jpeg, width, height, _ = image_bytes(image, "jpeg")
        decoded = _decoded({"data": base64.b64encode(jpeg).decode()})
        assert (mime, width, height) == ("image/jpeg", 80, 60)
        assert decoded.shape == expected.shape and np.abs(decoded.astype(int) - expected).mean() < 4, encoding
        _, raw, _, _, _ = image_bytes(image, "raw")
        shown = np.frombuffer(raw, np.uint8).reshape(60, 80, 3)
        assert np.array_equal(shown, np.repeat(expected[:, :, None], 3, axis=2) if expected.ndim == 2 else rgb)


def test_detections_and_trackings_carry_boxes_labels_and_their_image() -> None:
    image = ImageMsg(data=np.zeros((8, 8, 3), np.uint8))
    det = frame_for("d", "Detections", DetectionsMsg(boxes=[[1, 2, 3, 4]], labels=["cup"], scores=[0.9], image=image))
    assert det["kind"] == "detections" and det["boxes"] == [[1.0, 2.0, 3.0, 4.0]] and det["labels"] == ["cup"]
    assert det["scores"] == [0.9] and det["image"]["width"] == 8
    tracks = frame_for("t", "Trackings", TrackingsMsg(ids=[7], labels=["cat"], boxes=[[0, 0, 2, 2]],
                                                      centroids=[[1, 1]], estimated_velocities=[[0, 0]]))
    assert tracks["ids"] == [7] and tracks["image"] is None
    multi = frame_for("m", "DetectionsMultiSource", [DetectionsMsg(labels=["a"], boxes=[[0, 0, 1, 1]], scores=[1]),
                                                     DetectionsMsg()])
    assert multi["sources"] == 2 and multi["labels"] == ["a"]


def test_audio_becomes_a_wav_file_float_samples_scaled() -> None:
    frame = frame_for("voice", "Audio", AudioMsg(data=np.array([0.0, 0.5, -1.0], np.float32), sample_rate=22050))
    with wave.open(io.BytesIO(base64.b64decode(frame["data"]))) as w:
        assert w.getframerate() == 22050 and w.getsampwidth() == 2
        assert np.frombuffer(w.readframes(3), "<i2").tolist() == [0, 16383, -32767]


def test_other_values_are_bounded_json() -> None:
    scan = LaserScanMsg(ranges=np.full(MAX_LIST_ITEMS + 10, np.inf, np.float32))
    frame = frame_for("scan", "LaserScan", scan)
    ranges = frame["value"]["ranges"]
    assert ranges["truncated"] is True and len(ranges["data"]) == MAX_LIST_ITEMS and ranges["data"][0] is None
    json.dumps(frame, allow_nan=False)  # infinities became null
    assert frame_for("n", "Float64", 2.5)["value"] == 2.5
