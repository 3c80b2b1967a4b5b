"""The spec's code, run as written (messages.md): blocks 26-32, and what the page says of messages.

``ros_sugar.supported_types`` is ``agents_core.supported_types`` here, ``ros_sugar.io.callbacks``
``agents_core.callbacks``, and the guide's ``automatika_embodied_agents`` package is
``agents_interfaces`` (interfaces/, built with pip): see docs/porting.md.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from agents_core import Launcher, Topic, callbacks, supported_types
from agents_core.callbacks import GenericCallback, callback_for
from agents_core.components import LLM, Component
from agents_core.errors import ConfigError
from agents_core.messages import DetectionsMsg, ImageMsg, PointsOfInterestMsg, StreamingStringMsg
from agents_core.supported_types import SupportedType, add_additional_datatypes, registered_types

from ..components.scripted_client import ScriptedChatClient
from ..conftest import wait_for
from .spec_blocks import covers, run_block

ros_msgs = pytest.importorskip("agents_interfaces.msg", reason="the samples' messages are in agents_interfaces")


class _Talker(Component):
    """Publishes each value of ``self.to_send`` (value, publish keyword arguments) on its output, once."""

    def __init__(self, out: Topic, to_send: list[tuple[Any, dict[str, Any]]]) -> None:
        self.to_send = to_send
        super().__init__(inputs=[], outputs=[out], trigger=20.0, component_name="talker")

    def _execution_step(self, **kwargs: Any) -> None:
        while self.to_send:
            value, publish_kwargs = self.to_send.pop(0)
            for pub in self.publishers_dict.values():
                pub.publish(value, **publish_kwargs)


def _published(out: Topic, to_send: list[tuple[Any, dict[str, Any]]]) -> list[Any]:
    talker = _Talker(out, list(to_send))
    launcher = Launcher("memory")
    launcher.add_pkg(components=[talker])
    got: list[Any] = []
    with launcher:
        launcher.transport.create_subscription(out, got.append)
        assert wait_for(lambda: len(got) == len(to_send)), talker.health_message
    return got


@contextlib.contextmanager
def _forgetting(*names: str) -> Iterator[None]:
    """Unregister the sample's type names afterwards (the registry is process-wide)."""
    before = {n: registered_types().get(n) for n in names}
    try:
        yield
    finally:
        for name in names:
            if registered_types().get(name) is not before[name]:
                supported_types._registry.unregister(name)
        with contextlib.suppress(ImportError):
            from agents_zenoh.codecs import registry  # noqa: PLC0415

            for name in names:
                with contextlib.suppress(Exception):
                    registry._codecs.unregister(name)


@covers((26, "from ros_sugar.supported_types import SupportedType"))
def test_block_26_a_wrapper_whose_convert_takes_stream_and_done() -> None:
    namespace = run_block(26, {"StreamingStringCallback": callbacks.StreamingStringCallback,
                               "ROSStreamingString": ros_msgs.StreamingString})
    wrapper = namespace["StreamingString"]
    out = Topic("tokens", wrapper)
    # Publish keyword arguments reach the type's convert(): stream / done travel that way.
    got = _published(out, [("Hel", {"stream": True, "done": False}), ("lo", {"stream": True, "done": True})])
    assert [(m.data, m.stream, m.done) for m in got] == [("Hel", True, False), ("lo", True, True)]
    assert isinstance(got[0], ros_msgs.StreamingString)
    assert isinstance(callback_for(out), callbacks.StreamingStringCallback)


@covers((27, "from ros_sugar.supported_types import add_additional_datatypes"))
def test_block_27_registering_types_makes_their_names_resolve() -> None:
    from agents_core.ros import Detections, StreamingString, Video  # noqa: PLC0415

    namespace = {"StreamingString": StreamingString, "Video": Video, "Detections": Detections}
    run_block(27, namespace, (", ...]", "]"))  # the list's "..." stands for the other types
    for name, cls in namespace.items():
        if name in ("StreamingString", "Video", "Detections"):
            assert Topic(f"t_{name.lower()}", name).msg_type is cls


def _semantic_label() -> dict[str, Any]:
    namespace = run_block(28)
    namespace["SupportedType"] = SupportedType  # block 29 is a part of the types module (agents/ros.py)
    run_block(29, namespace, ("from .callbacks import SemanticLabelCallback\n", ""))
    return namespace


@covers((28, "from ros_sugar.io.callbacks import GenericCallback"),
        (29, "from automatika_embodied_agents.msg import SemanticLabel as ROSSemanticLabel"),
        (30, "agent_types = ["),
        (31, "__all__ = ["),
        (32, "from agents.ros import Topic"))
def test_blocks_28_to_32_adding_the_semantic_label_type() -> None:
    from agents_core.ros import Detections, StreamingString, Video  # noqa: PLC0415

    namespace = _semantic_label()
    label_class = namespace["SemanticLabel"]
    assert issubclass(namespace["SemanticLabelCallback"], GenericCallback)
    with _forgetting("SemanticLabel"):
        if registered_types().get("SemanticLabel") not in (None, label_class):
            supported_types._registry.unregister("SemanticLabel")  # another test's sample of the same name
        namespace.update(StreamingString=StreamingString, Video=Video, Detections=Detections,
                         add_additional_datatypes=add_additional_datatypes)
        run_block(30, namespace)  # registers it
        exports = run_block(31, {})["__all__"]
        assert "SemanticLabel" in exports
        namespace = run_block(32, namespace)
        label_topic = namespace["label_topic"]
        assert label_topic.msg_type is label_class
        # convert() runs on publish; the callback's _msg_to_output is what get_output() gives.
        got = _published(label_topic, [({"label": "door", "confidence": 0.75}, {})])
        assert isinstance(got[0], ros_msgs.SemanticLabel) and got[0].label == "door"
        callback = callback_for(label_topic)
        callback._receive(got[0])
        assert callback.get_output() == {"label": "door", "confidence": 0.75}


