"""Secrets never leak through what a server answers: errors, status messages, logs.

A real server (tests/servers/faults.py) echoes the API key in its error bodies and mid-stream
errors. The exception text, its traceback (chained causes included), the component's
``<name>/status`` messages and the log records must show ``***`` where the key was. Ollama and
Chroma clients take an API key too: sent on every request, hidden from ``repr()``, kept by
``serialize()``.
"""

from __future__ import annotations

import logging
import traceback
from collections.abc import Iterator
from typing import Any

import pytest

from agents_core import Launcher, Topic
from agents_core.clients import ChromaClient, GenericHTTPClient, ModelClient, OllamaClient, client_from_spec
from agents_core.clients.client_base import scrub_exception, scrub_text
from agents_core.components import LLM
from agents_core.config import LLMConfig
from agents_core.errors import ConfigError, HTTPStatusError, InferenceError, ModelClientError
from agents_core.models import GenericLLM, OllamaModel
from agents_core.vectordbs import ChromaDB

from ..conftest import wait_for
from ..servers.faults import FaultServer

KEY = "sk-test-7f3a9c1e5b2d4680"


@pytest.fixture
def server() -> Iterator[FaultServer]:
    with FaultServer() as srv:
        yield srv  # type: ignore[misc]


def _clients(port: int) -> list[ModelClient]:
    return [GenericHTTPClient(GenericLLM(name="m", checkpoint="m"), port=port, api_key=KEY, inference_timeout=5),
            OllamaClient(OllamaModel(name="m", checkpoint="m"), port=port, api_key=KEY, inference_timeout=5)]


def _no_key(text: str) -> None:
    assert KEY not in text
    assert KEY[3:] not in text, "not even the part after the prefix"


def _full_text(exc: BaseException) -> str:
    return "".join(traceback.format_exception(exc))


@pytest.mark.parametrize("mode", ["echo_auth", "key_in_json_500", "key_mid_stream"])
@pytest.mark.parametrize("stream", [False, True], ids=["whole", "stream"])
def test_server_errors_quoting_the_key_are_scrubbed(server: FaultServer, mode: str, stream: bool,
                                                    caplog: pytest.LogCaptureFixture) -> None:
    server.mode = mode
    for client in _clients(server.port):
        with caplog.at_level(logging.DEBUG), pytest.raises(ModelClientError) as info:
            output = client.inference({"query": "hi", "stream": stream})["output"]
            "".join(output)
        if mode == "key_mid_stream":
            # Asked for a whole answer, the client gets a stream: not JSON (ProtocolError quoting it).
            assert isinstance(info.value, InferenceError if stream else ModelClientError), repr(info.value)
        else:
            assert isinstance(info.value, HTTPStatusError), repr(info.value)
        assert "***" in str(info.value), str(info.value)
        _no_key(str(info.value))
        _no_key(_full_text(info.value))
        # The server did get the key, as a bearer token.
        assert server.requests[-1].headers["authorization"] == f"Bearer {KEY}"
        client.close()
    _no_key(caplog.text)


