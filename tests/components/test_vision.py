"""Vision: the real COCO SSD through the component (memory transport), bad inputs, actions, remote model, recipes."""

from __future__ import annotations

import io
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np
import pytest

from agents_core import Launcher, Topic
from agents_core.components import VLM, Vision
from agents_core.config import MLLMConfig, VisionConfig
from agents_core.errors import WiringError
from agents_core.messages import CompressedImageMsg, DetectionsMsg, Header, ImageMsg, RGBDMsg, TrackingsMsg
from agents_core.status import HealthStatus

from ..conftest import wait_for
from .scripted_client import ScriptedChatClient
from .vision_recipe import found_on, needs_ssd, photo

pytestmark = pytest.mark.local_models

CAMERA, PACKED = Topic("camera", "Image"), Topic("packed", "CompressedImage")
OBJECTS, TRACKS = Topic("objects", "Detections"), Topic("tracks", "Trackings")
ANNOTATED = Topic("annotated", "Image")


@contextmanager
def _running(vision: Vision, *others: Any) -> Iterator[tuple[Launcher, dict[str, list[Any]]]]:
    launcher = Launcher("memory")
    launcher.add_pkg(components=[vision, *others])
    with launcher:
        got: dict[str, list[Any]] = {}
        for t in vision.outputs:
            got[t.name] = []
            launcher.transport.create_subscription(t, got[t.name].append)
        yield launcher, got


def _vision(outputs: list[Topic] | None = None, inputs: list[Topic] | None = None, **config: Any) -> Vision:
    cfg = VisionConfig(enable_local_model=True, local_model_path=needs_ssd(), **config)
    return Vision(inputs=inputs or [CAMERA], outputs=outputs or [OBJECTS], config=cfg)


def _frame(pixels: np.ndarray, sec: int, encoding: str = "rgb8") -> ImageMsg:
    return ImageMsg(data=pixels, encoding=encoding, header=Header(stamp_ns=sec * 1_000_000_000 + 7, frame_id="cam"))


def _send(launcher: Launcher, topic: Topic, value: Any, got: list[Any], count: int) -> Any:
    launcher.transport.create_publisher(topic).publish(value)
    assert wait_for(lambda: len(got) >= count, timeout=20), f"no output #{count}"
    return got[count - 1]


@pytest.mark.parametrize("name", ["astronaut.png", "chelsea.png", "coffee.png"])
def test_the_component_finds_the_object_of_each_photo(name: str) -> None:
    vision = _vision(include_image=True)
    with _running(vision) as (launcher, got):
        det = _send(launcher, CAMERA, _frame(photo(name), 41), got["objects"], 1)
    assert isinstance(det, DetectionsMsg)
    assert found_on(name, det.labels, det.scores, det.boxes), (det.labels, det.scores, det.boxes)
    assert det.header.stamp_ns == 41_000_000_007 and det.header.frame_id == "cam"
    assert det.image is not None and det.image.data.shape == photo(name).shape
    assert float(det.scores.min()) >= 0.5


def test_a_blank_frame_has_nothing_above_threshold() -> None:
    vision = _vision()
    with _running(vision) as (launcher, got):
        det = _send(launcher, CAMERA, _frame(np.full((480, 640, 3), 128, np.uint8), 1), got["objects"], 1)
    assert det.labels == [] and det.boxes.shape == (0, 4) and det.image is None


