"""The upstream way of adding a message type (messages.md, custom_component.md) works unchanged.

The SemanticLabel sample of the upstream guide, with ``agents`` -> ``agents_core`` and the
message built into ``agents_interfaces`` (interfaces/msg/SemanticLabel.msg): ``convert`` runs on
publish, the callback's ``_msg_to_output`` is what ``get_output()`` returns, a value that does not
fit is refused naming the type and field, on memory, Zenoh and ROS 2.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from agents_core import supported_types
from agents_core.callbacks import GenericCallback, callback_for
from agents_core.errors import ConfigError, TypeValidationError
from agents_core.supported_types import SupportedType, add_additional_datatypes, registered_types
from agents_core.testing.helpers import wait_for
from agents_core.testing.pairs import memory_pair, missing_requirement, pair_factory
from agents_core.topics import FixedInput, Topic

ros_msgs = pytest.importorskip("agents_interfaces.msg", reason="the sample's message is built into agents_interfaces")
ROSSemanticLabel = ros_msgs.SemanticLabel


# --- the upstream sample, as written there (agents -> agents_core) ------------------------------


class SemanticLabelCallback(GenericCallback):
    """Callback for SemanticLabel messages."""

    def _msg_to_output(self, msg) -> dict:  # type: ignore[no-untyped-def]
        """Convert a SemanticLabel ROS message to a Python dict."""
        return {
            "label": msg.label,
            "confidence": msg.confidence,
        }


class SemanticLabel(SupportedType):
    """Wraps agents_interfaces/msg/SemanticLabel."""

    _ros_type = ROSSemanticLabel
    callback = SemanticLabelCallback

    @classmethod
    def convert(cls, output: dict, **_) -> ROSSemanticLabel:  # type: ignore[no-untyped-def,override,valid-type]
        msg = ROSSemanticLabel()
        msg.label = output["label"]
        msg.confidence = float(output["confidence"])
        return msg


@pytest.fixture(autouse=True, scope="module")
def _forget_the_sample() -> Iterator[None]:
    """Free the name "SemanticLabel" (and what the adapters derived for it) for the tests that run later."""
    yield
    if registered_types().get("SemanticLabel") is SemanticLabel:
        supported_types._registry.unregister("SemanticLabel")
    with contextlib.suppress(ImportError):
        from agents_zenoh.codecs import registry  # noqa: PLC0415  # only where the zenoh extra is installed

        registry._codecs.unregister("SemanticLabel")
    with contextlib.suppress(ImportError):
        from agents_ros2 import conversions  # noqa: PLC0415  # only where the ros2 extra is installed

        conversions._conversions.unregister("SemanticLabel")


def _register() -> None:
    if registered_types().get("SemanticLabel") is not SemanticLabel:
        # Another test registers a SemanticLabel of its own in the process-wide registry: take the name over.
        supported_types._registry.unregister("SemanticLabel")
        add_additional_datatypes([SemanticLabel])


@contextlib.contextmanager
def _pair(name: str) -> Iterator[tuple[Any, Any]]:
    if name != "memory" and missing_requirement(name):
        pytest.skip(missing_requirement(name) or "")
    factory = memory_pair if name == "memory" else pair_factory(name)
    with factory() as pair:
        yield pair


@pytest.mark.parametrize("transport", ["memory", "zenoh", "ros2"])
def test_the_upstream_sample_works_on_every_transport(transport: str) -> None:
    _register()
    topic = Topic(name="semantic_label", msg_type="SemanticLabel")
    assert topic.msg_type is SemanticLabel
    with _pair(transport) as (a, b):
        callback = callback_for(topic)
        assert type(callback) is SemanticLabelCallback
        received: list[Any] = []

        def on_value(value: Any) -> None:
            callback._receive(value)
            received.append(value)

        sub = b.create_subscription(topic, on_value)
        pub = a.create_publisher(topic)
        sent = {"label": "door", "confidence": 0.75}
        assert wait_for(lambda: (pub.publish(sent), bool(received))[1], timeout=10.0, interval=0.1)
        assert isinstance(received[-1], ROSSemanticLabel)  # convert ran on publish
        assert callback.get_output() == sent  # the callback's output method gives get_output()

        # A value that does not fit is refused on publish, naming the type and the field.
        with pytest.raises(TypeValidationError, match=r"SemanticLabel.*int"):
            pub.publish(12345)
        with pytest.raises(TypeValidationError, match="SemanticLabel: field 'confidence' is missing"):
            pub.publish({"label": "door"})
        with pytest.raises(TypeValidationError, match=r"SemanticLabel.*'label'"):
            pub.publish({"label": 3, "confidence": 0.5})
        sub.close()
        pub.close()


def test_the_ros_message_is_what_travels_on_ros2() -> None:
    pytest.importorskip("rclpy")
    from agents_ros2.conversions import conversion_for  # noqa: PLC0415  # only where the ros2 extra is installed

    _register()
    assert conversion_for(SemanticLabel).ros_type is ROSSemanticLabel


def test_the_zenoh_document_is_the_messages_fields() -> None:
    pytest.importorskip("msgpack")
    from agents_zenoh.codecs import decode_value, describe_schemas, encode_value  # noqa: PLC0415  # zenoh extra

    _register()
    value = SemanticLabel.validate({"label": "cup", "confidence": 0.5})
    value.image.height, value.image.width, value.image.step, value.image.encoding = 1, 2, 6, "rgb8"
    value.image.data = bytes(range(6))
    back = decode_value(SemanticLabel, encode_value(SemanticLabel, value))
    assert back == value
    assert describe_schemas()["SemanticLabel"].startswith('{"label": string, "confidence": float')


def test_a_fixed_input_of_the_type_uses_its_callback() -> None:
    _register()
    fixed = FixedInput("label_in", "SemanticLabel", fixed={"label": "x", "confidence": 1})
    callback = callback_for(fixed)
    assert isinstance(callback, SemanticLabelCallback)
    assert callback.get_output() == {"label": "x", "confidence": 1.0}


class _Missing(SupportedType):
    _ros_type = "no_such_interfaces/msg/Thing"


def test_a_ros_type_from_a_package_that_is_not_installed_fails_at_topic_creation() -> None:
    with pytest.raises(ConfigError, match=r"no_such_interfaces/msg/Thing.*'no_such_interfaces' is not installed"):
        Topic("thing", _Missing)


def test_a_callback_that_is_not_a_generic_callback_is_refused() -> None:
    class Odd(SupportedType):
        value_class = str
        callback = dict  # type: ignore[assignment]

    with pytest.raises(ConfigError, match="GenericCallback subclass"):
        callback_for(Topic("odd", Odd))


def test_numpy_input_to_the_sample_is_converted_too() -> None:
    _register()
    value = SemanticLabel.validate({"label": "cup", "confidence": np.float32(0.25)})
    assert value.confidence == 0.25
