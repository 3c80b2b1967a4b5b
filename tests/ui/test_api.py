"""The UI's API through Starlette's TestClient, on a real recipe (memory transport), good and bad input."""

from __future__ import annotations

import io
import json
import wave
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

pytest.importorskip("starlette", reason="the ui extra is not installed (pip install 'agents-core[ui]')")
pytest.importorskip("multipart", reason="python-multipart (the ui extra) is not installed")

from starlette.testclient import TestClient

from agents_core import Launcher, Topic
from agents_core.errors import ConfigError
from agents_core.testing.helpers import wait_for
from agents_core.ui import LocalRecipe, UISettings
from agents_core.ui.app import UIState, create_app

from .ui_parts import PICTURE, SHOUTS, WORDS

BASE = "http://127.0.0.1:5001"
TOKEN = "correct-horse-battery-staple"
CAMERA, SOUND, LEVEL = Topic("camera", "Image"), Topic("sound", "Audio"), Topic("level", "Float64")


def _client(launcher: Launcher, **settings: Any) -> TestClient:
    view = LocalRecipe(launcher.components)
    state = UIState(view, launcher.transport, [WORDS, CAMERA, SOUND, LEVEL], [SHOUTS, PICTURE, CAMERA, SOUND],
                    UISettings(**settings))
    return TestClient(create_app(state), base_url=BASE)


def _ws(client: TestClient, path: str) -> Any:
    # The test client's WebSocket requests name "testserver" as their host whatever the base URL.
    return client.websocket_connect(path, headers={"host": "127.0.0.1:5001"})


def _png(width: int = 8, height: int = 6) -> bytes:
    from PIL import Image  # noqa: PLC0415

    out = io.BytesIO()
    Image.fromarray(np.full((height, width, 3), 200, np.uint8)).save(out, format="PNG")
    return out.getvalue()


def _wav(samples: np.ndarray, rate: int = 16000, width: int = 2) -> bytes:
    out = io.BytesIO()
    with wave.open(out, "wb") as w:
        w.setnchannels(1)
        w.setsampwidth(width)
        w.setframerate(rate)
        w.writeframes(samples.tobytes())
    return out.getvalue()


def _next_frame(ws: Any, kind: str, limit: int = 20) -> dict[str, Any]:
    for _ in range(limit):  # bounded: status frames may come first
        frame = json.loads(ws.receive_text())
        if frame["kind"] == kind:
            return frame
    raise AssertionError(f"no {kind} frame in {limit} frames")


def test_health_and_interfaces_describe_the_recipe(running: Launcher) -> None:
    with _client(running) as client:
        health = client.get("/api/health").json()
        assert health["ok"] is True and health["transport"] == "memory" and health["components"] == 1
        doc = client.get("/api/interfaces").json()
    [component] = doc["components"]
    assert component["name"] == "shouter" and component["component_type"] == "Shouter"
    assert component["state"] == "active" and component["health"] == "HEALTHY"
    assert component["inputs"] == [{"name": "words", "msg_type": "String"}]
    assert {"name": "picture", "msg_type": "Image"} in component["outputs"]
    assert set(component["actions"]) == {"set_volume", "make_picture"}
    assert "How many exclamation marks" in json.dumps(component["actions"]["set_volume"])
    widgets = {i["name"]: i["widget"] for i in doc["inputs"]}
    assert widgets == {"words": "text", "camera": "image", "sound": "audio", "level": "number"}


def test_text_in_text_out_over_the_websocket(running: Launcher) -> None:
    with _client(running) as client, _ws(client, "/api/outputs?topics=shouts") as ws:
        reply = client.post("/api/inputs/words", json={"value": "hello robot"})
        assert reply.status_code == 200, reply.text
        frame = _next_frame(ws, "text")
    assert frame == {**frame, "topic": "shouts", "msg_type": "String", "text": "HELLO ROBOT!"}


