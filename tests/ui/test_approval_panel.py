"""The approval panel's HTTP API on a real UI server (uvicorn, memory transport): list, approve, deny."""

from __future__ import annotations

import json
import time

import httpx
import pytest

pytest.importorskip("starlette", reason="the ui extra is not installed (pip install 'agents-core[ui]')")

from agents_core.guardrails import configure_audit_log
from agents_core.testing.helpers import wait_for

from .approval_parts import HeldCall, arm_with_ui


def _http() -> httpx.Client:
    # A connection per request: a kept-alive one idle for the server's 5 s can close as it is reused.
    return httpx.Client(timeout=10, limits=httpx.Limits(max_keepalive_connections=0))


def _pending(http: httpx.Client, url: str) -> list[dict]:
    reply = http.get(url + "api/approvals")
    assert reply.status_code == 200, reply.text
    return reply.json()["pending"]


def _held(launcher, http: httpx.Client, target: str) -> tuple[HeldCall, dict]:
    """Call ``arm.launch(target)`` and wait until the panel lists it; the call and its entry."""
    held = HeldCall(launcher, target)
    assert wait_for(lambda: bool(_pending(http, launcher.ui.url)), 5.0)
    [call] = _pending(http, launcher.ui.url)
    return held, call


def test_a_held_call_is_listed_then_approved_once(tmp_path):
    configure_audit_log(tmp_path / "audit.jsonl")
    try:
        with arm_with_ui() as (launcher, component), _http() as http:
            url = launcher.ui.url
            assert _pending(http, url) == []
            held, call = _held(launcher, http, "the moon")
            assert (call["component"], call["action"], call["caller"], call["holder"]) == ("arm", "launch", "cli",
                                                                                         "arm")
            assert call["arguments"] == {"target": "the moon"} and 0 < call["expires_in_s"] <= 5.0
            assert component.launches == []  # held: not run yet
            reply = http.post(url + f"api/approvals/{call['id']}", json={"approve": True})
            assert reply.status_code == 200 and reply.json()["by"] == "web UI (127.0.0.1)"
            held.join()
            assert held.error is None and held.result["result"] == "launched at the moon"
            assert component.launches == ["the moon"]
            again = http.post(url + f"api/approvals/{call['id']}", json={"approve": True})
            assert again.status_code == 404  # decided: a second yes runs nothing
            assert component.launches == ["the moon"] and _pending(http, url) == []
        records = [json.loads(line) for line in (tmp_path / "audit.jsonl").read_text().splitlines()]
        allowed = [r for r in records if r.get("action") == "launch" and r["decision"] == "allowed"]
        assert [r["approved_by"] for r in allowed] == ["web UI (127.0.0.1)"]
    finally:
        configure_audit_log(None)


def test_deny_refuses_and_bad_requests_are_answered_clearly():
    with arm_with_ui() as (launcher, component), _http() as http:
        url = launcher.ui.url
        held, call = _held(launcher, http, "mars")
        for body in ({"approve": "yes"}, {}, {"approve": 1}):
            bad = http.post(url + f"api/approvals/{call['id']}", json=body)
            assert bad.status_code == 422 and "'approve' must be true or false" in bad.json()["error"]
        assert http.post(url + "api/approvals/nosuchcall", json={"approve": True}).status_code == 404
        evil = http.post(url + f"api/approvals/{call['id']}", json={"approve": True},
                         headers={"origin": "http://evil.example"})
        assert evil.status_code == 403  # another page cannot approve
        start = time.monotonic()
        assert http.post(url + f"api/approvals/{call['id']}", json={"approve": False}).status_code == 200
        held.join()
        assert time.monotonic() - start < 3.0
        assert held.error is not None and "denied by web UI (127.0.0.1)" in held.error
        assert component.launches == []


def test_a_call_nobody_decides_leaves_the_list_when_it_times_out():
    with arm_with_ui() as (launcher, component), _http() as http:
        url = launcher.ui.url
        held, call = _held(launcher, http, "venus")
        held.join()  # the Arm's launch waits 5 s
        assert held.error is not None and "not approved within" in held.error
        assert _pending(http, url) == []
        assert http.post(url + f"api/approvals/{call['id']}", json={"approve": True}).status_code == 404
        assert component.launches == []
