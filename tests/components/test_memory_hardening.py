"""Memory against hostile values, crashes, a second writer, another embedder, damaged and foreign files (issue 36).

Each test names the attack it repeats. The Memory runs on the real emem engine; the crash, lock and
Zenoh tests run it in a child process (``memory_recipe.py``) stopped by PID, SIGKILL included.
"""

from __future__ import annotations

import contextlib
import hashlib
import logging
import math
import os
import signal
import sqlite3
import time
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from agents_core import Launcher, MemoryTransport, Topic
from agents_core.components import MemLayer, Memory
from agents_core.components.memory.engine import Observation
from agents_core.config import MemoryConfig
from agents_core.errors import ComponentError, RemoteError
from agents_core.messages import Header, OdometryMsg, PoseMsg, StreamingStringMsg
from agents_core.status import HealthStatus
from agents_core.testing.recipes import RecipeProcess, RecipeTransport, recipe_environment

from ..conftest import wait_for
from .memory_recipe import HEARD, ODOM, WORDS, WordEmbedder, build, note

pytest.importorskip("emem", reason="the memory extra is not installed (pip install 'agents-core[memory]')")

REPO = Path(__file__).resolve().parents[2]


@contextlib.contextmanager
def running(m: Memory) -> Iterator[Any]:
    transport = MemoryTransport()
    launcher = Launcher(transport)
    launcher.add_pkg(components=[m])
    try:
        with launcher:
            yield lambda topic, value: transport.create_publisher(topic).publish(value)
    finally:
        transport.close()


@contextlib.contextmanager
def child(db: Path, tmp_path: Path, *args: str, name: str = "recipe",
          environment: Mapping[str, str] | None = None) -> Iterator[RecipeProcess]:
    process = RecipeProcess("tests.components.memory_recipe", ["--db", str(db), *args], tmp_path / f"{name}.log",
                            cwd=REPO, env=recipe_environment(**(environment or {})))
    try:
        process.wait_ready(60)
        yield process
    finally:
        process.stop()


def found_notes(m: Memory, n: int, writer: str = "") -> int:
    """How many of notes 0..n-1 (of ``writer``) a search for each one's own word finds."""
    hits = 0
    for i in range(n):
        answer = m.semantic_search(query=f"{writer}note {WORDS[i % len(WORDS)]}", n_results=3)
        hits += note(i, writer) in answer
    return hits


def test_nan_or_infinite_z_and_a_lone_surrogate_are_refused_and_never_block_the_values_after_them(
        tmp_path: Path) -> None:
    """Attack 1: store_specific_memory with z = NaN / inf, and a String holding a lone surrogate on a layer."""
    m = build(str(tmp_path / "m.db"))
    with running(m) as send:
        send(ODOM, OdometryMsg(pose=PoseMsg(position=[3.0, 4.0, 0.0]), header=Header(frame_id="map")))
        assert wait_for(lambda: m._fix is not None)
        for z in (math.nan, math.inf):  # at the current position, with only z given (z was never checked)
            with pytest.raises(ComponentError, match="z must be a finite number"):
                m.store_specific_memory("poison", z=z)
        for bad in ({"z": math.nan}, {"z": math.inf}, {"x": math.nan}, {"y": -math.inf}, {"z": True}):
            place: dict[str, Any] = {"x": 1.0, "y": 2.0, **bad}
            with pytest.raises(ComponentError, match="must be a finite number"):
                m.store_specific_memory("poison", **place)
        with pytest.raises(ComponentError, match="lone surrogate"):
            m.store_specific_memory("bad \ud800 text", x=1.0, y=1.0)
        with pytest.raises(ComponentError, match="max_text_length"):
            m.store_specific_memory("long " * 10_000, x=1.0, y=1.0)
        send(HEARD, "a voice \udc80 with a lone surrogate")  # as the web UI passes it on
        assert wait_for(lambda: m.stats["refused"] == 10)
        for i in range(10):
            assert m.store_specific_memory(note(i), x=float(i), y=0.0) is True
        assert m.stats["stored"] == 10 and m.stats["pending"] == 0
        assert found_notes(m, 10) == 10
        assert m.health_status == HealthStatus.HEALTHY