def test_the_environment_key_is_scrubbed_too(server: FaultServer, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("OPENAI_API_KEY", KEY)
    server.mode = "key_in_json_500"
    client = GenericHTTPClient(GenericLLM(name="m", checkpoint="m"), port=server.port, inference_timeout=5)
    with pytest.raises(HTTPStatusError, match=r"500.*for key \*\*\*") as info:
        client.inference({"query": "hi"})
    _no_key(_full_text(info.value))
    client.close()


def test_client_log_records_are_scrubbed(server: FaultServer, caplog: pytest.LogCaptureFixture) -> None:
    client = _clients(server.port)[1]
    with caplog.at_level(logging.DEBUG):
        client.logger.warning("server said: %s", f"bad token {KEY}")
        try:
            raise RuntimeError(f"Authorization: Bearer {KEY}")
        except RuntimeError:
            client.logger.exception("request failed")
    assert "server said: bad token ***" in caplog.text
    assert "Bearer ***" in caplog.text
    _no_key(caplog.text)


def test_scrub_helpers() -> None:
    assert scrub_text(f"key={KEY}&x=1 Authorization: Bearer other-token", [KEY]) == \
        "key=***&x=1 Authorization: Bearer ***"
    assert scrub_text('{"k": "a\\"b"}', ['a"b']) == '{"k": "***"}', "the JSON-escaped form too"
    inner = ValueError(f"echo {KEY}")
    outer = InferenceError("failed")
    outer.__cause__ = inner
    scrub_exception(outer, [KEY])
    assert str(inner) == "echo ***"

    class Opaque(Exception):
        def __str__(self) -> str:
            return f"opaque {KEY}"

    chained = InferenceError("failed")
    chained.__cause__ = Opaque()
    scrub_exception(chained, [KEY])
    assert chained.__cause__ is None, "a cause that cannot be scrubbed is cut from the chain"


# -- API keys of the Ollama and Chroma clients ------------------------------------------------------


def test_ollama_client_sends_its_key_and_hides_it(server: FaultServer) -> None:
    client = OllamaClient(OllamaModel(name="m", checkpoint="m"), port=server.port, api_key=KEY)
    client.check_connection()
    assert client.inference({"query": "hi"})["output"] == server.reply
    assert {r.headers.get("authorization") for r in server.requests} == {f"Bearer {KEY}"}
    _no_key(repr(client))
    assert "api_key='***'" in repr(client)
    spec = client.serialize()
    assert spec["api_key"] == KEY, "serialize() keeps it, to rebuild the client in a child process"
    assert client_from_spec(spec) == client
    client.close()
    keyless = OllamaClient(OllamaModel(name="m", checkpoint="m"), port=server.port)
    keyless.check_connection()
    assert "authorization" not in server.requests[-1].headers
    with pytest.raises(ConfigError, match="api_key"):
        OllamaClient(OllamaModel(name="m", checkpoint="m"), api_key="")


@pytest.mark.parametrize(("auth_header", "expected"), [("Authorization", ("authorization", f"Bearer {KEY}")),
                                                       ("X-Chroma-Token", ("x-chroma-token", KEY))])
def test_chroma_client_sends_its_token_and_hides_it(server: FaultServer, auth_header: str,
                                                    expected: tuple[str, str]) -> None:
    client = ChromaClient(ChromaDB(name="map"), port=server.port, api_key=KEY, auth_header=auth_header,
                          connection_retries=0)
    # The double serves no Chroma routes; what matters is what was sent and what the error shows.
    server.mode = "echo_auth"
    with pytest.raises(HTTPStatusError) as info:
        client.check_connection()
    name, value = expected
    assert server.requests[-1].headers[name] == value
    _no_key(_full_text(info.value))
    _no_key(repr(client))
    spec = client.serialize()
    assert (spec["api_key"], spec["auth_header"]) == (KEY, auth_header)
    assert client_from_spec(spec) == client
    with pytest.raises(ConfigError, match="auth_header"):
        ChromaClient(ChromaDB(name="map"), api_key=KEY, auth_header="Bad Header:")


# -- a component's status ---------------------------------------------------------------------------


def test_component_status_and_logs_never_show_the_key(server: FaultServer, caplog: pytest.LogCaptureFixture) -> None:
    server.mode = "echo_auth"
    question, answer = Topic("question", "String"), Topic("answer", "String")
    client = GenericHTTPClient(GenericLLM(name="m", checkpoint="m"), port=server.port, api_key=KEY,
                               inference_timeout=5)
    llm = LLM(inputs=[question], outputs=[answer], model_client=client, config=LLMConfig(), trigger=question,
              component_name="leaky")
    launcher = Launcher("memory")
    launcher.add_pkg(components=[llm])
    statuses: list[Any] = []
    with caplog.at_level(logging.DEBUG), launcher:
        launcher.transport.create_subscription(llm.status_topic, statuses.append)
        launcher.transport.create_publisher(question).publish("hi")
        # An error answer is an inference that failed: ALGORITHM_FAILURE, as upstream.
        assert wait_for(lambda: any(s.health == "ALGORITHM_FAILURE" for s in statuses), timeout=10)
    failure = next(s for s in statuses if s.health == "ALGORITHM_FAILURE")
    assert "HTTPStatusError" in failure.message and "Bearer ***" in failure.message, failure.message
    for status in statuses:
        _no_key(status.message)
    _no_key(caplog.text)