def test_uploaded_image_and_wav_are_published_and_shown(running: Launcher) -> None:
    with _client(running) as client, _ws(client, "/api/outputs?topics=camera,sound") as ws:
        reply = client.post("/api/inputs/camera", files={"file": ("pic.png", _png(), "image/png")})
        assert reply.status_code == 200, reply.text
        image = _next_frame(ws, "image")
        assert (image["width"], image["height"], image["mime"]) == (8, 6, "image/jpeg")
        tone = (np.sin(np.arange(1600) / 5) * 8000).astype("<i2")
        reply = client.post("/api/inputs/sound", files={"file": ("a.wav", _wav(tone), "audio/wav")})
        assert reply.status_code == 200, reply.text
        audio = _next_frame(ws, "audio")
    assert audio["sample_rate"] == 16000 and audio["seconds"] == 0.1
    import base64  # noqa: PLC0415

    with wave.open(io.BytesIO(base64.b64decode(audio["data"]))) as w:
        assert np.array_equal(np.frombuffer(w.readframes(w.getnframes()), "<i2"), tone)


def test_numbers_are_checked_against_the_topic_type(running: Launcher) -> None:
    with _client(running) as client:
        assert client.post("/api/inputs/level", json={"value": 0.25}).status_code == 200
        wrong = client.post("/api/inputs/level", json={"value": "loud"})
        assert wrong.status_code == 422 and "Float64 expects a number" in wrong.json()["error"]
        assert "'level'" in wrong.json()["error"]


@pytest.mark.parametrize(("topic", "kwargs", "status", "words"), [
    ("words", {"json": {"value": 42}}, 422, "expects text"),
    ("words", {"json": {"text": "hi"}}, 422, "'value' field"),
    ("words", {"content": b"{not json", "headers": {"content-type": "application/json"}}, 400, "invalid JSON"),
    ("words", {"content": b"hi", "headers": {"content-type": "text/plain"}}, 415, "send JSON"),
    ("camera", {"json": {"value": "a picture"}}, 422, "uploaded file"),
    ("camera", {"files": {"file": ("x.png", b"GIF89a....", "image/png")}}, 422, "not a PNG or JPEG"),
    ("camera", {"files": {"file": ("x.png", b"\x89PNG\r\n\x1a\n broken", "image/png")}}, 422, "does not decode"),
    ("camera", {"files": {"other": ("x.png", b"data", "image/png")}}, 422, "no 'file' field"),
    ("sound", {"files": {"file": ("a.wav", b"RIFF0000WAVEjunk", "audio/wav")}}, 422, "not a PCM WAV"),
    ("sound", {"files": {"file": ("a.wav", _wav(np.zeros(10, np.uint8), width=1), "audio/wav")}}, 422, "8-bit"),
    ("nowhere", {"json": {"value": "x"}}, 404, "not an input"),
    ("shouts", {"json": {"value": "x"}}, 404, "not an input"),
])
def test_bad_inputs_get_a_4xx_naming_the_problem(running: Launcher, topic: str, kwargs: dict[str, Any],
                                                 status: int, words: str) -> None:
    with _client(running) as client:
        reply = client.post(f"/api/inputs/{topic}", **kwargs)
    assert reply.status_code == status, reply.text
    assert words in reply.json()["error"]


def test_a_200_mb_upload_is_refused_before_it_is_read(running: Launcher) -> None:
    with _client(running, max_upload_bytes=1024 * 1024) as client:
        declared = client.post("/api/inputs/camera", content=b"x",
                               headers={"content-type": "multipart/form-data; boundary=b",
                                        "content-length": str(200 * 1024 * 1024)})
        assert declared.status_code == 413 and "limit" in declared.json()["error"]

        def chunks() -> Iterator[bytes]:  # no Content-Length: read until the limit, then refused
            for _ in range(200):
                yield b"\0" * (1024 * 1024)

        streamed = client.post("/api/inputs/camera", content=chunks(),
                               headers={"content-type": "multipart/form-data; boundary=b"})
        assert streamed.status_code == 413


