"""The CLI's value handling (parse for ``pub``, summarise for ``echo``) and Zenoh options from the environment."""

from __future__ import annotations

import numpy as np
import pytest

from agents_core.cli.connection import open_transport
from agents_core.cli.values import parse_call_argument, parse_value, summarize
from agents_core.errors import ConfigError
from agents_core.messages import ImageMsg
from agents_core.supported_types import get_type


def test_parse_value_reads_json_objects_numbers_and_bare_strings() -> None:
    twist = parse_value(get_type("Twist"), '{"linear": [0.2, 0, 0], "angular": [0, 0, 0.5]}')
    assert twist.linear.tolist() == [0.2, 0.0, 0.0] and twist.angular.tolist() == [0.0, 0.0, 0.5]
    assert parse_value(get_type("Float32"), "2.5") == 2.5
    assert parse_value(get_type("String"), "42") == "42"  # text stays text, even when it reads as JSON
    assert parse_value(get_type("String"), "hello there") == "hello there"
    assert parse_value(get_type("Bool"), "true") is True


@pytest.mark.parametrize(("type_name", "text", "message"), [
    ("Float32", "abc", "does not fit Float32"),
    ("Bool", "[1, 2]", "does not fit Bool"),
    ("Twist", '{"linear": [1, 2], "wings": 3}', "does not fit Twist"),
])
def test_parse_value_refuses_what_does_not_fit(type_name: str, text: str, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        parse_value(get_type(type_name), text)


def test_call_arguments_are_json_literals_or_strings() -> None:
    assert parse_call_argument("3") == 3
    assert parse_call_argument('{"a": [1]}') == {"a": [1]}
    assert parse_call_argument("bonjour") == "bonjour"


def test_summaries_never_carry_large_arrays_or_bytes() -> None:
    image = ImageMsg(data=np.zeros((480, 640, 3), np.uint8))
    doc = summarize(image)
    assert doc["data"] == {"shape": [480, 640, 3], "dtype": "uint8"}
    assert doc["header"]["frame_id"] == ""
    assert summarize(b"\x00" * 5000) == {"bytes": 5000}
    assert summarize(np.arange(3, dtype=np.float32)) == [0.0, 1.0, 2.0]
    assert summarize(list(range(1000))) == {"length": 1000}
    assert summarize(float("nan")) == "nan"
    assert len(summarize("x" * 10_000)) < 2100


def test_the_memory_transport_cannot_be_inspected_from_outside() -> None:
    with pytest.raises(ConfigError, match="memory transport lives inside one process"), open_transport("memory"):
        pass


def test_connect_is_a_zenoh_option_only() -> None:
    with pytest.raises(ConfigError, match=r"--connect is a Zenoh .*option; the ros2 transport does not take it"), \
            open_transport("ros2", ["tcp/127.0.0.1:7447"]):
        pass


def test_zenoh_options_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("zenoh")
    from agents_zenoh.transport import options_from_environment  # noqa: PLC0415

    monkeypatch.delenv("AGENTS_ZENOH_MODE", raising=False)
    monkeypatch.delenv("AGENTS_ZENOH_NAMESPACE", raising=False)
    monkeypatch.delenv("AGENTS_ZENOH_LISTEN", raising=False)
    monkeypatch.setenv("AGENTS_ZENOH_CONNECT", "tcp/10.0.0.2:7447, tcp/10.0.0.3:7447")
    assert options_from_environment() == {"connect": ["tcp/10.0.0.2:7447", "tcp/10.0.0.3:7447"], "mode": "client"}
    monkeypatch.setenv("AGENTS_ZENOH_LISTEN", "tcp/127.0.0.1:7600")
    assert options_from_environment() == {"connect": ["tcp/10.0.0.2:7447", "tcp/10.0.0.3:7447"],
                                          "listen": ["tcp/127.0.0.1:7600"]}
    monkeypatch.setenv("AGENTS_ZENOH_MODE", "peer")
    monkeypatch.setenv("AGENTS_ZENOH_NAMESPACE", "robot1")
    assert options_from_environment()["mode"] == "peer"
    assert options_from_environment()["namespace"] == "robot1"