def test_a_stream_that_never_ends_is_not_kept_whole_and_the_next_stream_is_stored(tmp_path: Path) -> None:
    """Attack 1 (sizes): a StreamingString whose chunks keep coming, never done."""
    said = Topic("said", "StreamingString")
    m = Memory(layers=[MemLayer(subscribes_to=said)], position=ODOM, embedding_client=WordEmbedder(),
               config=MemoryConfig(db_path=str(tmp_path / "m.db"), flush_interval=0.0),
               trigger=20.0)
    with running(m) as send:
        send(ODOM, OdometryMsg(pose=PoseMsg(position=[1.0, 1.0, 0.0]), header=Header(frame_id="map")))
        assert wait_for(lambda: m._fix is not None)
        for _ in range(2000):
            send(said, StreamingStringMsg(data="blah " * 20, stream=True, done=False))
        send(said, StreamingStringMsg(data="end", stream=True, done=True))
        assert wait_for(lambda: m.stats["stored"] + m.stats.get("refused", 0) == 1)
        assert "blah" not in m.temporal_query(last_n_minutes=5)  # 200,000 characters of it were never kept
        assert m.stats["refused"] == 1 and not m._partial
        for chunk, done in (("the kettle ", False), ("is boiling", True)):
            send(said, StreamingStringMsg(data=chunk, stream=True, done=done))
        assert wait_for(lambda: m.stats["stored"] == 1), m.stats
        assert "the kettle is boiling" in m.semantic_search(query="kettle")
        assert "blah" not in m.temporal_query(last_n_minutes=5)


def test_an_observation_the_store_refuses_is_dropped_and_counted_not_kept_at_the_head_of_the_buffer(
        tmp_path: Path) -> None:
    """Attack 1, past the checks: a value the database refuses (here NaN put straight into the buffer)."""
    m = build(str(tmp_path / "m.db"))
    with running(m):
        with m._lock:
            m._pending.append(Observation("poison", 0.0, 0.0, math.nan, time.time(), "agent_notes", False))
        for i in range(10):
            m.store_specific_memory(note(i), x=float(i), y=0.0)
        assert m.stats["refused"] == 1 and m.stats["stored"] == 10 and m.stats["pending"] == 0
        assert found_notes(m, 10) == 10
        # Nothing of the refused one is left in the engine: the rows and the index hold the ten notes.
        assert m._engine.store.count_observations() == 10 and len(m._engine.store._hnsw_id_map) == 10


def test_nan_z_from_a_peer_in_another_process_is_refused_and_the_next_notes_are_stored(
        recipe_transport: RecipeTransport, tmp_path: Path) -> None:
    """Attack 1 over the network: any Zenoh (or ROS 2) peer calls store_specific_memory with z = NaN."""
    transport = recipe_transport
    db = tmp_path / "peer.db"
    with child(db, tmp_path, *transport.recipe_args, environment=transport.environment) as process:
        peer = transport.open_asker()

        def call(method: str, **kwargs: Any) -> Any:
            return peer.request("memory/execute_method", {"method": method, "kwargs": kwargs},
                                timeout=15)["result"]

        assert wait_for(lambda: _answers(call), timeout=30), process.output()
        odom = peer.create_publisher(ODOM)

        def placed() -> bool:  # the robot's position reached the Memory: a note without x, y is stored
            odom.publish(OdometryMsg(pose=PoseMsg(position=[3.0, 4.0, 0.0]), header=Header(frame_id="map")))
            try:
                return bool(call("store_specific_memory", content="the robot is here"))
            except RemoteError:
                return False

        assert wait_for(placed, timeout=30), process.output()
        # At the current position, with only z given. ROS 2's JSON requests refuse NaN before it arrives.
        refused = "z must be a finite number" if transport.name == "zenoh" else "holds NaN or Infinity"
        for z in (float("nan"), float("inf")):
            with pytest.raises(RemoteError, match=refused):
                call("store_specific_memory", content="poison", z=z)
        with pytest.raises(RemoteError, match="'n_results' must be an integer"):
            call("semantic_search", query="note", n_results=10**18)
        for i in range(10):
            assert call("store_specific_memory", content=note(i), x=float(i), y=0.0) is True
        hits = sum(note(i) in call("semantic_search", query=f"note {WORDS[i]}", n_results=3) for i in range(10))
        assert hits == 10, process.output()


