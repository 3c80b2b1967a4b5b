"""OllamaClient against a protocol-faithful Ollama double (tests/servers/ollama_server.py) on 127.0.0.1.

Covers what the client sends (messages, base64 PNG images, options, tools, keep_alive), what it
makes of the answers (text, NDJSON streams, tool calls with generated ids, embeddings), the
model lifecycle (show, pull with progress, load, unload) and every failure as a typed error.
"""

from __future__ import annotations

import base64
import json
import logging
import socket
import time
from collections.abc import Iterator

import numpy as np
import pytest

from agents_core.clients import client_from_spec
from agents_core.clients.ollama import OllamaClient
from agents_core.clients.payloads import ChunkStream
from agents_core.errors import (
    ClientConnectionError,
    ConfigError,
    HTTPStatusError,
    InferenceError,
    InferenceTimeoutError,
)
from agents_core.models import OllamaModel
from tests.servers.ollama_server import Fault, OllamaTestServer, fake_embedding

INSTALLED = "llama3.2:1b"
PULLABLE = "qwen3:0.6b"


@pytest.fixture
def server() -> Iterator[OllamaTestServer]:
    with OllamaTestServer(models=[INSTALLED], registry=[PULLABLE]) as srv:
        yield srv  # type: ignore[misc]
    assert srv.errors == [], "the double itself failed"


def make_client(port: int, checkpoint: str = INSTALLED, timeout: float = 5.0, **model_kwargs: object) -> OllamaClient:
    model = OllamaModel(name="llm", checkpoint=checkpoint, **model_kwargs)  # type: ignore[arg-type]
    return OllamaClient(model, host="127.0.0.1", port=port, inference_timeout=timeout)


@pytest.fixture
def client(server: OllamaTestServer) -> Iterator[OllamaClient]:
    c = make_client(server.port, options={"num_ctx": 2048, "temperature": 0.1}, keep_alive="10m")
    yield c
    c.close()


