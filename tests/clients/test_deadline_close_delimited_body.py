"""A deadline that cuts a body delimited by the connection's close is a timeout, not a protocol error.

Without Content-Length or chunking (HTTP/1.0 style), the end of the body is the end of the
connection. When the watchdog shuts the socket down at ``inference_timeout``, the read ends as if
the body were complete; the truncated answer then failed to parse and the call was reported as
ProtocolError ("the answer is not JSON") although the server was only slow.
"""

from __future__ import annotations

import time
from collections.abc import Iterator

import pytest

from agents_core.clients import GenericHTTPClient, OllamaClient
from agents_core.clients.payloads import ChunkStream
from agents_core.errors import InferenceTimeoutError, ModelClientError
from agents_core.models import GenericLLM, OllamaModel

from ..servers.faults import FaultServer

TIMEOUT, LOW, HIGH = 1.0, 0.9, 3.0


@pytest.fixture
def server() -> Iterator[FaultServer]:
    with FaultServer(mode="trickle_until_close", interval=0.2, stall_seconds=20.0) as srv:
        yield srv  # type: ignore[misc]


@pytest.mark.parametrize("stream", [False, True], ids=["whole", "stream"])
@pytest.mark.parametrize("kind", ["generic", "ollama"])
def test_a_cut_trickled_body_is_an_inference_timeout(server: FaultServer, kind: str, stream: bool) -> None:
    client = (GenericHTTPClient(GenericLLM(name="m", checkpoint="m"), port=server.port, inference_timeout=TIMEOUT,
                                stream_chunk_timeout=None) if kind == "generic" else
              OllamaClient(OllamaModel(name="m", checkpoint="m"), port=server.port, inference_timeout=TIMEOUT,
                           stream_chunk_timeout=None))
    try:
        started = time.monotonic()
        with pytest.raises(ModelClientError) as caught:
            output = client.inference({"query": "hi", "stream": stream})["output"]
            if isinstance(output, ChunkStream):
                "".join(output)
        elapsed = time.monotonic() - started
        assert isinstance(caught.value, InferenceTimeoutError), repr(caught.value)
        assert "not finished within inference_timeout 1 s" in str(caught.value)
        assert LOW <= elapsed <= HIGH, elapsed
        # A complete close-delimited answer (the server fast enough) still reads as an answer.
        server.interval = 0.0
        output = client.inference({"query": "hi", "stream": stream})["output"]
        text = "".join(output) if isinstance(output, ChunkStream) else output
        assert text == server.reply
    finally:
        client.close()


def test_a_stream_whose_cut_ends_between_pieces_is_still_a_timeout() -> None:
    """The cut lands where the partial stream still parses: the stream must not end as if complete."""
    pieces = iter(["Hello ", "there"])

    class Fired:
        fired = "deadline"

        def before_chunk(self) -> None: ...
        def after_chunk(self) -> None: ...
        def close(self) -> None: ...

        def error(self) -> InferenceTimeoutError:
            return InferenceTimeoutError("chat timed out: not finished within inference_timeout 1 s")

    stream: ChunkStream[str] = ChunkStream(pieces, watch=Fired())  # type: ignore[arg-type]
    assert next(stream) == "Hello " and next(stream) == "there"
    with pytest.raises(InferenceTimeoutError, match="inference_timeout"):
        next(stream)
