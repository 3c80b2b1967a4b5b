"""A third-party client of a running agents graph that uses only ``zenoh`` and ``msgpack``.

It imports nothing from this project (no ``agents_core``, no ``agents_zenoh``): it follows
``docs/zenoh-wire-format.md`` alone, which is the point. The integration tests drive a recipe
process with it, and run it as a script (``python tests/agents_zenoh/raw_client.py --connect
tcp/127.0.0.1:PORT --namespace NS``), which runs the documented minimal example and checks
that no project module was imported.

The blocks between ``# --- doc:...`` markers are quoted verbatim in the wire-format document
(a test compares them), so the documented code is the tested code.
"""

from __future__ import annotations

import argparse
import json
import queue
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

import msgpack
import zenoh

MSGPACK = "application/msgpack"


def open_peer(connect: str) -> zenoh.Session:
    """A peer session that connects to ``connect`` only: no listening, no multicast scouting."""
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("listen/endpoints", "[]")
    conf.insert_json5("connect/endpoints", json.dumps([connect]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    return zenoh.open(conf)


def key(namespace: str, name: str) -> str:
    """``<namespace>/<name>`` (no leading ``/`` when the namespace is empty)."""
    return f"{namespace}/{name}" if namespace else name


# --- doc:unpack_payload ---
def unpack_payload(payload: bytes) -> Any:
    """Decode a payload: the msgpack document, then the msgpack bins that hold its arrays.

    Each ndarray map {"__ndarray__": i, "dtype": ..., "shape": ...} comes back with a "data"
    entry holding the bytes (i is the index of the bin after the document; nil is padding).
    """
    unpacker = msgpack.Unpacker(raw=False)
    unpacker.feed(payload)
    document = unpacker.unpack()
    bins = [obj for obj in unpacker if obj is not None]

    def resolve(obj: Any) -> Any:
        if isinstance(obj, dict):
            if "__ndarray__" in obj:
                ref = obj["__ndarray__"]
                data = bins[ref] if isinstance(ref, int) else ref
                return {"dtype": obj["dtype"], "shape": obj["shape"], "data": data}
            return {k: resolve(v) for k, v in obj.items()}
        if isinstance(obj, list):
            return [resolve(v) for v in obj]
        return obj

    return resolve(document)
# --- doc:end ---


def publisher(session: zenoh.Session, namespace: str, topic: str, type_name: str) -> zenoh.Publisher:
    """A publisher on a topic of ``type_name``, with the encoding subscribers check."""
    return session.declare_publisher(key(namespace, topic),
                                     encoding=zenoh.Encoding(MSGPACK).with_schema(type_name))


def wait_matched(pub: zenoh.Publisher, timeout: float = 10.0) -> bool:
    """Wait (bounded) until Zenoh has matched a subscriber for ``pub``."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if pub.matching_status.matching:  # an object with .matching in zenoh-python 1.x
            return True
        time.sleep(0.01)
    return False


def put(pub: zenoh.Publisher, document: Any, seq: int) -> None:
    """Publish one msgpack document with the attachment the graph's publishers send."""
    pub.put(msgpack.packb(document), attachment=msgpack.packb({"seq": seq, "stamp_ns": time.time_ns()}))


class Collector:
    """Subscribes to one topic and keeps every decoded sample (with its encoding and attachment)."""

    def __init__(self, session: zenoh.Session, namespace: str, topic: str) -> None:
        self.samples: list[dict[str, Any]] = []
        self._cond = threading.Condition()
        self._sub = session.declare_subscriber(key(namespace, topic), self._on_sample)

    def _on_sample(self, sample: zenoh.Sample) -> None:
        attachment = sample.attachment
        entry = {
            "value": unpack_payload(sample.payload.to_bytes()),
            "encoding": str(sample.encoding),
            "attachment": msgpack.unpackb(attachment.to_bytes()) if attachment is not None else None,
        }
        with self._cond:
            self.samples.append(entry)
            self._cond.notify_all()

    def wait_for(self, predicate: Callable[[list[dict[str, Any]]], bool], timeout: float = 10.0) -> bool:
        """Wait (bounded) until ``predicate(samples)`` holds."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while not predicate(self.samples):
                left = deadline - time.monotonic()
                if left <= 0:
                    return False
                self._cond.wait(left)
            return True

    def values(self) -> list[Any]:
        with self._cond:
            return [s["value"] for s in self.samples]

    def close(self) -> None:
        self._sub.undeclare()


def query(session: zenoh.Session, key_expr: str, request: dict[str, Any] | None = None,
          timeout: float = 5.0) -> list[tuple[bool, str, Any]]:
    """``get`` ``key_expr`` with a msgpack request; (ok, encoding, decoded payload) per reply."""
    options: dict[str, Any] = {"timeout": timeout}
    if request is not None:
        options.update(payload=msgpack.packb(request), encoding=MSGPACK)
    out = []
    for reply in session.get(key_expr, **options):
        if reply.ok is not None:
            out.append((True, str(reply.ok.encoding), unpack_payload(reply.ok.payload.to_bytes())))
        else:
            raw = reply.err.payload.to_bytes()
            encoding = str(reply.err.encoding)
            out.append((False, encoding, msgpack.unpackb(raw) if encoding.startswith(MSGPACK) else raw))
    return out


def component_state(session: zenoh.Session, namespace: str, name: str, timeout: float = 2.0) -> Any:
    """The component's ComponentStatus document, or None when nobody answers."""
    for ok, _, doc in query(session, key(namespace, f"@agents/state/{name}"), timeout=timeout):
        if ok:
            return doc
    return None


def alive_components(session: zenoh.Session, namespace: str, timeout: float = 2.0) -> set[str]:
    """Names of the components whose liveliness tokens are present."""
    prefix = key(namespace, "@agents/components/")
    names = set()
    for reply in session.liveliness().get(key(namespace, "@agents/components/**"), timeout=timeout):
        if reply.ok is not None:
            names.add(str(reply.ok.key_expr)[len(prefix):])
    return names


# --- doc:example ---
def example(connect: str, namespace: str) -> str:
    """Send a String into the relay's input topic and return what it publishes in reply."""
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("connect/endpoints", json.dumps([connect]))
    conf.insert_json5("listen/endpoints", "[]")  # Zenoh's default would listen on every interface
    conf.insert_json5("scouting/multicast/enabled", "false")
    prefix = f"{namespace}/" if namespace else ""
    replies: queue.SimpleQueue[Any] = queue.SimpleQueue()
    with zenoh.open(conf) as session:
        sub = session.declare_subscriber(prefix + "relay_out",
                                         lambda sample: replies.put(msgpack.unpackb(sample.payload.to_bytes())))
        pub = session.declare_publisher(prefix + "relay_in",
                                        encoding=zenoh.Encoding("application/msgpack").with_schema("String"))
        deadline = time.monotonic() + 10
        while not pub.matching_status.matching and time.monotonic() < deadline:
            time.sleep(0.01)  # a put before the subscriber is discovered would be dropped
        pub.put(msgpack.packb("hello from zenoh"),
                attachment=msgpack.packb({"seq": 0, "stamp_ns": time.time_ns()}))
        reply = replies.get(timeout=10)
        sub.undeclare()
        return str(reply)
# --- doc:end ---


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Run the documented minimal example against a recipe.")
    parser.add_argument("--connect", required=True)
    parser.add_argument("--namespace", default="")
    args = parser.parse_args(argv)
    reply = example(args.connect, args.namespace)
    project = sorted(m for m in sys.modules if m.split(".")[0] in ("agents_core", "agents_zenoh", "agents_ros2"))
    print(json.dumps({"reply": reply, "project_modules": project}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
