"""A goal client that uses only ``zenoh`` and ``msgpack``, following docs/zenoh-wire-format.md ("Goals").

Run as a script against a running action server; prints one JSON line with what it saw::

    python tests/agents_zenoh/raw_goal_client.py --connect tcp/127.0.0.1:PORT --action NAME

It sends a goal and collects its feedback and result, then a second goal that it cancels after
the first feedback, then a payload that is not msgpack. It imports no project module.
"""

from __future__ import annotations

import argparse
import json
import secrets
import sys
import threading
import time
import uuid
from typing import Any

import msgpack
import zenoh

MSGPACK = "application/msgpack"


def open_peer(connect: str) -> zenoh.Session:
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("listen/endpoints", "[]")
    conf.insert_json5("connect/endpoints", json.dumps([connect]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    return zenoh.open(conf)


def query(session: zenoh.Session, key: str, body: bytes, timeout: float = 5.0) -> tuple[bool, Any]:
    """(ok, decoded reply) of the first reply; (False, None) when nobody answered."""
    for reply in session.get(key, payload=body, encoding=MSGPACK, timeout=timeout):
        if reply.ok is not None:
            return True, msgpack.unpackb(reply.ok.payload.to_bytes())
        return False, msgpack.unpackb(reply.err.payload.to_bytes())
    return False, None


class Goal:
    """One goal: subscribe to its feedback and status first, then send it."""

    def __init__(self, session: zenoh.Session, base: str, goal: dict[str, Any]) -> None:
        self.session, self.base = session, base
        self.goal_id = uuid.uuid4().hex
        self.cancel_token = secrets.token_hex(16)  # only this client can cancel the goal
        self.feedback: list[dict[str, Any]] = []
        self.statuses: list[int] = []
        self.first_feedback = threading.Event()
        self.sub = session.declare_subscriber(f"{base}/@action/*/{self.goal_id}", self._on_sample)
        ok, self.answer = query(session, f"{base}/@action/goal",
                                msgpack.packb({"goal_id": self.goal_id, "goal": goal,
                                               "cancel_token": self.cancel_token}))
        assert ok, self.answer

    def _on_sample(self, sample: zenoh.Sample) -> None:
        doc = msgpack.unpackb(sample.payload.to_bytes())
        if "/@action/feedback/" in str(sample.key_expr):
            self.feedback.append(doc)
            self.first_feedback.set()
        else:
            self.statuses.append(doc["status"])

    def result(self, deadline_s: float = 10.0) -> dict[str, Any]:
        deadline = time.monotonic() + deadline_s
        while time.monotonic() < deadline:
            ok, doc = query(self.session, f"{self.base}/@action/result",
                            msgpack.packb({"goal_id": self.goal_id, "wait_s": 1.0}))
            assert ok and doc is not None, doc
            if not doc.get("pending"):
                return doc
        raise TimeoutError("no result")

    def cancel(self) -> Any:
        request = {"goal_id": self.goal_id, "cancel_token": self.cancel_token}
        return query(self.session, f"{self.base}/@action/cancel", msgpack.packb(request))[1]


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--connect", required=True)
    parser.add_argument("--action", required=True)
    args = parser.parse_args()
    session = open_peer(args.connect)
    try:
        time.sleep(0.3)  # the connection to the server is made asynchronously
        done = Goal(session, args.action, {"task": "reach", "max_steps": 3})
        done_result = done.result()
        time.sleep(0.2)
        long = Goal(session, args.action, {"task": "hold", "max_steps": 100000})
        long.first_feedback.wait(5.0)
        cancel_answer = long.cancel()
        long_result = long.result()
        ok, garbage = query(session, f"{args.action}/@action/goal", b"\xc1 not msgpack")
        print(json.dumps({
            "accepted": done.answer, "feedback": done.feedback, "statuses": done.statuses, "result": done_result,
            "cancel": cancel_answer, "cancel_result": long_result, "garbage_ok": ok, "garbage": garbage,
            "project_modules": sorted(m for m in sys.modules if m.startswith(("agents_core", "agents_zenoh"))),
        }))
    finally:
        session.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