def test_transitions_change_the_state_and_bad_ones_are_refused(running: Launcher) -> None:
    [component] = running.components
    with _client(running) as client:
        off = client.post("/api/components/shouter/transition", json={"transition": "deactivate"})
        assert off.status_code == 200 and off.json()["state"] == "inactive"
        assert component.lifecycle_state.value == "inactive"
        again = client.post("/api/components/shouter/transition", json={"transition": "deactivate"})
        assert again.status_code == 409 and "did not deactivate" in again.json()["error"]
        on = client.post("/api/components/shouter/transition", json={"transition": "activate"})
        assert on.status_code == 200 and on.json()["state"] == "active"
        unknown = client.post("/api/components/nobody/transition", json={"transition": "activate"})
        assert unknown.status_code == 404 and "no component 'nobody'" in unknown.json()["error"]
        bad = client.post("/api/components/shouter/transition", json={"transition": "explode"})
        assert bad.status_code == 422 and "must be one of" in bad.json()["error"]


def test_only_component_actions_can_be_called(running: Launcher) -> None:
    [component] = running.components
    with _client(running) as client, _ws(client, "/api/outputs?topics=picture") as ws:
        reply = client.post("/api/components/shouter/actions/set_volume", json={"kwargs": {"volume": 3}})
        assert reply.status_code == 200 and reply.json()["result"] == 3 and component.volume == 3
        assert client.post("/api/components/shouter/actions/make_picture").json()["result"] is True
        picture = _next_frame(ws, "image")
        assert (picture["width"], picture["height"]) == (32, 24)
        for method in ("not_an_action", "_execution_step", "__init__", "deactivate"):
            refused = client.post(f"/api/components/shouter/actions/{method}", json={})
            assert refused.status_code == 404 and "is not a component action" in refused.json()["error"], method
        missing = client.post("/api/components/ghost/actions/make_picture")
        assert missing.status_code == 404
        wrong_args = client.post("/api/components/shouter/actions/set_volume", json={"kwargs": {"loud": 1}})
        assert wrong_args.status_code == 422 and "set_volume" in wrong_args.json()["error"]
        malformed = client.post("/api/components/shouter/actions/set_volume", json={"args": "3"})
        assert malformed.status_code == 422


def test_status_changes_reach_websocket_clients(running: Launcher) -> None:
    state = UIState(LocalRecipe(running.components), running.transport, [WORDS], [SHOUTS], UISettings())
    with TestClient(create_app(state), base_url=BASE) as client:
        # The status topic's backlog reaches a just-started hub on the transport's delivery thread.
        assert wait_for(lambda: (state.hub.latest_status("shouter") or {}).get("state") == "active", 10.0)
        with _ws(client, "/api/outputs?topics=shouts") as ws:
            first = _next_frame(ws, "status")  # the current status comes first
            assert (first["component"], first["state"]) == ("shouter", "active")
            client.post("/api/components/shouter/transition", json={"transition": "deactivate"})
            states = [_next_frame(ws, "status")["state"]]
            while states[-1] != "inactive" and len(states) < 5:  # bounded
                states.append(_next_frame(ws, "status")["state"])
    assert states[-1] == "inactive"