def _answers(call: Any) -> bool:
    try:
        call("temporal_query")
    except Exception:
        return False
    return True


def test_notes_committed_before_a_sigkill_are_found_by_meaning_after_the_restart(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """Attack 2: SIGKILL 0.5 s after 20 notes were committed (the index file was never saved)."""
    db = tmp_path / "crash.db"
    with child(db, tmp_path, "--transport", "memory", "--notes", "20") as process:
        assert "COMMITTED 20" in process.lines
        time.sleep(0.5)
        os.kill(process.pid, signal.SIGKILL)
        process.proc.wait(10)
    assert process.proc.returncode == -signal.SIGKILL
    m = build(str(db))
    with caplog.at_level(logging.INFO), running(m):
        assert m.health_status == HealthStatus.HEALTHY, m.health_message
        assert found_notes(m, 20) == 20
    assert "20 entries committed after the last index save added back from the rows" in caplog.text
    again = build(str(db))  # the index is whole now: nothing to add back
    with caplog.at_level(logging.INFO), running(again):
        assert found_notes(again, 20) == 20


def test_a_second_process_on_the_same_database_is_refused_with_the_holder_s_pid(tmp_path: Path) -> None:
    """Attack 3: two Memory processes on one db_path; after both, each writer's notes are found."""
    db = tmp_path / "shared.db"
    second = build(str(db))
    with child(db, tmp_path, "--transport", "memory", "--notes", "20", "--writer", "first") as process, \
            running(second):
        assert second.health_status == HealthStatus.COMPONENT_FAILURE
        assert f"in use by process {process.pid}" in second.health_message
        with pytest.raises(ComponentError, match=f"in use by process {process.pid}"):
            second.store_specific_memory(note(0, "second"), x=0.0, y=0.0)
        with pytest.raises(ComponentError, match="in use by process"):
            second.semantic_search(query="note")
        assert second.stats["stored"] == 0
    # The first process is gone (stopped cleanly): the lock is free, another writer's notes go in beside its own.
    m = build(str(db))
    with running(m):
        for i in range(20):
            m.store_specific_memory(note(i, "second"), x=float(i), y=1.0)
        assert found_notes(m, 20, "first") == 20 and found_notes(m, 20, "second") == 20


def _asker(transport: RecipeTransport, process: RecipeProcess) -> Any:
    """A peer's ``call(method, **kwargs)`` of the child's Memory, once it answers."""
    peer = transport.open_asker()

    def call(method: str, **kwargs: Any) -> Any:
        return peer.request("memory/execute_method", {"method": method, "kwargs": kwargs}, timeout=15)["result"]

    assert wait_for(lambda: _answers(call), timeout=30), process.output()
    return call


def test_notes_a_peer_committed_before_a_sigkill_are_found_by_meaning_after_the_restart(
        recipe_transport: RecipeTransport, tmp_path: Path) -> None:
    """Attack 2 over the network: a Zenoh (or ROS 2) peer stores 20 notes, the Memory is SIGKILLed 0.5 s later."""
    db = tmp_path / "peer-crash.db"
    with child(db, tmp_path, *recipe_transport.recipe_args, environment=recipe_transport.environment) as process:
        call = _asker(recipe_transport, process)
        for i in range(20):
            assert call("store_specific_memory", content=note(i, "peer"), x=float(i), y=0.0) is True
        time.sleep(0.5)
        os.kill(process.pid, signal.SIGKILL)
        process.proc.wait(10)
    assert process.proc.returncode == -signal.SIGKILL
    m = build(str(db))
    with running(m):
        assert m.health_status == HealthStatus.HEALTHY, m.health_message
        assert found_notes(m, 20, "peer") == 20


def test_a_second_memory_process_a_peer_writes_to_is_refused_with_the_holder_s_pid(
        recipe_transport: RecipeTransport, tmp_path: Path) -> None:
    """Attack 3 over the network: the second Memory process on one db_path is served on Zenoh (or ROS 2); its
    own notes and a peer's are refused naming the first process, and nothing of them is lost silently."""
    db = tmp_path / "shared.db"
    with child(db, tmp_path, "--transport", "memory", "--notes", "20", "--writer", "first", name="first") as first, \
            child(db, tmp_path, *recipe_transport.recipe_args, "--notes", "20", "--writer", "second",
                  name="second", environment=recipe_transport.environment) as second:
        assert "COMMITTED 20" in first.lines
        assert any(line.startswith("REFUSED") and f"in use by process {first.pid}" in line for line in second.lines), \
            second.lines
        peer = recipe_transport.open_asker()
        answers: list[str] = []

        def store() -> bool:  # retried until the second process's service is reached
            try:
                peer.request("memory/execute_method", {"method": "store_specific_memory", "kwargs": {
                    "content": note(0, "peer"), "x": 0.0, "y": 0.0}}, timeout=15)
                answers.append("stored")
            except RemoteError as exc:
                answers.append(str(exc))
            except Exception:  # not reachable yet
                return False
            return True

        assert wait_for(store, timeout=30), second.output()
        assert f"in use by process {first.pid}" in answers[-1], answers
    m = build(str(db))
    with running(m):
        assert found_notes(m, 20, "first") == 20 and found_notes(m, 20, "second") == 0


def test_a_database_of_another_embedding_model_is_refused_or_embedded_again_never_answered_wrong(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """Attack 4: a 64-dimension database reopened with a 128- or 16-dimension embedder, or another model."""
    db = str(tmp_path / "model.db")
    first = build(db)
    with running(first):
        for i in range(30):
            first.store_specific_memory(note(i), x=float(i), y=0.0)
    for dim, checkpoint in ((128, "words"), (16, "words"), (64, "other-words")):
        other = build(db, dim=dim, checkpoint=checkpoint)
        with running(other):
            assert other.health_status == HealthStatus.COMPONENT_FAILURE
            assert "'words' (64 dimensions)" in other.health_message
            assert f"{checkpoint!r} ({dim} dimensions)" in other.health_message
            with pytest.raises(ComponentError, match="its answers would be wrong"):
                other.semantic_search(query="note apple")
    again = build(db, dim=128, on_embedding_change="reembed")
    with caplog.at_level(logging.INFO), running(again):
        assert again.health_status == HealthStatus.HEALTHY, again.health_message
        assert found_notes(again, 30) >= 27  # as good as a fresh 128-dimension database
    assert "every text is embedded again" in caplog.text and "30 text(s)" in caplog.text
    fresh = build(str(tmp_path / "fresh.db"), dim=128)
    with running(fresh):
        for i in range(30):
            fresh.store_specific_memory(note(i), x=float(i), y=0.0)
        assert found_notes(again, 30) == found_notes(fresh, 30)


@pytest.mark.parametrize("damage", ["garbage", "truncated", "empty"])
def test_a_damaged_index_file_is_set_aside_and_rebuilt_from_the_rows(
        tmp_path: Path, damage: str, caplog: pytest.LogCaptureFixture) -> None:
    """Item 11: a damaged index kept Memory down until a person deleted it."""
    db = tmp_path / "damaged.db"
    first = build(str(db))
    with running(first):
        for i in range(20):
            first.store_specific_memory(note(i), x=float(i), y=0.0)
    index = tmp_path / "damaged.hnsw.bin"
    data = index.read_bytes()
    index.write_bytes({"garbage": os.urandom(len(data)), "truncated": data[:len(data) // 2], "empty": b""}[damage])
    m = build(str(db))
    with caplog.at_level(logging.INFO), running(m):
        assert m.health_status == HealthStatus.HEALTHY, m.health_message
        assert found_notes(m, 20) == 20
    assert "damaged" in caplog.text and (tmp_path / "damaged.hnsw.bin.damaged").is_file()
    assert not list(tmp_path.glob("*.tmp"))  # saved atomically: no temporary file left


def _snapshot(folder: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in folder.iterdir() if p.is_file()}


def test_a_foreign_sqlite_file_and_non_regular_paths_are_refused_untouched(tmp_path: Path) -> None:
    """Item 11: a foreign SQLite file silently got six tables; /dev/null made SQLite create /dev/null-journal."""
    foreign = tmp_path / "accounts.db"
    conn = sqlite3.connect(foreign)
    conn.execute("CREATE TABLE accounts (name TEXT, balance REAL)")
    conn.execute("INSERT INTO accounts VALUES ('alice', 10.0)")
    conn.commit()
    conn.close()
    text = tmp_path / "notes.txt"
    text.write_text("not a database at all\n" * 10)
    folder = tmp_path / "a_folder.db"
    folder.mkdir()
    fifo = tmp_path / "pipe.db"
    os.mkfifo(fifo)
    before = _snapshot(tmp_path)
    journal_before = os.path.exists("/dev/null-journal")
    cases = [(foreign, "not a memory database"), (text, "not a SQLite database"), (folder, "not a regular file"),
             (fifo, "not a regular file"), (Path("/dev/null"), "not a regular file")]
    try:
        for path, why in cases:
            m = build(str(path))
            with running(m):
                assert m.health_status == HealthStatus.COMPONENT_FAILURE
                assert why in m.health_message and str(path) in m.health_message
                with pytest.raises(ComponentError, match=why):
                    m.store_specific_memory("a note", x=0.0, y=0.0)
        assert _snapshot(tmp_path) == before  # nothing written, nothing created beside them
        assert sorted(p.name for p in tmp_path.iterdir()) == sorted([*before, folder.name, fifo.name])
        assert os.path.exists("/dev/null-journal") == journal_before
        conn = sqlite3.connect(f"file:{foreign}?mode=ro", uri=True)
        assert [r[0] for r in conn.execute("SELECT name FROM sqlite_master")] == ["accounts"]
        conn.close()
    finally:
        if not journal_before and os.path.isfile("/dev/null-journal"):
            os.unlink("/dev/null-journal")  # main's SQLite created it


def test_a_database_of_an_earlier_version_is_adopted_and_its_vectors_kept_with_its_rows(tmp_path: Path) -> None:
    """An emem database without our mark (as earlier versions wrote it) opens, and its index survives a crash."""
    emem = pytest.importorskip("emem")
    db = tmp_path / "earlier.db"
    embedder = WordEmbedder()

    class Provider:
        dim = 64

        def embed(self, texts: list[str]) -> Any:
            return np.asarray(embedder.embed(texts), dtype=np.float32)

    config = emem.SpatioTemporalMemoryConfig(db_path=str(db), hnsw_path=str(tmp_path / "earlier.hnsw.bin"),
                                        embedding_dim=64, flush_batch_size=1)
    with emem.SpatioTemporalMemory(config=config, embedding_provider=Provider()) as earlier:
        for i in range(10):
            earlier.add(text=note(i), x=float(i), y=0.0)
    m = build(str(db))
    with running(m):
        assert m.health_status == HealthStatus.HEALTHY, m.health_message
        assert found_notes(m, 10) == 10
    (tmp_path / "earlier.hnsw.bin").unlink()  # the index lost: rebuilt from the vectors now kept as rows
    m = build(str(db))
    with running(m):
        assert found_notes(m, 10) == 10


HOSTILE: list[tuple[str, dict[str, Any], str]] = [
    ("spatial_query", {"x": math.nan, "y": 0.0}, "'x' must be a finite number"),
    ("spatial_query", {"x": 0.0, "y": 0.0, "z": math.inf}, "'z' must be a finite number"),
    ("spatial_query", {"x": 0.0, "y": 0.0, "radius": -1.0}, "'radius' must be > 0"),
    ("spatial_query", {"x": 1e300, "y": 0.0}, "'x' must be at most"),
    ("semantic_search", {"query": "x", "n_results": 10**18}, "'n_results' must be an integer from 1 to 1000"),
    ("semantic_search", {"query": "x", "n_results": -3}, "'n_results' must be an integer"),
    ("semantic_search", {"query": "x", "n_results": 0}, "'n_results' must be an integer"),
    ("semantic_search", {"query": "x" * 10_000_000}, "'query' must be at most 2000 characters"),
    ("semantic_search", {"query": "bad \ud800"}, "'query' must be valid Unicode"),
    ("semantic_search", {"query": "x", "time_after": "nan"}, "'time_after' must be a finite time"),
    ("semantic_search", {"query": "x", "time_after": math.inf}, "'time_after' must be a finite Unix timestamp"),
    ("semantic_search", {"query": "x", "time_after": "the day the moon fell"}, "semantic_search cannot answer"),
    ("semantic_search", {"query": "x", "near_x": math.nan, "near_y": 0.0}, "'near_x' must be a finite number"),
    ("semantic_search", {"query": ["not", "text"]}, "'query' must be a string"),
    ("temporal_query", {"last_n_minutes": -5.0}, "'last_n_minutes' must be > 0"),
    ("temporal_query", {"last_n_minutes": math.nan}, "'last_n_minutes' must be a finite number"),
    ("get_current_context", {"radius": math.inf}, "'radius' must be a finite number"),
    ("episode_summary", {"last_n": 10**30}, "'last_n' must be an integer"),
    ("recall", {"query": "x", "radius_multiplier": 1e30}, "'radius_multiplier' must be > 0"),
    ("locate", {"concept": "x", "n_results": True}, "'n_results' must be a integer"),
    ("body_status", {"layers": ["x"] * 1000}, "'layers' must have at most 100 items"),
    ("body_status", {"layers": [1, 2]}, "'layers' must be a array"),
    ("entity_query", {"last_seen_after": "-1e400s"}, "entity_query cannot answer"),
]


@pytest.mark.parametrize(("tool", "arguments", "message"), HOSTILE, ids=[f"{t}-{i}" for i, (t, _, _) in
                                                                         enumerate(HOSTILE)])
def test_retrieval_tools_answer_hostile_arguments_with_one_clear_error(
        tmp_path: Path, tool: str, arguments: dict[str, Any], message: str, memory_under_attack: Memory) -> None:
    """Item 11: NaN passed the checks, and hnswlib / Rtree / sqlite errors came out raw."""
    with pytest.raises(ComponentError) as raised:
        getattr(memory_under_attack, tool)(**arguments)
    assert type(raised.value) is ComponentError and message in str(raised.value), raised.value
    assert str(raised.value).startswith((tool, f"component 'memory': {tool}"))
    assert len(str(raised.value)) < 600
    assert memory_under_attack.health_status == HealthStatus.HEALTHY


def test_an_episode_name_with_a_lone_surrogate_or_of_a_megabyte_is_one_clear_error(
        memory_under_attack: Memory) -> None:
    """Item 11: the episode's name went to sqlite as it was (a raw UnicodeEncodeError)."""
    for name, why in (("patrol \ud800", "lone surrogate"), ("x" * 1_000_000, "at most")):
        with pytest.raises(ComponentError, match=f"start_episode: the name .*{why}"):
            memory_under_attack.start_episode(name)
    assert memory_under_attack.health_status == HealthStatus.HEALTHY


@pytest.fixture(scope="module")
def memory_under_attack(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Memory]:
    m = build(str(tmp_path_factory.mktemp("attack") / "m.db"))
    with running(m):
        for i in range(5):
            m.store_specific_memory(note(i), x=float(i), y=0.0)
        yield m
