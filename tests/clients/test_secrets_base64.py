"""A secret echoed base64-encoded is masked like the raw one: HTTP Basic credentials, bare base64 text.

A server or proxy that quotes ``Authorization: Basic base64(user:key)`` (or the key's base64 in
any other text) used to pass through the scrubbing: the raw key never appears, its encoding does,
and base64 decodes in one line.
"""

from __future__ import annotations

import base64
import logging
import traceback
from collections.abc import Iterator

import pytest

from agents_core.clients import GenericHTTPClient, ModelClient, OllamaClient
from agents_core.clients.client_base import SECRET_MASK, scrub_exception, scrub_text
from agents_core.errors import HTTPStatusError, InferenceError
from agents_core.models import GenericLLM, OllamaModel

from ..servers.faults import FaultServer

KEY = "sk-test-7f3a9c1e5b2d4680"


def encodings_of(key: str) -> list[str]:
    """The key's base64 forms a peer may echo: after user names of each length mod 3, both alphabets."""
    forms = []
    for prefix in ("", "u:", "us:", "robot:", "robot-arm-7:"):
        for suffix in ("", "!", "?>"):
            data = f"{prefix}{key}{suffix}".encode()
            forms += [base64.b64encode(data).decode(), base64.urlsafe_b64encode(data).decode()]
    return forms


def assert_hidden(text: str) -> None:
    assert KEY not in text and KEY[3:] not in text
    for form in encodings_of(KEY):
        assert form not in text, form
    for start in range(0, len(text)):  # nothing left in the text decodes to a piece of the key
        chunk = text[start:start + 12]
        for candidate in (chunk, chunk + "=", chunk + "=="):
            try:
                decoded = base64.b64decode(candidate, altchars=b"-_", validate=True)
            except ValueError:
                continue
            assert KEY[3:12].encode() not in decoded


@pytest.mark.parametrize("form", encodings_of(KEY))
def test_every_base64_form_of_the_key_is_masked(form: str) -> None:
    for text in (f"Authorization: Basic {form}", f'{{"token": "{form}"}}', f"got {form}, expected another"):
        clean = scrub_text(text, [KEY])
        assert SECRET_MASK in clean and form not in clean, (text, clean)
        assert_hidden(clean)


def test_any_basic_credential_is_masked_even_of_an_unknown_secret() -> None:
    credential = base64.b64encode(b"admin:hunter2").decode()
    assert scrub_text(f"Proxy-Authorization: Basic {credential}", []) == "Proxy-Authorization: Basic ***"
    assert scrub_text(f"authorization: basic {credential}", []) == "authorization: basic ***"


def test_ordinary_text_is_left_alone() -> None:
    for text in ("the Basic authentication failed", "basic idea", "Basic Zm9vYmFy (foobar, no colon)",
                 "id 0123456789abcdef0123456789abcdef ok", "model llama3.2:1b-instruct-q4"):
        assert scrub_text(text, [KEY]) == text


def test_a_chained_exception_quoting_the_base64_key_is_scrubbed() -> None:
    encoded = base64.b64encode(f"robot:{KEY}".encode()).decode()
    outer = InferenceError("failed")
    outer.__cause__ = ValueError(f"401: 'Authorization: Basic {encoded}'")
    scrub_exception(outer, [KEY])
    assert_hidden("".join(traceback.format_exception(outer)))


@pytest.fixture
def server() -> Iterator[FaultServer]:
    with FaultServer(mode="echo_auth_base64") as srv:
        yield srv  # type: ignore[misc]


@pytest.mark.parametrize("stream", [False, True], ids=["whole", "stream"])
def test_a_server_echoing_the_key_in_base64_is_scrubbed(server: FaultServer, stream: bool,
                                                        caplog: pytest.LogCaptureFixture) -> None:
    clients: list[ModelClient] = [
        GenericHTTPClient(GenericLLM(name="m", checkpoint="m"), port=server.port, api_key=KEY, inference_timeout=5),
        OllamaClient(OllamaModel(name="m", checkpoint="m"), port=server.port, api_key=KEY, inference_timeout=5)]
    for client in clients:
        with caplog.at_level(logging.DEBUG), pytest.raises(HTTPStatusError) as info:
            output = client.inference({"query": "hi", "stream": stream})["output"]
            "".join(output)
        message = str(info.value)
        assert "Basic ***" in message and "token ***" in message, message
        assert_hidden(message)
        assert_hidden("".join(traceback.format_exception(info.value)))
        client.logger.warning("server said: %s", message.replace(SECRET_MASK, base64.b64encode(KEY.encode()).decode()))
        client.close()
    assert_hidden(caplog.text)