def closed_port() -> int:
    """A port nothing listens on (bound, then released)."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


# -- construction, serialization ----------------------------------------------------------------------


def test_constructor_does_no_io_and_round_trips() -> None:
    port = closed_port()
    client = make_client(port, options={"temperature": 0.2}, keep_alive=-1)
    assert client._client is None
    spec = client.serialize()
    assert spec["client_type"] == "OllamaClient"
    assert spec["model"]["model_init_params"] == {"checkpoint": INSTALLED, "options": {"temperature": 0.2},
                                                  "keep_alive": -1}
    rebuilt = client_from_spec(json.loads(json.dumps(spec)))
    assert isinstance(rebuilt, OllamaClient)
    assert rebuilt == client
    assert rebuilt.pull_timeout == client.pull_timeout
    assert client.supports_tool_calls
    assert OllamaClient(OllamaModel(name="m", checkpoint="c")).port == 11434
    assert OllamaClient(OllamaModel(name="m", checkpoint="c", port=12000)).port == 12000
    with pytest.raises(ConfigError, match="pull_timeout"):
        OllamaClient(OllamaModel(name="m", checkpoint="c"), pull_timeout=0)


def test_connection_refused_is_typed() -> None:
    client = make_client(closed_port(), timeout=1.0)
    with pytest.raises(ClientConnectionError, match="cannot reach the server"):
        client.check_connection()
    with pytest.raises(ClientConnectionError):
        client.inference({"query": [{"role": "user", "content": "hi"}]})
    client.close()


# -- lifecycle -------------------------------------------------------------------------------------------


def test_initialize_loads_an_installed_model(server: OllamaTestServer, client: OllamaClient) -> None:
    client.check_connection()
    assert client.server_version == server.version
    client.initialize()
    assert [r.json for r in server.requests_to("/api/show")] == [{"model": INSTALLED}]
    assert server.requests_to("/api/pull") == []
    load = server.requests_to("/api/generate")[-1].json
    # The load request carries the options: runner options such as num_ctx decide how Ollama loads.
    assert load == {"model": INSTALLED, "options": {"num_ctx": 2048, "temperature": 0.1}, "keep_alive": "10m",
                    "stream": False}
    assert "llama3.2:1b" in server.loaded
    client.deinitialize()
    unload = server.requests_to("/api/generate")[-1].json
    assert unload == {"model": INSTALLED, "keep_alive": 0, "stream": False}
    assert server.loaded == set()
    assert client._client is None


def test_initialize_pulls_a_missing_model_with_progress(server: OllamaTestServer,
                                                        caplog: pytest.LogCaptureFixture) -> None:
    client = make_client(server.port, checkpoint=PULLABLE)
    with caplog.at_level(logging.INFO, logger="agents_core.clients.OllamaClient"):
        client.initialize()
    client.close()
    assert [r.json for r in server.requests_to("/api/pull")] == [{"model": PULLABLE, "stream": True}]
    assert "qwen3:0.6b" in server.installed and "qwen3:0.6b" in server.loaded
    messages = [r.getMessage() for r in caplog.records]
    assert any("not present, pulling" in m for m in messages)
    progress = [m for m in messages if "%" in m]
    assert any("100%" in m for m in progress) and any(" 0%" in m for m in progress), progress
    assert any("pulling manifest" in m for m in messages)
    assert any("pulled 'qwen3:0.6b'" in m for m in messages)


def test_pull_failure_in_the_stream_is_typed(server: OllamaTestServer) -> None:
    client = make_client(server.port, checkpoint="no-such-model:7b")
    with pytest.raises(InferenceError, match="file does not exist"):
        client.initialize()
    assert not client.initialized
    client.close()


# -- chat ----------------------------------------------------------------------------------------------


def test_chat_request_shape(server: OllamaTestServer, client: OllamaClient) -> None:
    image = np.zeros((4, 6, 3), np.uint8)
    image[0, 0] = (255, 0, 0)
    query = [
        {"role": "system", "content": "You are a robot."},
        {"role": "user", "content": "What is 2+3?"},
        {"role": "assistant", "content": "",
         "tool_calls": [{"id": "call_0", "type": "function",
                         "function": {"name": "add", "arguments": {"a": 2, "b": 3}}}]},
        {"role": "tool", "content": "5", "tool_call_id": "call_0", "name": "add"},
        {"role": "user", "content": "And what do you see?", "images": [image]},
    ]
    result = client.inference({"query": query, "temperature": 0.5, "max_new_tokens": 20, "stream": False,
                               "chat_history": True})
    assert result == {"output": "You said: And what do you see?"}
    sent = server.requests_to("/api/chat")[-1].json
    assert sent["model"] == INSTALLED
    assert sent["stream"] is False
    assert sent["keep_alive"] == "10m"
    # Model options merged with the call's parameters; max_new_tokens is Ollama's num_predict.
    assert sent["options"] == {"num_ctx": 2048, "temperature": 0.5, "num_predict": 20}
    assert "chat_history" not in sent and "chat_history" not in sent["options"]
    assert "tools" not in sent
    messages = sent["messages"]
    assert [m["role"] for m in messages] == ["system", "user", "assistant", "tool", "user"]
    assert messages[2]["tool_calls"] == [{"function": {"name": "add", "arguments": {"a": 2, "b": 3}}}]
    assert messages[3] == {"role": "tool", "content": "5", "tool_name": "add"}
    png = base64.b64decode(messages[4]["images"][0])
    assert png.startswith(b"\x89PNG\r\n\x1a\n")
    assert "images" not in messages[1]


def test_streamed_answer_arrives_in_chunks(server: OllamaTestServer, client: OllamaClient) -> None:
    server.reply = "The red cube is on the table."
    result = client.inference({"query": [{"role": "user", "content": "Where?"}], "stream": True})
    stream = result["output"]
    assert isinstance(stream, ChunkStream)
    chunks = list(stream)
    assert len(chunks) == 7
    assert "".join(chunks) == server.reply
    assert stream.closed
    assert client.last_stats is not None and client.last_stats["eval_count"] == 7
    assert server.requests_to("/api/chat")[-1].json["stream"] is True


def test_closing_a_stream_early_releases_the_connection(server: OllamaTestServer, client: OllamaClient) -> None:
    server.reply = "one two three four five six"
    stream = client.inference({"query": "count", "stream": True})["output"]
    assert next(stream) == "one "
    stream.close()
    assert stream.closed
    # The pool is usable again straight away.
    server.reply = None
    assert client.inference({"query": "again"})["output"] == "You said: again"


def test_tool_calls_get_ids(server: OllamaTestServer, client: OllamaClient) -> None:
    server.tool_calls = [{"name": "get_weather", "arguments": {"city": "Paris"}},
                         {"name": "get_time", "arguments": {}}]
    tools = [{"type": "function", "function": {
        "name": "get_weather", "description": "Weather for a city",
        "parameters": {"type": "object", "properties": {"city": {"type": "string"}}, "required": ["city"]}}}]
    result = client.inference({"query": "Weather in Paris?", "tools": tools, "stream": True})
    assert result["output"] == ""
    assert result["tool_calls"] == [
        {"id": "call_0", "type": "function", "function": {"name": "get_weather", "arguments": {"city": "Paris"}}},
        {"id": "call_1", "type": "function", "function": {"name": "get_time", "arguments": {}}},
    ]
    sent = server.requests_to("/api/chat")[-1].json
    assert sent["tools"] == tools
    assert sent["stream"] is False, "tool requests are read whole"


def test_generate_plain_and_streamed(server: OllamaTestServer, client: OllamaClient) -> None:
    assert client.generate("hello there", temperature=0.0) == "You said: hello there"
    sent = server.requests_to("/api/generate")[-1].json
    assert sent["prompt"] == "hello there" and sent["stream"] is False
    assert sent["options"]["temperature"] == 0.0
    stream = client.generate("a b c", images=[np.zeros((2, 2, 3), np.uint8)], system="Be brief.", stream=True)
    assert isinstance(stream, ChunkStream)
    assert list(stream) == ["You ", "said: ", "a ", "b ", "c"]
    sent = server.requests_to("/api/generate")[-1].json
    assert sent["system"] == "Be brief." and base64.b64decode(sent["images"][0]).startswith(b"\x89PNG")


def test_embed(server: OllamaTestServer, client: OllamaClient) -> None:
    texts = ["red cube", "blue ball"]
    assert client.embed(texts) == [fake_embedding(t) for t in texts]
    sent = server.requests_to("/api/embed")[-1].json
    assert sent["input"] == texts and sent["model"] == INSTALLED


def test_unload(server: OllamaTestServer, client: OllamaClient) -> None:
    client.load()
    assert "llama3.2:1b" in server.loaded
    client.unload()
    assert server.loaded == set()


# -- failures ------------------------------------------------------------------------------------------


def test_unknown_model_is_http_404_with_ollamas_message(server: OllamaTestServer) -> None:
    client = make_client(server.port, checkpoint="ghost:1b")
    with pytest.raises(HTTPStatusError, match=r'404.*model "ghost:1b" not found, try pulling it first') as info:
        client.inference({"query": "hi"})
    assert info.value.status == 404
    client.close()


def test_server_error_status_is_typed(server: OllamaTestServer, client: OllamaClient) -> None:
    server.add_fault(Fault("/api/chat", "status", status=500, message="llama runner process has terminated"))
    with pytest.raises(HTTPStatusError, match=r"500.*llama runner process has terminated") as info:
        client.inference({"query": "hi"})
    assert info.value.status == 500
    with pytest.raises(HTTPStatusError, match="llama runner process has terminated"):
        client.inference({"query": "hi", "stream": True})


def test_connection_dropped_mid_stream_raises_while_iterating(server: OllamaTestServer,
                                                              client: OllamaClient) -> None:
    server.reply = "one two three four five"
    server.add_fault(Fault("/api/chat", "die", after=2))
    stream = client.inference({"query": "count", "stream": True})["output"]
    got: list[str] = []
    start = time.monotonic()
    with pytest.raises(ClientConnectionError, match="reading the stream"):
        for chunk in stream:
            got.append(chunk)
    assert got == ["one ", "two "]
    assert time.monotonic() - start < 2.0
    assert stream.closed


def test_error_object_mid_stream_is_typed(server: OllamaTestServer, client: OllamaClient) -> None:
    server.reply = "one two three"
    server.add_fault(Fault("/api/chat", "stream_error", after=1, message="out of memory"))
    stream = client.inference({"query": "count", "stream": True})["output"]
    assert next(stream) == "one "
    with pytest.raises(InferenceError, match="failed mid-stream: out of memory"):
        next(stream)


def test_silent_server_times_out(server: OllamaTestServer) -> None:
    client = make_client(server.port, timeout=0.5)
    server.add_fault(Fault("/api/chat", "hang", seconds=5.0))
    start = time.monotonic()
    with pytest.raises(InferenceTimeoutError, match="timed out"):
        client.inference({"query": "hi"})
    elapsed = time.monotonic() - start
    assert 0.4 < elapsed < 2.0, elapsed
    client.close()

