"""Values the frame encoder used to fail on (issue 25, item 6): an image wider than JPEG allows, audio with
65,535 channels, NaN / infinite audio. Each gives a frame that says what happened, never a traceback
and never a frame lost without a word."""

from __future__ import annotations

import base64
import io
import json
import logging
import wave

import numpy as np
import pytest

pytest.importorskip("PIL", reason="Pillow (the ui extra) is not installed")

from agents_core import Launcher, Topic
from agents_core.messages import AudioMsg, DetectionsMsg, ImageMsg
from agents_core.ui.frames import frame_for


def test_an_image_wider_than_jpeg_allows_is_sent_downscaled_with_a_note() -> None:
    from PIL import Image  # noqa: PLC0415

    wide = ImageMsg.from_array(np.full((2, 70_000, 3), 90, np.uint8))
    frame = frame_for("camera", "Image", wide)
    assert frame["kind"] == "image" and (frame["width"], frame["height"]) == (70_000, 2)  # the image's own size
    assert "downscaled 1:2 to 35000x1" in frame["note"]
    with Image.open(io.BytesIO(base64.b64decode(frame["data"]))) as sent:
        assert sent.size == (35_000, 1)
    # in a detections frame too, boxes stay in the image's own pixels
    detections = DetectionsMsg(boxes=np.array([[0, 0, 60_000, 2]], np.float32), labels=["wide"],
                               scores=np.array([0.9], np.float32), image=wide)
    frame = frame_for("found", "Detections", detections)
    assert frame["image"]["width"] == 70_000 and "note" in frame["image"]
    assert frame["boxes"] == [[0.0, 0.0, 60000.0, 2.0]]


def test_png_frames_are_not_downscaled() -> None:
    wide = ImageMsg.from_array(np.zeros((1, 70_000, 3), np.uint8))
    frame = frame_for("camera", "Image", wide, image_format="png")
    assert frame["mime"] == "image/png" and "note" not in frame


def test_nan_and_infinite_audio_is_sent_as_silence_and_counted() -> None:
    samples = np.array([0.5, np.nan, np.inf, -np.inf, -0.5], np.float32)
    frame = frame_for("voice", "Audio", AudioMsg(data=samples, sample_rate=16000, channels=1))
    assert frame["kind"] == "audio" and frame["sanitized"] == 3 and "3 NaN or infinite" in frame["note"]
    with wave.open(io.BytesIO(base64.b64decode(frame["data"]))) as w:
        pcm = np.frombuffer(w.readframes(w.getnframes()), "<i2")
    assert pcm.tolist() == [16383, 0, 0, 0, -16383]


def test_clean_audio_carries_no_note() -> None:
    frame = frame_for("voice", "Audio", AudioMsg(data=np.zeros(160, np.int16), sample_rate=16000, channels=1))
    assert "sanitized" not in frame and "note" not in frame


def test_absurd_audio_becomes_an_error_frame_on_the_socket(caplog: pytest.LogCaptureFixture) -> None:
    """Through the hub of a real server: the client gets an ``error`` frame, the log has no traceback."""
    pytest.importorskip("uvicorn", reason="the ui extra is not installed")
    from websockets.sync.client import connect  # noqa: PLC0415

    from agents_core.ui import LocalRecipe, UISettings  # noqa: PLC0415
    from agents_core.ui.server import UIServer  # noqa: PLC0415

    from .ui_parts import WORDS, shouter  # noqa: PLC0415

    sound = Topic("sound", "Audio")
    launcher = Launcher("memory")
    launcher.add_pkg(components=[shouter()])
    with launcher:
        ui = UIServer(LocalRecipe(launcher.components), launcher.transport, inputs=[WORDS], outputs=[sound],
                      settings=UISettings(port=0)).start()
        try:
            with connect(f"ws://127.0.0.1:{ui.port}/api/outputs?topics=sound", open_timeout=10) as ws:
                publisher = launcher.transport.create_publisher(sound)
                with caplog.at_level(logging.WARNING, logger="agents_core.ui.hub"):
                    publisher.publish(AudioMsg(data=np.zeros(65_535 * 2, np.int16), sample_rate=16000,
                                               channels=65_535))
                    publisher.publish(AudioMsg(data=np.zeros(160, np.int16), sample_rate=16000, channels=1))
                    kinds = []
                    for _ in range(10):  # bounded: status frames come too
                        frame = json.loads(ws.recv(timeout=10))
                        if frame["topic"] == "sound":
                            kinds.append(frame)
                        if len(kinds) == 2:
                            break
            assert [f["kind"] for f in kinds] == ["error", "audio"], "the next value still gets through"
            assert "65535 channels" in kinds[0]["message"] and kinds[0]["msg_type"] == "Audio"
            assert all(record.exc_info is None for record in caplog.records), "a traceback was logged"
            assert ui.state.hub.encode_errors == 1
        finally:
            ui.stop()
