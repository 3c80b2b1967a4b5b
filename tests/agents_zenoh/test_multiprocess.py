"""A recipe in one process, driven over Zenoh by a client that uses only ``zenoh`` + ``msgpack``.

The recipe (``tests/agents_zenoh/recipe.py``) runs on ``Launcher(transport="zenoh")`` in a subprocess
listening on an explicit loopback port; this process talks to it through
``tests/agents_zenoh/raw_client.py`` (no project import), with multicast scouting off. Every
subprocess is stopped by PID in a ``finally``; every wait is bounded.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("zenoh")
pytest.importorskip("msgpack")

import zenoh  # after the importorskip guards

from tests.agents_zenoh import raw_client as rc
from tests.conftest import free_tcp_port

pytestmark = pytest.mark.zenoh

REPO = Path(__file__).resolve().parents[2]
STARTUP_TIMEOUT = 60.0


class Recipe:
    """The recipe subprocess: its endpoint, namespace and log."""

    def __init__(self, log_dir: Path) -> None:
        port = free_tcp_port()
        self.endpoint = f"tcp/127.0.0.1:{port}"
        self.namespace = f"it_{os.getpid()}_{port}"
        self.log_path = log_dir / f"recipe_{port}.log"
        self._log = self.log_path.open("w")
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "tests.agents_zenoh.recipe", "--listen", self.endpoint,
             "--namespace", self.namespace],
            cwd=REPO, stdout=self._log, stderr=subprocess.STDOUT,
        )

    def log(self) -> str:
        return self.log_path.read_text()

    def stop(self) -> None:
        """SIGTERM by PID (a clean shutdown), SIGKILL by PID if it does not exit in time."""
        try:
            if self.proc.poll() is None:
                os.kill(self.proc.pid, signal.SIGTERM)
                try:
                    self.proc.wait(timeout=15)
                except subprocess.TimeoutExpired:
                    os.kill(self.proc.pid, signal.SIGKILL)
                    self.proc.wait(timeout=10)
        finally:
            self._log.close()


def _wait(predicate: Any, timeout: float, interval: float = 0.05) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(interval)
    return bool(predicate())


@contextlib.contextmanager
def running_recipe(log_dir: Path) -> Iterator[tuple[Recipe, zenoh.Session]]:
    """Start the recipe, connect a raw client to it, and wait until both components are active."""
    recipe = Recipe(log_dir)
    session = None
    try:
        session = rc.open_peer(recipe.endpoint)

        def both_active() -> bool:
            assert recipe.proc.poll() is None, f"the recipe exited early:\n{recipe.log()}"
            states = [rc.component_state(session, recipe.namespace, name, timeout=1.0) for name in ("relay", "vision")]
            return all(s is not None and s["lifecycle_state"] == "active" for s in states)

        assert _wait(both_active, STARTUP_TIMEOUT, 0.2), f"the recipe never became active:\n{recipe.log()}"
        yield recipe, session
    finally:
        if session is not None:
            session.close()
        recipe.stop()


@pytest.fixture(scope="module")
def graph(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Recipe, zenoh.Session]]:
    with running_recipe(tmp_path_factory.mktemp("zenoh_recipe")) as pair:
        yield pair


def _service(session: zenoh.Session, namespace: str, name: str, request: dict[str, Any]) -> Any:
    replies = rc.query(session, rc.key(namespace, name), request, timeout=10.0)
    assert replies, f"no reply from {name}"
    return replies[0]


def _input_statistics(session: zenoh.Session, namespace: str, component: str) -> dict[str, int]:
    ok, _, reply = _service(session, namespace, f"{component}/execute_method", {"method": "input_statistics"})
    assert ok, reply
    result: dict[str, int] = reply["result"]
    return result


def _image_doc(height: int, width: int, stamp_ns: int = 1_700_000_000_000_000_001) -> tuple[dict[str, Any], bytes]:
    pixels = bytes((x * 7 + y * 3 + c * 50) % 256 for y in range(height) for x in range(width) for c in range(3))
    doc = {"data": {"__ndarray__": pixels, "dtype": "|u1", "shape": [height, width, 3]},
           "encoding": "rgb8", "header": {"stamp_ns": stamp_ns, "frame_id": "cam0"}}
    return doc, pixels


def test_relay_round_trip_with_encoding_and_attachment(graph: tuple[Recipe, zenoh.Session]) -> None:
    recipe, session = graph
    out = rc.Collector(session, recipe.namespace, "relay_out")
    pub = rc.publisher(session, recipe.namespace, "relay_in", "String")
    assert rc.wait_matched(pub)
    for seq, text in enumerate(["hello", "robot"]):
        rc.put(pub, text, seq)
    assert out.wait_for(lambda s: {"HELLO", "ROBOT"} <= {x["value"] for x in s}), out.samples
    sample = next(x for x in out.samples if x["value"] == "ROBOT")
    assert sample["encoding"] == "application/msgpack;String"
    assert isinstance(sample["attachment"]["seq"], int)
    assert abs(sample["attachment"]["stamp_ns"] - time.time_ns()) < 60e9
    out.close()
    pub.undeclare()


def test_image_in_mean_and_detections_out(graph: tuple[Recipe, zenoh.Session]) -> None:
    recipe, session = graph
    means = rc.Collector(session, recipe.namespace, "image_mean")
    detections = rc.Collector(session, recipe.namespace, "detections")
    pub = rc.publisher(session, recipe.namespace, "camera", "Image")
    assert rc.wait_matched(pub)
    doc, pixels = _image_doc(48, 64)
    rc.put(pub, doc, 0)
    assert means.wait_for(bool) and detections.wait_for(bool), recipe.log()
    assert means.values()[0] == f"mean={sum(pixels) / len(pixels):.3f}"
    det = detections.samples[0]
    assert det["encoding"] == "application/msgpack;Detections"
    value = det["value"]
    assert value["boxes"] == [[0.0, 0.0, 64.0, 48.0]]
    assert value["scores"] == [1.0]
    # The attached image comes back through the trailing-bin path, byte for byte, header kept.
    assert value["image"]["data"] == {"dtype": "|u1", "shape": [48, 64, 3], "data": pixels}
    assert value["image"]["header"] == {"stamp_ns": 1_700_000_000_000_000_001, "frame_id": "cam0"}
    assert value["header"]["stamp_ns"] == 1_700_000_000_000_000_001
    for c in (means, detections):
        c.close()
    pub.undeclare()


def test_bad_payloads_are_counted_logged_once_and_skipped(graph: tuple[Recipe, zenoh.Session]) -> None:
    recipe, session = graph
    ns = recipe.namespace
    out = rc.Collector(session, ns, "relay_out")
    pub = rc.publisher(session, ns, "relay_in", "String")
    wrong_type = rc.publisher(session, ns, "relay_in", "Int64")
    assert rc.wait_matched(pub) and rc.wait_matched(wrong_type)
    before = _input_statistics(session, ns, "relay")["decode_errors"]
    pub.put(b"\xc1 not msgpack at all")  # 0xc1 is never valid msgpack
    rc.put(pub, 42, 1)  # valid msgpack, but an int is not a String
    rc.put(wrong_type, "text", 2)  # the right bytes under another type's schema
    rc.put(pub, "still serving", 3)
    assert out.wait_for(lambda s: any(x["value"] == "STILL SERVING" for x in s)), recipe.log()
    assert _wait(lambda: _input_statistics(session, ns, "relay")["decode_errors"] == before + 3, 10.0)
    warnings = [line for line in recipe.log().splitlines()
                if line.startswith("WARNING") and "'relay_in'" in line and "does not decode" in line]
    assert len(warnings) == 1, recipe.log()
    assert "cannot decode the sample as String" in warnings[0]

    # A corrupt image (its bin is too short for its shape) on the vision input: same story.
    means = rc.Collector(session, ns, "image_mean")
    camera = rc.publisher(session, ns, "camera", "Image")
    assert rc.wait_matched(camera)
    vision_before = _input_statistics(session, ns, "vision")["decode_errors"]
    rc.put(camera, {"data": {"__ndarray__": b"abc", "dtype": "|u1", "shape": [2, 2, 3]}, "encoding": "rgb8"}, 0)
    doc, pixels = _image_doc(4, 5)
    rc.put(camera, doc, 1)
    assert means.wait_for(lambda s: any(x["value"] == f"mean={sum(pixels) / len(pixels):.3f}" for x in s))
    assert _wait(lambda: _input_statistics(session, ns, "vision")["decode_errors"] == vision_before + 1, 10.0)
    for c in (out, means):
        c.close()
    for p in (pub, wrong_type, camera):
        p.undeclare()


def test_lifecycle_and_services_from_a_plain_client(graph: tuple[Recipe, zenoh.Session]) -> None:
    recipe, session = graph
    ns = recipe.namespace
    status = rc.Collector(session, ns, "relay/status")
    assert status.wait_for(lambda s: any(x["value"]["lifecycle_state"] == "active" for x in s)), status.samples
    assert status.samples[0]["encoding"] == "application/msgpack;ComponentStatus"

    # The state key answers JSON too, for tools that do not speak msgpack.
    json_replies = [r.ok.payload.to_bytes() for r in session.get(rc.key(ns, "@agents/state/relay?format=json"),
                                                                 timeout=5.0) if r.ok is not None]
    assert json.loads(json_replies[0])["lifecycle_state"] == "active"

    transition = rc.key(ns, "@agents/transition/relay")
    assert rc.query(session, transition, {"transition": "deactivate"}) == [(True, "application/msgpack", {"ok": True})]
    assert rc.component_state(session, ns, "relay")["lifecycle_state"] == "inactive"
    assert rc.query(session, transition, {"transition": "deactivate"})[0][2] == {"ok": False}
    assert rc.query(session, transition, {"transition": "activate"})[0][2] == {"ok": True}
    assert rc.component_state(session, ns, "relay")["lifecycle_state"] == "active"

    ok, encoding, error = _service(session, ns, "relay/execute_method", {"method": "no_such_action"})
    assert not ok
    assert encoding == "application/msgpack;error"
    assert "no_such_action" in error["error"]

    out = rc.Collector(session, ns, "relay_out")
    pub = rc.publisher(session, ns, "relay_in", "String")
    assert rc.wait_matched(pub)
    rc.put(pub, "back again", 0)
    assert out.wait_for(lambda s: any(x["value"] == "BACK AGAIN" for x in s))
    for c in (status, out):
        c.close()
    pub.undeclare()


def test_documented_example_runs_with_zenoh_and_msgpack_only(graph: tuple[Recipe, zenoh.Session]) -> None:
    recipe, _ = graph
    done = subprocess.run(
        [sys.executable, str(REPO / "tests" / "agents_zenoh" / "raw_client.py"), "--connect", recipe.endpoint,
         "--namespace", recipe.namespace],
        cwd=REPO, capture_output=True, text=True, timeout=60, check=False,
    )
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert result == {"reply": "HELLO FROM ZENOH", "project_modules": []}


def test_documented_code_is_the_tested_code() -> None:
    doc = (REPO / "docs" / "zenoh-wire-format.md").read_text()
    source = (REPO / "tests" / "agents_zenoh" / "raw_client.py").read_text()
    blocks = re.findall(r"# --- doc:(\w+) ---\n(.*?)# --- doc:end ---", source, flags=re.S)
    assert {name for name, _ in blocks} == {"example", "unpack_payload"}
    for name, code in blocks:
        assert code.strip() in doc, f"docs/zenoh-wire-format.md does not quote raw_client.py's {name!r} block"


def test_killed_recipe_disappears_from_liveliness(tmp_path: Path) -> None:
    with running_recipe(tmp_path) as (recipe, session):
        ns = recipe.namespace
        gone: list[str] = []
        listener = session.liveliness().declare_subscriber(
            rc.key(ns, "@agents/components/**"),
            lambda s: gone.append(str(s.key_expr)) if s.kind == zenoh.SampleKind.DELETE else None,
        )
        assert rc.alive_components(session, ns) == {"relay", "vision"}
        os.kill(recipe.proc.pid, signal.SIGKILL)
        recipe.proc.wait(timeout=10)
        killed_at = time.monotonic()
        assert _wait(lambda: len(gone) >= 2, 10.0), gone
        elapsed = time.monotonic() - killed_at
        assert sorted(k.rsplit("/", 1)[-1] for k in gone) == ["relay", "vision"]
        assert rc.alive_components(session, ns) == set()
        assert rc.component_state(session, ns, "relay", timeout=1.0) is None
        assert elapsed < 10.0
        listener.undeclare()


def test_raw_client_imports_no_project_module() -> None:
    source = (REPO / "tests" / "agents_zenoh" / "raw_client.py").read_text()
    imports = re.findall(r"^\s*(?:import|from)\s+([\w.]+)", source, flags=re.M)
    assert not [m for m in imports if m.split(".")[0] in ("agents_core", "agents_zenoh", "tests")]