# -- what messages.md says beyond its blocks (issue 37) ---------------------------------------------


def test_the_builtin_streaming_string_honours_stream_and_done_with_its_own_callback() -> None:
    out = Topic("answer", "StreamingString")
    got = _published(out, [("partial", {"stream": True, "done": False}), ("end", {"stream": True, "done": True}),
                           ("plain", {})])
    assert [(m.data, m.stream, m.done) for m in got] == [("partial", True, False), ("end", True, True),
                                                         ("plain", False, True)]
    callback = callback_for(out)
    assert isinstance(callback, callbacks.StreamingStringCallback)
    callback._receive(StreamingStringMsg(data="tok", stream=True, done=False))
    assert callback.get_output() == "tok" and callback.msg.stream is True


def test_frame_id_given_to_publish_reaches_the_header() -> None:
    camera = Topic("camera", "Image")
    frame = np.zeros((4, 4, 3), np.uint8)
    got = _published(camera, [(frame, {"frame_id": "head_camera", "time_stamp": 12.5}), (frame, {})])
    assert got[0].header.frame_id == "head_camera" and got[0].header.stamp_ns == 12_500_000_000
    assert got[1].header.frame_id == ""


def test_a_custom_type_with_a_convert_but_neither_ros_type_nor_value_class_is_refused() -> None:
    class Reading(SupportedType):
        @classmethod
        def convert(cls, output: Any, **_: Any) -> Any:
            return {"value": float(output)}

    with pytest.raises(ConfigError, match=r"'Reading' defines convert\(\) but neither _ros_type nor value_class"):
        add_additional_datatypes([Reading])
    with pytest.raises(ConfigError, match="Reading"):
        Topic("reading", Reading)
    assert "Reading" not in registered_types()

    class Plain(SupportedType):
        """No convert, no value class: any JSON-like value travels as it is (docs/porting.md)."""

    Topic("plain", Plain)  # still accepted


def test_detections_and_points_of_interest_carry_a_depth_image() -> None:
    depth = ImageMsg(data=np.full((4, 4), 1500, np.uint16), encoding="16UC1")
    detections = DetectionsMsg(boxes=[[0, 0, 2, 2]], labels=["cup"], scores=[0.9], depth=depth)
    points = PointsOfInterestMsg(points=[[1, 1]], depth=depth)
    got = _published(Topic("det", "Detections"), [(detections, {})])
    assert got[0].depth is depth
    assert _published(Topic("poi", "PointsOfInterest"), [(points, {})])[0].depth is depth
    assert DetectionsMsg().depth is None and PointsOfInterestMsg().depth is None
    zenoh_codecs = pytest.importorskip("agents_zenoh.codecs")
    for type_name, value in (("Detections", detections), ("PointsOfInterest", points)):
        msg_type = Topic("t", type_name).msg_type
        back = zenoh_codecs.decode_value(msg_type, zenoh_codecs.encode_value(msg_type, value))
        assert np.array_equal(back.depth.data, depth.data) and back.depth.encoding == "16UC1"


def test_the_detections_callback_gives_dicts_and_prompts_still_read_labels() -> None:
    topic = Topic("objects", "Detections")
    callback = callback_for(topic)
    assert isinstance(callback, callbacks.DetectionsCallback)
    callback._receive(DetectionsMsg(boxes=[[1, 2, 3, 4], [5, 6, 7, 8]], labels=["cup", "person"], scores=[0.9, 0.5]))
    assert callback.get_output() == [{"label": "cup", "score": pytest.approx(0.9), "box": [1.0, 2.0, 3.0, 4.0]},
                                     {"label": "person", "score": pytest.approx(0.5), "box": [5.0, 6.0, 7.0, 8.0]}]
    # Upstream's recipes put detections in an LLM prompt: they read as the labels, as upstream.
    question, answer = Topic("question", "String"), Topic("answer", "String")
    client = ScriptedChatClient(["ok"])
    llm = LLM(inputs=[question, topic], outputs=[answer], model_client=client, trigger=question)
    llm.set_topic_prompt(question, "Seen: {{ objects }}. {{ question }}")
    launcher = Launcher("memory")
    launcher.add_pkg(components=[llm])
    with launcher:
        answers: list[str] = []
        launcher.transport.create_subscription(answer, answers.append)
        launcher.transport.create_publisher(topic).publish(
            DetectionsMsg(boxes=[[1, 2, 3, 4]], labels=["cup"], scores=[0.9]))
        assert wait_for(lambda: llm.callbacks["objects"].got_msg)
        launcher.transport.create_publisher(question).publish("what is there?")
        assert wait_for(lambda: answers == ["ok"])
    assert client.inputs[0]["query"][-1]["content"].endswith("Seen: cup. what is there?")