def test_a_status_older_than_the_one_shown_never_reaches_clients(running: Launcher) -> None:
    """A late value of the status topic's backlog (stamped before the newest seen) is not news: no client
    gets it, and a client that connects later gets the newest status first."""
    import time  # noqa: PLC0415

    from agents_core.messages import ComponentStatusMsg, Header  # noqa: PLC0415
    from agents_core.transport.core import status_topic  # noqa: PLC0415

    def status(state: str, message: str, stamp_ns: int) -> ComponentStatusMsg:
        return ComponentStatusMsg(component="shouter", lifecycle_state=state, health="HEALTHY", message=message,
                                  header=Header(stamp_ns=stamp_ns))

    publisher = running.transport.create_publisher(status_topic("shouter"))
    state = UIState(LocalRecipe(running.components), running.transport, [WORDS], [SHOUTS], UISettings())
    try:
        with TestClient(create_app(state), base_url=BASE) as client:
            assert wait_for(lambda: (state.hub.latest_status("shouter") or {}).get("state") == "active", 10.0)
            with _ws(client, "/api/outputs?topics=shouts") as ws:
                assert _next_frame(ws, "status")["state"] == "active"
                now = time.time_ns()
                publisher.publish(status("inactive", "stale", now - 10**9))  # older than the active one shown
                time.sleep(0.3)  # delivered and fanned out, if the hub took it for news
                assert state.hub.latest_status("shouter")["state"] == "active"
                publisher.publish(status("active", "newest", now))
                frame = _next_frame(ws, "status")
                assert (frame["state"], frame["message"]) == ("active", "newest")
                with _ws(client, "/api/outputs?topics=shouts") as late:
                    first = _next_frame(late, "status")
                assert (first["state"], first["message"]) == ("active", "newest")
    finally:
        publisher.close()


def test_unknown_websocket_topics_are_refused(running: Launcher) -> None:
    from starlette.websockets import WebSocketDisconnect  # noqa: PLC0415

    with (_client(running) as client, _ws(client, "/api/outputs?topics=secret") as ws,
          pytest.raises(WebSocketDisconnect) as closed):
        ws.receive_text()
    assert closed.value.code == 1008


def test_binding_off_loopback_needs_a_token_and_it_is_never_shown() -> None:
    with pytest.raises(ConfigError, match="give it a token"):
        UISettings(host="0.0.0.0")
    with pytest.raises(ConfigError, match="16 characters"):
        UISettings(host="0.0.0.0", token="short")
    settings = UISettings(host="0.0.0.0", token=TOKEN)
    assert TOKEN not in repr(settings)


def test_a_missing_or_wrong_token_is_refused_and_login_sets_a_cookie(running: Launcher) -> None:
    with _client(running, host="0.0.0.0", token=TOKEN) as client:
        assert client.get("/api/health").status_code == 401
        assert client.get("/api/health", headers={"Authorization": "Bearer nope"}).status_code == 401
        assert client.post("/api/inputs/words", json={"value": "x"}).status_code == 401
        assert client.get("/api/health", headers={"Authorization": f"Bearer {TOKEN}"}).status_code == 200
        assert client.post("/api/login", json={"token": "wrong"}).status_code == 401
        login = client.post("/api/login", json={"token": TOKEN})
        assert login.status_code == 200 and "httponly" in login.headers["set-cookie"].lower()
        assert client.get("/api/interfaces").status_code == 200  # the cookie now
        assert client.get("/").status_code == 200  # the page itself holds no secret
    with _client(running, host="0.0.0.0", token=TOKEN) as client:
        from starlette.websockets import WebSocketDisconnect  # noqa: PLC0415

        with pytest.raises(WebSocketDisconnect) as closed, _ws(client, "/api/outputs") as ws:
            ws.receive_text()
        assert closed.value.code == 1008


def test_other_origins_and_rebound_host_names_are_refused(running: Launcher) -> None:
    with _client(running) as client:
        evil = client.post("/api/inputs/words", json={"value": "x"}, headers={"Origin": "http://evil.example"})
        assert evil.status_code == 403 and "origin" in evil.json()["error"]
        same = client.post("/api/inputs/words", json={"value": "x"}, headers={"Origin": BASE})
        assert same.status_code == 200
        rebound = client.get("/api/health", headers={"Host": "evil.example:5001"})
        assert rebound.status_code == 403


def test_the_page_and_its_assets_are_served_from_the_package(running: Launcher) -> None:
    with _client(running) as client:
        page = client.get("/")
        assert page.status_code == 200 and "/static/app.js" in page.text
        for asset in ("app.js", "style.css"):
            assert client.get(f"/static/{asset}").status_code == 200
    assert "http" not in page.text.replace("http-equiv", ""), "the page must load nothing from the internet"
