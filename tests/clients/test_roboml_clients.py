"""RoboML's HTTP, WebSocket and RESP clients against a protocol-faithful double (tests/servers/roboml_server.py).

Covers the node lifecycle each client drives (add, initialize with the model's init parameters,
remove), the inputs it sends for every RoboML model class (numpy images and audio included), the
WebSocket's streaming and reply ordering, reconnection, and every failure as a typed error.
"""

from __future__ import annotations

import base64
import importlib.util
import queue
import socket
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import msgpack
import numpy as np
import pytest
from attrs import define

from agents_core.clients import RoboMLHTTPClient, RoboMLRESPClient, RoboMLWSClient, client_from_spec
from agents_core.clients.model_base import ModelClient
from agents_core.clients.payloads import ChunkStream
from agents_core.clients.roboml import RESPONSE_ENDED, packb, unpackb
from agents_core.errors import (
    ClientConnectionError,
    ConfigError,
    HTTPStatusError,
    InferenceError,
    InferenceTimeoutError,
    ProtocolError,
)
from agents_core.models import (
    LeRobotPolicy,
    Model,
    OllamaModel,
    RoboBrain2,
    TransformersLLM,
    TransformersMLLM,
    TransformersTTS,
    VisionModel,
    Whisper,
)
from tests.conftest import wait_for
from tests.servers.roboml_server import RoboMLTestServer, decode_png

# redis-py is the RESP client's one optional dependency: without it only the RESP cases skip.
HAVE_REDIS = importlib.util.find_spec("redis") is not None
HTTP = pytest.param(RoboMLHTTPClient, id="http")
WS = pytest.param(RoboMLWSClient, id="ws")
RESP = pytest.param(RoboMLRESPClient, id="resp", marks=pytest.mark.skipif(not HAVE_REDIS, reason="needs redis"))
CLIENTS = [HTTP, WS, RESP]
TRANSPORT = {RoboMLHTTPClient: "http", RoboMLWSClient: "ws", RoboMLRESPClient: "resp"}
ALL_MODELS = [TransformersLLM, TransformersMLLM, RoboBrain2, Whisper, TransformersTTS, VisionModel]

Factory = Callable[..., Any]


@pytest.fixture
def server() -> Iterator[RoboMLTestServer]:
    with RoboMLTestServer() as srv:
        yield srv
    assert srv.errors == [], "the double itself failed"


@pytest.fixture
def make(server: RoboMLTestServer) -> Iterator[Factory]:
    """Build clients pointed at the double (RESP clients at its RESP port); all closed afterwards."""
    made: list[Any] = []

    def factory(cls: type[ModelClient], model: Model | None = None, timeout: float = 5.0,
                port: int | None = None) -> Any:
        if port is None:
            port = server.resp_port if cls is RoboMLRESPClient else server.port
        client = cls(model or TransformersLLM(name="llm"), port=port, inference_timeout=timeout)  # type: ignore[call-arg]
        made.append(client)
        return client

    yield factory
    for client in made:
        client.close()