def test_other_encodings_are_converted_and_bad_frames_fail_the_step_then_recover() -> None:
    rgb = photo("astronaut.png")
    vision = _vision(inputs=[CAMERA, PACKED])
    with _running(vision) as (launcher, got):
        n = 0
        for encoding, pixels in (("bgr8", rgb[:, :, ::-1].copy()), ("rgba8", np.dstack([rgb, np.full(rgb.shape[:2], 255,
                                                                                                       np.uint8)])),
                                 ("mono8", rgb.mean(axis=2).astype(np.uint8)[:, :, None])):
            n += 1
            det = _send(launcher, CAMERA, _frame(pixels, n, encoding), got["objects"], n)
            assert "person" in det.labels, encoding
        bad = [_frame(np.zeros((0, 0, 3), np.uint8), 20),  # empty
               _frame(np.zeros((8000, 8000, 3), np.uint8), 21),  # oversized (calloc'd: no memory touched)
               _frame(np.zeros((48, 64, 1), np.uint16), 22, "16UC1"),  # 16-bit pixels: wrong dtype
               CompressedImageMsg(data=b"not an image at all", format="png", header=Header(stamp_ns=23))]
        for value in bad:
            failed = vision.failed_steps
            topic = PACKED if isinstance(value, CompressedImageMsg) else CAMERA
            launcher.transport.create_publisher(topic).publish(value)
            # The count goes up just before the health is set: wait for both.
            assert wait_for(lambda f=failed: vision.failed_steps > f
                            and vision.health_status == HealthStatus.ALGORITHM_FAILURE, timeout=10), value
            # The next good frame is processed and the health recovers.
            n += 1
            _send(launcher, CAMERA, _frame(rgb, 100 + n), got["objects"], n)
            assert wait_for(lambda: vision.health_status == HealthStatus.HEALTHY)
    assert vision.frames_refused == 4
    assert [d.header.stamp_ns // 1_000_000_000 for d in got["objects"]] == [1, 2, 3, 104, 105, 106, 107]


def test_compressed_frames_are_decoded() -> None:
    from PIL import Image as PILImage  # noqa: PLC0415  (optional: needs_ssd() skipped without it)

    buffer = io.BytesIO()
    PILImage.fromarray(photo("chelsea.png")).save(buffer, format="JPEG", quality=90)
    vision = _vision(inputs=[PACKED])
    with _running(vision) as (launcher, got):
        det = _send(launcher, PACKED, CompressedImageMsg(data=buffer.getvalue(), format="jpeg",
                                                         header=Header(stamp_ns=5, frame_id="c")), got["objects"], 1)
    assert found_on("chelsea.png", det.labels, det.scores, det.boxes) and det.header.stamp_ns == 5


def test_rgbd_frames_are_seen_through_their_colour_image() -> None:
    depth_camera = Topic("depth_camera", "RGBD")
    pixels = photo("chelsea.png")
    depth = ImageMsg(data=np.full((*pixels.shape[:2], 1), 1.5, dtype=np.float32), encoding="32FC1")
    frame = RGBDMsg(image=_frame(pixels, 3), depth=depth, header=Header(stamp_ns=3, frame_id="rgbd"))
    vision = _vision(inputs=[depth_camera])
    with _running(vision) as (launcher, got):
        det = _send(launcher, depth_camera, frame, got["objects"], 1)
    assert found_on("chelsea.png", det.labels, det.scores, det.boxes), (det.labels, det.scores)
    assert det.header.frame_id == "rgbd"


def test_visualization_publishes_the_annotated_frame() -> None:
    rgb = photo("coffee.png")
    vision = _vision(outputs=[OBJECTS, ANNOTATED], enable_visualization=True)
    with _running(vision) as (launcher, got):
        _send(launcher, CAMERA, _frame(rgb, 3), got["objects"], 1)
        assert wait_for(lambda: len(got["annotated"]) == 1)
    drawn = got["annotated"][0]
    assert isinstance(drawn, ImageMsg) and drawn.data.shape == rgb.shape and drawn.header.stamp_ns == 3_000_000_007
    changed = np.any(drawn.data != rgb, axis=2)
    x1, y1, x2, y2 = (round(float(v)) for v in got["objects"][0].boxes[0])
    assert changed[y2 - 1, x1 + 2:x2 - 2].mean() > 0.9, "the box's bottom edge is drawn"
    assert changed[y1 + 5:y2 - 5, x1 + 1].mean() > 0.9, "the box's left edge is drawn"
    assert changed.mean() < 0.2, "the rest of the frame is untouched"


def test_wiring_errors() -> None:
    path = needs_ssd()
    with pytest.raises(WiringError, match="enable_visualization"):
        Vision(inputs=[CAMERA], outputs=[OBJECTS], config=VisionConfig(enable_local_model=True, local_model_path=path,
                                                                       enable_visualization=True))
    with pytest.raises(WiringError, match="enable_visualization"):
        Vision(inputs=[CAMERA], outputs=[OBJECTS, ANNOTATED],
               config=VisionConfig(enable_local_model=True, local_model_path=path))
    with pytest.raises(WiringError):
        Vision(inputs=[Topic("text", "String")], outputs=[OBJECTS],
               config=VisionConfig(enable_local_model=True, local_model_path=path))


def test_a_model_file_that_is_not_onnx_fails_configure_with_a_typed_error(tmp_path: Any) -> None:
    needs_ssd()
    bogus = tmp_path / "detector.onnx"
    bogus.write_bytes(b"this is not a protobuf" * 10)
    vision = Vision(inputs=[CAMERA], outputs=[OBJECTS],
                    config=VisionConfig(enable_local_model=True, local_model_path=str(bogus)))
    launcher = Launcher("memory")
    launcher.add_pkg(components=[vision])
    with pytest.raises(Exception, match="not a loadable ONNX model"), launcher:
        pass
    assert vision.health_status == HealthStatus.COMPONENT_FAILURE


def test_tracking_through_the_component_keeps_the_id_and_sees_the_motion() -> None:
    rgb = photo("astronaut.png")
    vision = _vision(outputs=[TRACKS], labels_to_track=["person"])
    with _running(vision) as (launcher, got):
        for n in range(6):
            canvas = np.zeros((512, 800, 3), np.uint8)
            canvas[:, 20 * n:20 * n + 512] = rgb  # the person moves right 20 px per 0.1 s: 200 px/s
            frame = ImageMsg(data=canvas, encoding="rgb8", header=Header(stamp_ns=10**9 + n * 10**8))
            _send(launcher, CAMERA, frame, got["tracks"], n + 1)
    tracks: list[TrackingsMsg] = got["tracks"]
    assert all(t.labels == ["person"] for t in tracks)
    assert {int(t.ids[0]) for t in tracks} == {int(tracks[0].ids[0])} and tracks[0].ids.dtype == np.int64
    vx, vy = tracks[-1].estimated_velocities[0]
    assert 120 < vx < 280 and abs(vy) < 60, (vx, vy)
    assert tracks[-1].centroids[0][0] > tracks[0].centroids[0][0] + 80


def test_track_and_take_picture_actions() -> None:
    vision = _vision(outputs=[OBJECTS, TRACKS], labels_to_track=["cup"])
    with _running(vision) as (launcher, got):
        _send(launcher, CAMERA, _frame(photo("coffee.png"), 9), got["objects"], 1)
        assert wait_for(lambda: len(got["tracks"]) == 1)
        assert got["tracks"][0].labels == ["cup"]
        assert vision.run_on_worker(lambda: vision.track("dining table")) is True
        picture = vision.run_on_worker(vision.take_picture)
        assert wait_for(lambda: len(got["tracks"]) == 2)
    assert vision.config.labels_to_track == ["dining table"]
    assert got["tracks"][1].labels == ["dining table"]
    seen = picture["detections"][0]
    assert seen["source"] == "camera" and "cup" in seen["labels"] and seen["stamp"] == pytest.approx(9.0)
    assert {"track", "take_picture"} <= set(vision.available_actions())


def test_remote_vision_model_through_roboml() -> None:
    from agents_core.clients import RoboMLHTTPClient  # noqa: PLC0415
    from agents_core.models import VisionModel  # noqa: PLC0415

    from ..servers.roboml_server import RoboMLTestServer  # noqa: PLC0415

    with RoboMLTestServer() as server:
        client = RoboMLHTTPClient(VisionModel(name="eyes"), port=server.port)
        vision = Vision(inputs=[CAMERA], outputs=[OBJECTS], model_client=client, config=VisionConfig(threshold=0.5))
        with _running(vision) as (launcher, got):
            det = _send(launcher, CAMERA, _frame(np.zeros((30, 40, 3), np.uint8), 2), got["objects"], 1)
        calls = server.calls_of("inference")
    assert det.labels == ["object"] and det.boxes.tolist() == [[0.0, 0.0, 40.0, 30.0]]
    assert det.header.stamp_ns == 2_000_000_007
    assert calls and calls[-1].payload["threshold"] == 0.5


def test_camera_to_vision_to_vlm_describes_what_was_detected() -> None:
    question = Topic("question", "String")
    answer = Topic("answer", "String")
    client = ScriptedChatClient(["I see an astronaut."])
    vlm = VLM(inputs=[question, CAMERA, OBJECTS], outputs=[answer], model_client=client, config=MLLMConfig(),
              trigger=question, component_name="describer")
    vision = _vision()
    with _running(vision, vlm) as (launcher, got):
        answers: list[str] = []
        launcher.transport.create_subscription(answer, answers.append)
        _send(launcher, CAMERA, _frame(photo("astronaut.png"), 4), got["objects"], 1)
        assert wait_for(lambda: vlm.callbacks["objects"].got_msg)
        launcher.transport.create_publisher(question).publish("What do you see?")
        assert wait_for(lambda: answers == ["I see an astronaut."], timeout=10)
    sent = client.inputs[0]["query"][-1]
    assert "person" in sent["content"] and sent["images"][0].shape == (512, 512, 3)
