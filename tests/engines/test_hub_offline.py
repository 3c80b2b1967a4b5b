"""An unreachable model hub is noticed once, with one short request, and a hub lookup then fails at once.

Before, each lookup spent ~25 s in huggingface_hub's retries (five "Retrying in 8s" warnings, each
printed twice) before the error. The hub here is a closed port on 127.0.0.1 (nothing leaves the host).
"""

from __future__ import annotations

import logging
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from agents_core.engines import model_files
from agents_core.errors import ConfigError

pytest.importorskip("huggingface_hub")


def _closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture
def unreachable_hub(monkeypatch: pytest.MonkeyPatch) -> str:
    """HF_ENDPOINT on a closed port, HF_HUB_OFFLINE unset, the per-process check not yet done."""
    endpoint = f"http://127.0.0.1:{_closed_port()}"
    monkeypatch.setenv("HF_ENDPOINT", endpoint)
    monkeypatch.delenv("HF_HUB_OFFLINE", raising=False)
    monkeypatch.setattr(model_files, "_hub_checked", False)
    monkeypatch.setattr(model_files, "_hub_offline_reason", None)
    return endpoint


def test_an_unreachable_hub_fails_a_lookup_at_once_with_one_message(unreachable_hub: str) -> None:
    start = time.monotonic()
    with pytest.raises(ConfigError) as caught:
        model_files.resolve_model_file("someone/not-cached-model", "*.onnx", "Vision component 'eyes': local model")
    elapsed = time.monotonic() - start
    text = str(caught.value)
    assert elapsed < model_files.HUB_CHECK_TIMEOUT_S + 2.0, elapsed
    assert text.startswith("Vision component 'eyes': local model: the model hub cannot be used")
    assert unreachable_hub in text and "'someone/not-cached-model'" in text and "local_model_path" in text
    assert os.environ["HF_HUB_OFFLINE"] == "1"  # huggingface_hub and child processes stay off the network


def test_the_hub_is_checked_once_per_process(unreachable_hub: str, monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[str] = []
    real = model_files._check_hub
    monkeypatch.setattr(model_files, "_check_hub", lambda endpoint, timeout: calls.append(endpoint) or
                        real(endpoint, timeout))
    for _ in range(3):
        with pytest.raises(ConfigError):
            model_files.resolve_model_file("someone/model", "*.gguf", "LLM")
    assert calls == [unreachable_hub]


def test_offline_mode_asked_for_sends_no_request(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    monkeypatch.setattr(model_files, "_hub_checked", False)
    monkeypatch.setattr(model_files, "_check_hub", lambda *a: pytest.fail("no request when offline is asked for"))
    assert model_files.hub_offline_reason() == "offline mode is on (HF_HUB_OFFLINE)"


def test_speech_model_lookup_fails_at_once_too(unreachable_hub: str) -> None:
    from agents_core.engines.local_stt import _model_dir  # noqa: PLC0415

    start = time.monotonic()
    with pytest.raises(ConfigError, match=r"the model hub cannot be used .* not in the local cache"):
        _model_dir("someone/whisper-not-cached", "SpeechToText 'ears': local model")
    assert time.monotonic() - start < model_files.HUB_CHECK_TIMEOUT_S + 2.0


def test_huggingface_hub_retry_lines_are_dropped(caplog: pytest.LogCaptureFixture, unreachable_hub: str) -> None:
    model_files.import_hub("x", "a/b", "local_model_path")
    http = logging.getLogger("huggingface_hub.utils._http")
    with caplog.at_level(logging.WARNING):
        http.warning("Retrying in 8s [Retry 1/5].")
        http.warning("'[Errno -2] Name or service not known' thrown while requesting GET https://x/api")
        http.warning("something else")
    assert [r.getMessage() for r in caplog.records] == ["something else"]


def test_a_cached_model_is_found_offline(tmp_path: Path) -> None:
    """In a fresh process (the cache location is read when huggingface_hub is imported)."""
    snapshot = tmp_path / "hub" / "models--someone--cached" / "snapshots" / ("a" * 40)
    (snapshot / "onnx").mkdir(parents=True)
    (snapshot / "onnx" / "model_int8.onnx").write_bytes(b"onnx")
    (snapshot / "README.md").write_text("x")
    refs = tmp_path / "hub" / "models--someone--cached" / "refs"
    refs.mkdir()
    (refs / "main").write_text("a" * 40)
    env = {**os.environ, "HF_HOME": str(tmp_path), "HF_ENDPOINT": f"http://127.0.0.1:{_closed_port()}"}
    env.pop("HF_HUB_OFFLINE", None)
    code = ("from agents_core.engines.model_files import resolve_model_file; "
            "print(resolve_model_file('someone/cached', 'onnx/*.onnx', 'x'))")
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=60,
                          check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == str(snapshot / "onnx" / "model_int8.onnx")