def closed_port() -> int:
    """A port nothing listens on (bound, then released)."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def ready(client: Any) -> Any:
    client.check_connection()
    client.initialize()
    return client


def chat(text: str, **extra: Any) -> dict[str, Any]:
    return {"query": [{"role": "system", "content": "You are a robot."}, {"role": "user", "content": text}], **extra}


def image(height: int = 6, width: int = 8, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 256, (height, width, 3), dtype=np.uint8)


def sent_image(server: RoboMLTestServer, transport: str) -> np.ndarray:
    """The image the double received in the last inference, decoded as RoboML would."""
    img = server.calls_of("inference", transport)[-1].payload["images"][0]
    return img if isinstance(img, np.ndarray) else decode_png(base64.b64decode(img))


# -- construction, lifecycle, serialization -------------------------------------------------------


@pytest.mark.parametrize("cls", CLIENTS)
def test_constructor_does_no_io(cls: type[ModelClient], server: RoboMLTestServer, make: Factory) -> None:
    client = make(cls)
    make(cls, port=closed_port())  # nothing listens: still no error
    assert server.calls == []
    assert getattr(client, "_http", None) is None and getattr(client, "_redis", None) is None


@pytest.mark.parametrize("cls", CLIENTS)
def test_lifecycle_calls_in_order_with_init_params(cls: type[ModelClient], server: RoboMLTestServer,
                                                   make: Factory) -> None:
    model = TransformersLLM(name="planner", checkpoint="Qwen/Qwen3-1.7B", quantization="8bit",
                            system_prompt="Be brief.", source="modelscope")
    client = ready(make(cls, model))
    assert server.nodes["planner"].model == "TransformersLLM"
    assert server.nodes["planner"].status == "READY" and client.node_status() == "READY"
    client.deinitialize()
    assert "planner" not in server.nodes and not client.initialized
    lifecycle = [c for c in server.calls if c.op in ("add_node", "initialize", "remove_node")]
    assert [c.op for c in lifecycle] == ["add_node", "initialize", "remove_node"]
    assert lifecycle[0].payload == {"node_name": "planner", "node_model": "TransformersLLM"}
    assert lifecycle[1].payload == {"checkpoint": "Qwen/Qwen3-1.7B", "quantization": "8bit",
                                    "system_prompt": "Be brief.", "source": "modelscope"}
    assert lifecycle[2].payload == {"node_name": "planner"}
    assert {c.transport for c in lifecycle} == {"resp" if cls is RoboMLRESPClient else "http"}


@pytest.mark.parametrize("model_cls", ALL_MODELS)
@pytest.mark.parametrize("cls", [HTTP, RESP])
def test_every_model_initializes_with_what_roboml_accepts(cls: type[ModelClient], model_cls: type[Model],
                                                          server: RoboMLTestServer, make: Factory) -> None:
    # The double rejects any keyword RoboML 0.6.1's _initialize does not take, as validate_call does.
    ready(make(cls, model_cls(name="m", source="huggingface")))  # type: ignore[call-arg]
    assert server.nodes["m"].model == model_cls.__name__ and server.nodes["m"].status == "READY"


def test_subclass_of_a_roboml_model_runs_on_its_roboml_class(server: RoboMLTestServer, make: Factory) -> None:
    @define(kw_only=True)
    class TinyLLM(TransformersLLM):
        checkpoint: str = "HuggingFaceTB/SmolLM2-135M-Instruct"

    client = ready(make(RoboMLHTTPClient, TinyLLM(name="tiny")))
    assert client.node_model == "TransformersLLM" and server.nodes["tiny"].model == "TransformersLLM"


@pytest.mark.parametrize("cls", CLIENTS)
def test_models_roboml_cannot_serve_and_bad_node_names_are_config_errors(cls: type[ModelClient]) -> None:
    for model in (OllamaModel(name="o", checkpoint="llama3.2:1b"), LeRobotPolicy(name="p")):
        with pytest.raises(ConfigError, match="RoboML cannot serve"):
            cls(model)  # type: ignore[call-arg]
    with pytest.raises(ConfigError, match="cannot name a RoboML node"):
        cls(TransformersLLM(name="my.llm"))  # type: ignore[call-arg]


@pytest.mark.parametrize("cls", CLIENTS)
def test_serialize_round_trip_gives_an_equal_working_client(cls: type[ModelClient], server: RoboMLTestServer,
                                                            make: Factory) -> None:
    client = make(cls, VisionModel(name="eyes", setup_trackers=True, num_trackers=2), timeout=3)
    rebuilt = client_from_spec(client.serialize())
    assert rebuilt == client and type(rebuilt) is cls
    assert rebuilt.node_model == "VisionModel"  # type: ignore[attr-defined]
    try:
        ready(rebuilt)
        assert server.calls_of("initialize")[-1].payload == VisionModel(name="eyes", setup_trackers=True,
                                                                        num_trackers=2)._get_init_params()
        assert rebuilt.inference({"images": [image()]})["output"][0]["labels"] == ["object"]  # type: ignore[attr-defined]
    finally:
        rebuilt.close()  # type: ignore[attr-defined]


def test_server_rejecting_init_params_is_a_typed_error(server: RoboMLTestServer, make: Factory) -> None:
    spec = make(RoboMLHTTPClient, Whisper(name="ears")).serialize()
    spec["model"]["model_init_params"]["beam_size"] = 5  # not a keyword of RoboML's Whisper._initialize
    http = client_from_spec(spec)
    spec_resp = dict(spec, client_type="RoboMLRESPClient", port=server.resp_port)
    resp = client_from_spec(spec_resp)
    try:
        with pytest.raises(HTTPStatusError, match=r"Initialization Error.*beam_size") as info:
            http.initialize()  # type: ignore[attr-defined]
        assert info.value.status == 500
        server.nodes.clear()
        with pytest.raises(InferenceError, match=r"VALIDATION_ERROR.*beam_size"):
            resp.initialize()  # type: ignore[attr-defined]
    finally:
        http.close()  # type: ignore[attr-defined]
        resp.close()  # type: ignore[attr-defined]


# -- what each model's inference sends and returns ----------------------------------------------


@pytest.mark.parametrize("cls", CLIENTS)
def test_chat_input_shape(cls: type[ModelClient], server: RoboMLTestServer, make: Factory) -> None:
    client = ready(make(cls))
    query = [{"role": "system", "content": "You are a robot."},
             {"role": "user", "content": "add 2 and 3"},
             {"role": "assistant", "content": "", "tool_calls": [{"id": "c0", "type": "function",
                                                                   "function": {"name": "add", "arguments": {}}}]},
             {"role": "tool", "content": "5", "tool_call_id": "c0", "name": "add"},
             {"role": "user", "content": "and now?"}]
    result = client.inference({"query": query, "temperature": 0.2, "max_new_tokens": 64, "tools": [],
                               "chat_history": True})
    assert result["output"] == "echo: and now?"
    sent = server.calls_of("inference", TRANSPORT[cls])[-1].payload
    assert sent == {"query": [{"role": m["role"], "content": m["content"]} for m in query],
                    "temperature": 0.2, "max_new_tokens": 64, "stream": False}


@pytest.mark.parametrize("cls", CLIENTS)
def test_numpy_image_round_trip(cls: type[ModelClient], server: RoboMLTestServer, make: Factory) -> None:
    client = ready(make(cls, TransformersMLLM(name="vlm")))
    picture = image(7, 9, seed=3)
    message = {"role": "user", "content": "what is this?", "images": [picture]}
    result = client.inference({"query": [message], "temperature": 0.5})
    assert result["output"] == "echo: what is this? | images: 7x9x3"
    received = sent_image(server, TRANSPORT[cls])
    assert received.dtype == np.uint8 and np.array_equal(received, picture)
    payload = server.calls_of("inference", TRANSPORT[cls])[-1].payload
    # JSON carries base64 PNG; the msgpack transports carry the array (msgpack-numpy's format).
    assert isinstance(payload["images"][0], str if cls is RoboMLHTTPClient else np.ndarray)
    assert "images" not in payload["query"][0]


@pytest.mark.parametrize("cls", CLIENTS)
def test_mllm_without_an_image_fails_before_sending(cls: type[ModelClient], server: RoboMLTestServer,
                                                    make: Factory) -> None:
    client = ready(make(cls, TransformersMLLM(name="vlm")))
    with pytest.raises(InferenceError, match="at least one image"):
        client.inference(chat("hello"))
    assert server.calls_of("inference") == []


@pytest.mark.parametrize("cls", CLIENTS)
def test_detection_with_tracking(cls: type[ModelClient], server: RoboMLTestServer, make: Factory) -> None:
    client = ready(make(cls, VisionModel(name="eyes", setup_trackers=True, num_trackers=2)))
    frames = [image(10, 20), image(30, 40, seed=1)]
    result = client.inference({"images": frames, "threshold": 0.3, "labels_to_track": ["object"],
                               "get_dataset_labels": True})
    assert [r["bboxes"][0][2:] for r in result["output"]] == [[20.0, 10.0], [40.0, 30.0]]
    assert all(r["ids"] == [1] for r in result["output"])
    sent = server.calls_of("inference", TRANSPORT[cls])[-1].payload
    assert sent["threshold"] == 0.3 and sent["labels_to_track"] == ["object"]
    assert np.array_equal(sent_image(server, TRANSPORT[cls]), frames[0])


@pytest.mark.parametrize("cls", CLIENTS)
def test_planning_model_gets_its_task(cls: type[ModelClient], server: RoboMLTestServer, make: Factory) -> None:
    client = ready(make(cls, RoboBrain2(name="brain")))
    result = client.inference(chat("where is the cup?", images=[image()], task="pointing", stream=True))
    assert result["output"] == [[12, 34]] and result.get("thinking", "") == ""
    sent = server.calls_of("inference", TRANSPORT[cls])[-1].payload
    assert sent["task"] == "pointing" and "stream" not in sent  # RoboBrain2 never streams


@pytest.mark.parametrize("cls", CLIENTS)
def test_speech_synthesis_returns_wav_bytes(cls: type[ModelClient], server: RoboMLTestServer, make: Factory) -> None:
    client = ready(make(cls, TransformersTTS(name="voice")))
    result = client.inference({"query": "hello robot", "voice": "v2/en_speaker_1"})
    assert isinstance(result["output"], bytes) and result["output"][:4] == b"RIFF"
    sent = server.calls_of("inference", TRANSPORT[cls])[-1].payload
    # JSON cannot hold bytes, so RoboML answers base64 there; msgpack carries the WAV as is.
    assert sent == {"query": "hello robot", "voice": "v2/en_speaker_1", "get_bytes": cls is not RoboMLHTTPClient}


@pytest.mark.parametrize("cls", CLIENTS)
def test_transcription_audio_goes_as_pcm16(cls: type[ModelClient], server: RoboMLTestServer, make: Factory) -> None:
    client = ready(make(cls, Whisper(name="ears")))
    audio = np.linspace(-0.5, 0.5, 1600, dtype=np.float32)
    assert client.inference({"query": audio, "language": "en", "vad_filter": True})["output"] == "heard 1600 samples"
    assert client.inference({"query": np.zeros(800, np.int16).tobytes()})["output"] == "heard 800 samples"
    words = client.inference({"query": audio, "word_timestamps": True})["output"]
    assert [w[2] for w in words] == ["heard", "1600"]
    first = server.calls_of("inference", TRANSPORT[cls])[0].payload
    pcm = base64.b64decode(first["query"]) if cls is RoboMLHTTPClient else first["query"]
    expected = (np.clip(audio, -1, 1) * 32767).astype("<i2")
    assert np.array_equal(np.frombuffer(pcm, "<i2"), expected)
    assert first["language"] == "en" and first["vad_filter"] is True


# -- streaming ---------------------------------------------------------------------------------


@pytest.mark.parametrize("cls", CLIENTS)
def test_stream_gives_a_chunk_stream(cls: type[ModelClient], server: RoboMLTestServer, make: Factory) -> None:
    client = ready(make(cls))
    stream = client.inference(chat("tell me a long story", stream=True))["output"]
    assert isinstance(stream, ChunkStream)
    chunks = list(stream)
    assert "".join(chunks) == "echo: tell me a long story"
    if cls is RoboMLRESPClient:
        # RoboML's RESP server cannot stream: the whole answer, asked for without streaming.
        assert len(chunks) == 1 and server.calls_of("inference", "resp")[-1].payload["stream"] is False
    else:
        assert len(chunks) == 6 and server.calls_of("inference")[-1].payload["stream"] is True


def test_ws_streams_back_to_back_do_not_mix(server: RoboMLTestServer, make: Factory) -> None:
    client = ready(make(RoboMLWSClient))
    for text in ("first question here", "second one", "third and last question"):
        assert list(client.inference(chat(text, stream=True))["output"])[-1] == text.split()[-1]
    assert client.inference(chat("plain"))["output"] == "echo: plain"
    assert server.ws_connections == 1  # one connection, reused in order


def test_ws_stream_closed_early_does_not_leak_into_the_next_reply(server: RoboMLTestServer, make: Factory) -> None:
    client = ready(make(RoboMLWSClient))
    stream = client.inference(chat("one two three four five", stream=True))["output"]
    assert next(stream) == "echo: "
    stream.close()  # the rest of that reply is still on the wire: that connection is dropped
    assert client.inference(chat("next"))["output"] == "echo: next"
    assert server.ws_connections == 2


def test_ws_concurrent_requests_get_their_own_replies(server: RoboMLTestServer, make: Factory) -> None:
    client = ready(make(RoboMLWSClient))
    results: dict[str, list[str]] = {}
    errors: list[BaseException] = []

    def ask(tag: str) -> None:
        try:
            for i in range(5):
                results.setdefault(tag, []).append(client.inference(chat(f"{tag}-{i}"))["output"])
        except BaseException as exc:
            errors.append(exc)

    threads = [threading.Thread(target=ask, args=(tag,)) for tag in ("a", "b", "c")]
    for t in threads:
        t.start()
    for t in threads:
        t.join(10)
    assert errors == []
    assert results == {tag: [f"echo: {tag}-{i}" for i in range(5)] for tag in ("a", "b", "c")}


def test_ws_reply_split_over_frames_is_reassembled(server: RoboMLTestServer, make: Factory) -> None:
    client = ready(make(RoboMLWSClient, TransformersTTS(name="voice")))
    text = "a" * 60_000  # the double's WAV: 20 bytes per character, so about 1.2 MB in two frames
    audio = client.inference({"query": text})["output"]
    assert len(audio) == 44 + 20 * len(text) and audio[:4] == b"RIFF"
    assert client.inference({"query": "short"})["output"][:4] == b"RIFF"  # the connection stays in step


def test_ws_pump_once_feeds_a_component_queue(server: RoboMLTestServer, make: Factory) -> None:
    client = ready(make(RoboMLWSClient))
    assert client.is_websocket
    requests: queue.Queue[dict[str, Any]] = queue.Queue()
    replies: queue.Queue[Any] = queue.Queue()
    assert client.pump_once(requests, replies) is False
    requests.put(chat("stream this please", stream=True))
    requests.put(chat("not streamed"))
    assert client.pump_once(requests, replies) and client.pump_once(requests, replies)
    items = [replies.get_nowait() for _ in range(replies.qsize())]
    assert items == ["echo: ", "stream ", "this ", "please", RESPONSE_ENDED, "echo: not streamed", RESPONSE_ENDED]
    server.set_fault("error")
    requests.put(chat("boom"))
    client.pump_once(requests, replies)
    failure = replies.get_nowait()
    assert isinstance(failure, InferenceError) and "model exploded" in str(failure)


def test_ws_serve_queues_runs_until_stopped(server: RoboMLTestServer, make: Factory) -> None:
    client = ready(make(RoboMLWSClient))
    requests: queue.Queue[dict[str, Any]] = queue.Queue()
    replies: queue.Queue[Any] = queue.Queue()
    stop = threading.Event()
    thread = threading.Thread(target=client.serve_queues, args=(requests, replies, stop))
    thread.start()
    try:
        requests.put(chat("hi there", stream=True))
        assert [replies.get(timeout=5) for _ in range(4)] == ["echo: ", "hi ", "there", RESPONSE_ENDED]
    finally:
        stop.set()
        thread.join(5)
    assert not thread.is_alive()


def test_ws_reconnects_after_the_server_drops_the_connection(server: RoboMLTestServer, make: Factory) -> None:
    client = ready(make(RoboMLWSClient))
    server.set_fault("drop_after_reply")
    assert client.inference(chat("one"))["output"] == "echo: one"
    assert wait_for(lambda: not client.connected, timeout=5)
    assert client.inference(chat("two"))["output"] == "echo: two"
    assert server.ws_connections == 2 and client.connected


# -- failures ----------------------------------------------------------------------------------


@pytest.mark.parametrize("cls", CLIENTS)
def test_refused_connection_is_client_connection_error(cls: type[ModelClient], make: Factory) -> None:
    client = make(cls, port=closed_port(), timeout=1)
    start = time.monotonic()
    with pytest.raises(ClientConnectionError):
        client.check_connection()
    with pytest.raises(ClientConnectionError):
        client.inference(chat("anyone?"))
    assert time.monotonic() - start < 5  # a few quick retries, no long waits


@pytest.mark.parametrize("cls", CLIENTS)
def test_never_answering_times_out_and_the_late_reply_does_not_mix(cls: type[ModelClient], server: RoboMLTestServer,
                                                                  make: Factory) -> None:
    client = ready(make(cls, timeout=0.5))
    server.set_fault("hang", seconds=1.0)
    start = time.monotonic()
    with pytest.raises(InferenceTimeoutError):
        client.inference(chat("slow"))
    elapsed = time.monotonic() - start
    assert 0.4 < elapsed < 1.5
    # The server answers "slow" late; the next request must get its own answer.
    assert client.inference(chat("fast"))["output"] == "echo: fast"
    time.sleep(0.7)
    assert client.inference(chat("again"))["output"] == "echo: again"


@pytest.mark.parametrize("cls", [HTTP, RESP])
def test_model_loading_times_out_after_init_timeout(cls: type[ModelClient], server: RoboMLTestServer,
                                                    make: Factory) -> None:
    client = make(cls, TransformersLLM(name="llm", init_timeout=1), timeout=0.2)
    server.set_fault("hang", op="initialize", seconds=3.0)
    start = time.monotonic()
    with pytest.raises(InferenceTimeoutError):
        client.initialize()
    assert 0.9 < time.monotonic() - start < 2.0  # the model's init_timeout, not inference_timeout


@pytest.mark.parametrize("cls", [HTTP, WS])
def test_server_dying_mid_stream_is_a_typed_error(cls: type[ModelClient], server: RoboMLTestServer,
                                                  make: Factory) -> None:
    client = ready(make(cls, timeout=2))
    server.set_fault("die", after=2)
    stream = client.inference(chat("a b c d e f", stream=True))["output"]
    got: list[str] = []
    start = time.monotonic()
    with pytest.raises(ClientConnectionError):
        got.extend(stream)
    assert got == ["echo: ", "a "] and time.monotonic() - start < 1.5
    assert stream.closed
    assert client.inference(chat("after"))["output"] == "echo: after"


@pytest.mark.parametrize("cls", CLIENTS)
def test_server_dying_before_replying_is_a_connection_error(cls: type[ModelClient], server: RoboMLTestServer,
                                                            make: Factory) -> None:
    client = ready(make(cls, timeout=2))
    server.set_fault("die")
    with pytest.raises(ClientConnectionError):
        client.inference(chat("hello"))
    assert client.inference(chat("again"))["output"] == "echo: again"


@pytest.mark.parametrize("cls", CLIENTS)
def test_model_errors_carry_the_server_message(cls: type[ModelClient], server: RoboMLTestServer,
                                               make: Factory) -> None:
    client = ready(make(cls))
    server.set_fault("error", message="CUDA out of memory")
    with pytest.raises(InferenceError if cls is not RoboMLHTTPClient else HTTPStatusError,
                       match="CUDA out of memory") as info:
        client.inference(chat("hello"))
    if cls is RoboMLHTTPClient:
        assert info.value.status == 500  # type: ignore[attr-defined]
    elif cls is RoboMLRESPClient:
        assert "UNEXPECTED_ERROR" in str(info.value)
    assert client.inference(chat("again"))["output"] == "echo: again"


@pytest.mark.parametrize("cls", CLIENTS)
def test_invalid_input_is_reported_with_roboml_validation_errors(cls: type[ModelClient], server: RoboMLTestServer,
                                                                 make: Factory) -> None:
    client = ready(make(cls))
    with pytest.raises((HTTPStatusError, InferenceError), match="greater than 0") as info:
        client.inference(chat("hello", temperature=0))
    if cls is RoboMLHTTPClient:
        assert info.value.status == 400  # type: ignore[union-attr]
    elif cls is RoboMLWSClient:
        assert "1007" in str(info.value)
    else:
        assert "VALIDATION_ERROR" in str(info.value)


@pytest.mark.parametrize("cls", [WS, RESP])
def test_malformed_reply_is_a_protocol_error(cls: type[ModelClient], server: RoboMLTestServer, make: Factory) -> None:
    client = ready(make(cls, VisionModel(name="eyes")))
    server.set_fault("bad_frame")
    with pytest.raises(ProtocolError):
        client.inference({"images": [image()]})
    assert client.inference({"images": [image()]})["output"][0]["scores"] == [0.9]


def test_binary_frame_inside_a_token_stream_is_a_protocol_error(server: RoboMLTestServer, make: Factory) -> None:
    client = ready(make(RoboMLWSClient))
    server.set_fault("bad_frame")
    stream = client.inference(chat("one two", stream=True))["output"]
    with pytest.raises(ProtocolError):
        list(stream)
    assert client.inference(chat("three"))["output"] == "echo: three"


@pytest.mark.parametrize("cls", CLIENTS)
def test_inference_on_a_node_that_does_not_exist(cls: type[ModelClient], make: Factory) -> None:
    client = make(cls)
    with pytest.raises((HTTPStatusError, InferenceError)) as info:
        client.inference(chat("hello"))
    if cls is RoboMLRESPClient:
        assert "INVALID_COMMAND" in str(info.value)
    else:
        assert info.value.status == 404  # type: ignore[union-attr]


@pytest.mark.parametrize("cls", [HTTP, RESP])
def test_unknown_node_model_and_duplicate_nodes(cls: type[ModelClient], server: RoboMLTestServer,
                                                make: Factory, caplog: pytest.LogCaptureFixture) -> None:
    first = ready(make(cls))
    second = ready(make(cls))  # same node name: RoboML warns and keeps the loaded node
    assert "Name duplication" in caplog.text and second.node_status() == "READY"
    first.deinitialize()
    spec = make(cls, Whisper(name="ears")).serialize()
    spec["model"]["model_type"] = "Whisper"
    client = client_from_spec(spec)
    client.node_model = "FasterWhisper"  # type: ignore[attr-defined]  # as if RoboML had no such class
    try:
        with pytest.raises((HTTPStatusError, InferenceError), match=r"not a supported model type|FasterWhisper"):
            client.initialize()  # type: ignore[attr-defined]
    finally:
        client.close()  # type: ignore[attr-defined]


def test_redis_default_handshake_is_refused_by_roboml(server: RoboMLTestServer) -> None:
    # Why the RESP client pins protocol=2: redis-py 8 opens with HELLO 3, an invalid command to RoboML.
    redis = pytest.importorskip("redis")

    default = redis.Redis(port=server.resp_port, socket_timeout=2, retry=None)
    try:
        if int(redis.__version__.split(".")[0]) >= 8:
            with pytest.raises(redis.exceptions.ResponseError, match="INVALID_COMMAND"):
                default.ping()
    finally:
        default.close()
    pinned = redis.Redis(port=server.resp_port, socket_timeout=2, protocol=2)
    try:
        assert pinned.ping() is True
    finally:
        pinned.close()


def test_msgpack_numpy_format() -> None:
    array = np.arange(12, dtype=np.float32).reshape(3, 4)
    raw = packb({"a": array, "s": np.int16(7)})
    decoded = unpackb(raw)
    assert np.array_equal(decoded["a"], array) and decoded["a"].dtype == np.float32 and decoded["s"] == 7
    plain = msgpack.unpackb(raw)  # what RoboML's patched msgpack reads before its object hook
    assert plain["a"] == {b"nd": True, b"type": "<f4", b"kind": b"", b"shape": [3, 4], b"data": array.tobytes()}
    pickled = msgpack.packb({b"nd": True, b"type": "|O", b"kind": b"O", b"shape": [1], b"data": b"x"})
    with pytest.raises(ProtocolError):
        unpackb(pickled)  # never unpickle what a server sends
    with pytest.raises(ProtocolError):
        unpackb(b"\xc1")
