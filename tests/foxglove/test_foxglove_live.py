"""The Foxglove live view, end to end: a recipe's image and detections reach a Foxglove protocol client.

The client (``ws_client``) is written from the published protocol spec, not from our code or the SDK.
"""

from __future__ import annotations

import asyncio
from typing import Any

import numpy as np
import pytest

pytest.importorskip("foxglove")
pytest.importorskip("google.protobuf")

from agents_core import Launcher, Topic
from agents_core.components import Component
from agents_core.messages import DetectionsMsg, Header, ImageMsg

from .ws_client import FoxgloveClient

pytestmark = pytest.mark.timeout(120)


class Camera(Component):
    """Publishes a 48x64 image with a white square and a detection of it, stamped alike, at each step."""

    def _execution_step(self, **kwargs: Any) -> None:
        pixels = np.zeros((48, 64, 3), np.uint8)
        pixels[10:20, 5:25] = 255
        image = ImageMsg(data=pixels, header=Header(frame_id="cam"))
        self.publishers_dict["camera"].publish(image)
        self.publishers_dict["detections"].publish(DetectionsMsg(boxes=[[5, 10, 25, 20]], labels=["square"],
                                                                 scores=[0.75], image=image))
        self.publishers_dict["say"].publish("hello foxglove")


def _recipe(transport: Any) -> Launcher:
    camera = Camera(inputs=[], outputs=[Topic("camera", "Image"), Topic("detections", "Detections"),
                                        Topic("say", "String")], trigger=10.0, component_name="cam")
    launcher = Launcher(transport, quiet=True)
    launcher.add_pkg(components=[camera])
    launcher.enable_foxglove(port=0)
    return launcher


async def _watch(url: str) -> dict[str, Any]:
    client = await FoxgloveClient.connect(url)
    try:
        await client.wait_for_channels(["/camera", "/detections", "/detections/image", "/say", "/cam/status"])
        for topic in ("/camera", "/detections", "/detections/image", "/say"):
            await client.subscribe(topic)
        got = {"channels": dict(client.channels)}
        for topic in ("/camera", "/detections", "/say"):
            got[topic] = await client.next_message(topic)
        # The annotated frame is the one the detections carry: same stamp on both channels.
        while True:
            got["/detections/image"] = await client.next_message("/detections/image")
            got["/detections"] = await client.next_message("/detections")
            if got["/detections"][0] == got["/detections/image"][0]:
                return got
    finally:
        await client.close()


def _check(got: dict[str, Any]) -> None:
    channels = got["channels"]
    assert channels["/camera"]["schemaName"] == "foxglove.RawImage"
    assert channels["/detections"]["schemaName"] == "foxglove.ImageAnnotations"
    assert channels["/say"]["schemaName"] == "foxglove.Log"
    assert channels["/cam/status"]["schemaName"] == "foxglove.Log"

    stamp, image = got["/camera"]
    assert (image.width, image.height, image.encoding, image.step) == (64, 48, "rgb8", 64 * 3)
    pixels = np.frombuffer(image.data, np.uint8).reshape(48, 64, 3)
    assert pixels[15, 10].tolist() == [255, 255, 255] and pixels[30, 40].tolist() == [0, 0, 0]
    assert image.frame_id == "cam"
    assert stamp == image.timestamp.seconds * 10**9 + image.timestamp.nanos

    stamp, annotations = got["/detections"]
    image_stamp, _ = got["/detections/image"]
    assert stamp == image_stamp
    (box,) = annotations.points
    assert [(p.x, p.y) for p in box.points] == [(5, 10), (25, 10), (25, 20), (5, 20)]
    assert box.timestamp.seconds * 10**9 + box.timestamp.nanos == image_stamp
    (label,) = annotations.texts
    assert label.text == "square 0.75"

    _, log = got["/say"]
    assert log.message == "hello foxglove"


def test_a_memory_recipe_shows_its_image_and_detections_in_foxglove() -> None:
    with _recipe("memory") as launcher:
        assert launcher.foxglove.url.startswith("ws://127.0.0.1:")
        got = asyncio.run(_watch(launcher.foxglove.url))
        stats = launcher.foxglove.statistics()
    _check(got)
    assert stats["camera"].delivered >= 1 and stats["camera"].callback_errors == 0
    assert launcher.foxglove is None  # stopped with the recipe


@pytest.mark.zenoh
def test_a_zenoh_recipe_shows_its_image_and_detections_in_foxglove() -> None:
    pytest.importorskip("zenoh")
    from agents_zenoh.transport import ZenohTransport  # noqa: PLC0415 - only with the zenoh extra

    transport = ZenohTransport(mode="peer", listen=["tcp/127.0.0.1:0"], connect=[], multicast_scouting=False)
    try:
        with _recipe(transport) as launcher:
            got = asyncio.run(_watch(launcher.foxglove.url))
    finally:
        transport.close()
    _check(got)
