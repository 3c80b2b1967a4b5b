"""Whole-call deadlines against a real misbehaving server (tests/servers/faults.py).

``inference_timeout`` bounds the whole call, connect to last byte: a server that sends keep-alive
comments forever, or its answer one byte at a time, fails the call with InferenceTimeoutError
about ``inference_timeout`` seconds after it started. Streams also have a first-chunk and a
between-chunk timer. Wall-clock bounds are loose on purpose (the machines running this are noisy):
a timeout of 1 s must fire after 0.9 s and before 3 s.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest

from agents_core.clients import GenericHTTPClient, ModelClient, OllamaClient, client_from_spec
from agents_core.clients.payloads import ChunkStream
from agents_core.errors import (
    ClientConnectionError,
    ConfigError,
    InferenceTimeoutError,
    ModelClientError,
    ProtocolError,
)
from agents_core.models import GenericLLM, OllamaModel

from ..servers.faults import FaultServer

#: A timeout of TIMEOUT seconds must fire within [LOW, HIGH] seconds of the call's start.
TIMEOUT, LOW, HIGH = 1.0, 0.9, 3.0

Factory = Callable[..., ModelClient]


@pytest.fixture
def server() -> Iterator[FaultServer]:
    # Keep-alives and bytes every 0.25 s: each read succeeds well within any per-read timeout,
    # which is exactly what a per-read timeout cannot catch.
    with FaultServer(interval=0.25, stall_seconds=20.0) as srv:
        yield srv  # type: ignore[misc]


def generic(port: int, **kwargs: Any) -> GenericHTTPClient:
    return GenericHTTPClient(GenericLLM(name="m", checkpoint="m"), port=port, **kwargs)


def ollama(port: int, **kwargs: Any) -> OllamaClient:
    return OllamaClient(OllamaModel(name="m", checkpoint="m"), port=port, **kwargs)


@pytest.fixture(params=["generic", "ollama"])
def make(request: pytest.FixtureRequest) -> Iterator[Factory]:
    """Builds the client under test; its connections are closed after the test."""
    made: list[GenericHTTPClient | OllamaClient] = []

    def build(port: int, **kwargs: Any) -> ModelClient:
        client = generic(port, **kwargs) if request.param == "generic" else ollama(port, **kwargs)
        made.append(client)
        return client

    yield build
    for client in made:
        client.close()


def run(client: ModelClient, stream: bool) -> str:
    """One chat inference, the stream read to its end."""
    output = client.inference({"query": "hi", "stream": stream})["output"]
    if isinstance(output, ChunkStream):
        return "".join(output)
    assert isinstance(output, str)
    return output


def timed_failure(client: ModelClient, stream: bool) -> tuple[float, ModelClientError]:
    start = time.monotonic()
    with pytest.raises(ModelClientError) as info:
        run(client, stream)
    return time.monotonic() - start, info.value


# -- the whole-call deadline --------------------------------------------------------------------------


@pytest.mark.parametrize("stream", [False, True], ids=["whole", "stream"])
@pytest.mark.parametrize("mode", ["keepalive", "trickle", "headers_then_stall", "stall_before_headers",
                                  "first_chunk_then_stall"])
def test_inference_timeout_bounds_the_whole_call(server: FaultServer, make: Factory, stream: bool, mode: str) -> None:
    # No chunk timers: only the whole-call deadline can stop these.
    client = make(server.port, inference_timeout=TIMEOUT, stream_chunk_timeout=None)
    server.mode = mode
    elapsed, error = timed_failure(client, stream)
    assert isinstance(error, InferenceTimeoutError), repr(error)
    assert "timed out" in str(error)
    assert LOW <= elapsed <= HIGH, f"{mode}: failed after {elapsed:.2f} s"
    # The connection the watchdog cut is not reused: the next call gets its answer.
    server.mode = "ok"
    assert run(client, stream) == server.reply


def test_slow_but_steady_stream_is_still_bounded_by_the_deadline(server: FaultServer, make: Factory) -> None:
    # Every chunk comes well within the between-chunk timer, the whole does not fit in 1 s.
    client = make(server.port, inference_timeout=TIMEOUT, stream_chunk_timeout=0.8)
    server.mode, server.interval = "slow_chunks", 0.3
    elapsed, error = timed_failure(client, stream=True)
    assert isinstance(error, InferenceTimeoutError)
    assert "inference_timeout" in str(error)
    assert LOW <= elapsed <= HIGH, elapsed


def test_keepalives_do_not_count_as_chunks(server: FaultServer, make: Factory) -> None:
    client = make(server.port, inference_timeout=10.0, stream_first_chunk_timeout=0.6)
    server.mode, server.interval = "keepalive", 0.1
    elapsed, error = timed_failure(client, stream=True)
    assert isinstance(error, InferenceTimeoutError)
    assert "stream_first_chunk_timeout" in str(error)
    assert 0.5 <= elapsed <= 2.5, elapsed


# -- chunk timers -------------------------------------------------------------------------------------


def test_first_chunk_timeout_fires(server: FaultServer, make: Factory) -> None:
    client = make(server.port, inference_timeout=10.0, stream_first_chunk_timeout=0.6)
    server.mode = "headers_then_stall"
    elapsed, error = timed_failure(client, stream=True)
    assert isinstance(error, InferenceTimeoutError)
    assert "no first chunk within stream_first_chunk_timeout 0.6 s" in str(error)
    assert 0.5 <= elapsed <= 2.5, elapsed


def test_between_chunk_timeout_fires_after_the_first_chunk(server: FaultServer, make: Factory) -> None:
    client = make(server.port, inference_timeout=10.0, stream_chunk_timeout=0.6)
    server.mode = "first_chunk_then_stall"
    stream = client.inference({"query": "hi", "stream": True})["output"]
    assert isinstance(stream, ChunkStream)
    assert next(stream) == "Hello "
    start = time.monotonic()
    with pytest.raises(InferenceTimeoutError, match=r"no chunk for stream_chunk_timeout 0\.6 s"):
        next(stream)
    assert 0.5 <= time.monotonic() - start <= 2.5
    assert stream.closed


def test_chunk_timer_runs_only_while_the_consumer_waits(server: FaultServer, make: Factory) -> None:
    # A consumer slower than the chunk timer does not make the server look stalled.
    client = make(server.port, inference_timeout=10.0, stream_chunk_timeout=0.3)
    server.mode = "ok"
    stream = client.inference({"query": "hi", "stream": True})["output"]
    assert isinstance(stream, ChunkStream)
    pieces = []
    for piece in stream:
        pieces.append(piece)
        time.sleep(0.4)
    assert "".join(pieces) == server.reply


def test_chunks_within_their_timers_pass(server: FaultServer, make: Factory) -> None:
    client = make(server.port, inference_timeout=10.0, stream_first_chunk_timeout=2.0, stream_chunk_timeout=1.0)
    server.mode, server.interval = "slow_chunks", 0.2
    assert run(client, stream=True) == server.reply
    assert run(client, stream=False) == server.reply


# -- other faults are typed and quick -----------------------------------------------------------------


@pytest.mark.parametrize("stream", [False, True], ids=["whole", "stream"])
def test_malformed_answer_is_a_protocol_error(server: FaultServer, make: Factory, stream: bool) -> None:
    server.mode = "malformed_json"
    elapsed, error = timed_failure(make(server.port, inference_timeout=5.0), stream)
    assert isinstance(error, ProtocolError), repr(error)
    assert elapsed < 2.0


@pytest.mark.parametrize("stream", [False, True], ids=["whole", "stream"])
def test_connection_reset_midway_is_a_connection_error(server: FaultServer, make: Factory, stream: bool) -> None:
    server.mode = "reset_midway"
    elapsed, error = timed_failure(make(server.port, inference_timeout=5.0), stream)
    assert isinstance(error, ClientConnectionError), repr(error)
    assert elapsed < 2.0


# -- the settings -------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["inference_timeout", "stream_first_chunk_timeout", "stream_chunk_timeout"])
@pytest.mark.parametrize("value", [0, -1.0, math.nan, math.inf, True, "5"])
def test_timeouts_are_validated(name: str, value: Any) -> None:
    with pytest.raises(ConfigError, match=name):
        generic(8000, **{name: value})


def test_timeouts_have_defaults_and_survive_serialize() -> None:
    client = generic(8000)
    defaults = (client.inference_timeout, client.stream_first_chunk_timeout, client.stream_chunk_timeout)
    assert defaults == (30, None, 10.0)
    tuned = ollama(8000, inference_timeout=120, stream_first_chunk_timeout=45, stream_chunk_timeout=None)
    rebuilt = client_from_spec(tuned.serialize())
    assert rebuilt == tuned
    assert (rebuilt.stream_first_chunk_timeout, rebuilt.stream_chunk_timeout) == (45.0, None)
    with pytest.raises(ConfigError, match="inference_timeout"):
        generic(8000, inference_timeout=None)
