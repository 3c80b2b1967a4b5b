"""Memory under a burst: every value of a trigger layer is kept, in order, at its own place, and written in batches.

Uses the real emem engine and the hashed bag-of-words embedder of ``test_memory.py``, slowed down so that
values pile up behind the component's worker while it writes (as behind a real embedding server).
"""

from __future__ import annotations

import contextlib
import sqlite3
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from agents_core import Topic
from agents_core.components import MemLayer, Memory
from agents_core.config import MemoryConfig

from ..conftest import wait_for
from .test_memory import ODOM, WordEmbedder, odom, running

pytest.importorskip("emem", reason="the memory extra is not installed (pip install 'agents-core[memory]')")

HEARD = Topic("heard", "String")


class SlowEmbedder(WordEmbedder):
    """Each request takes 30 ms (a server round trip), whatever its size; counts the texts per request."""

    def __init__(self) -> None:
        super().__init__()
        self.sizes: list[int] = []

    def _embed(self, texts: list[str]) -> list[list[float]]:
        time.sleep(0.03)
        self.sizes.append(len(texts))
        return super()._embed(texts)


def rows(db_path: Path) -> list[tuple[str, float]]:
    """(text, x) of the committed observations, in the order they were written (read by another connection)."""
    with contextlib.closing(sqlite3.connect(db_path)) as db:
        return [(t, x) for t, x in db.execute("SELECT text, x FROM observations ORDER BY rowid")]


def test_a_burst_on_a_trigger_layer_is_stored_whole_in_order_at_each_value_s_place_in_batches(
        tmp_path: Path) -> None:
    embedder = SlowEmbedder()
    db = tmp_path / "burst.db"
    m = Memory(layers=[MemLayer(subscribes_to=HEARD, temporal_change=True)], position=ODOM, embedding_client=embedder,
               config=MemoryConfig(db_path=str(db), flush_batch_size=5, flush_interval=60.0), trigger=HEARD)
    sent = [(f"value number {i}", float(i)) for i in range(40)]
    with running(m) as (_, send):
        for text, x in sent:  # no waiting: the worker is busy embedding while most of these arrive
            send(ODOM, odom(x, 0.0))
            send(HEARD, text)
        assert wait_for(lambda: m.stats["stored"] == 40, timeout=20), m.stats
        assert rows(db) == sent
        assert m.stats == {"stored": 40, "no_position": 0, "unchanged": 0, "dropped": 0, "unreadable": 0, "refused": 0,
                           "embed_errors": 0, "store_errors": 0, "pending": 0}
    written = embedder.sizes[1:]  # the first request is the dimension probe
    assert sum(written) == 40 and len(written) < 20, written  # batched: not one request per value
    assert all(size % 5 == 0 for size in written), written  # whole batches of flush_batch_size


def test_values_short_of_a_batch_wait_for_it_and_a_query_writes_them_first(tmp_path: Path) -> None:
    db = tmp_path / "short.db"
    m = Memory(layers=[MemLayer(subscribes_to=HEARD, temporal_change=True)], position=ODOM,
               embedding_client=WordEmbedder(), trigger=20.0,
               config=MemoryConfig(db_path=str(db), flush_batch_size=5, flush_interval=30.0))
    with running(m) as (_, send):
        send(ODOM, odom(1.0, 2.0))
        for i in range(7):
            send(HEARD, f"note {i}")
            assert wait_for(lambda i=i: m._last_stored.get("heard", ("",))[0] == f"note {i}")
            if i == 4:
                assert wait_for(lambda: len(rows(db)) == 5)
        assert wait_for(lambda: m.stats["pending"] == 2)
        assert len(rows(db)) == 5  # the sixth and seventh wait for their batch (or 30 s)
        assert "note 6" in m.semantic_search(query="note 6")
        assert [t for t, _ in rows(db)] == [f"note {i}" for i in range(7)]


def test_a_value_that_arrived_before_any_position_is_counted_even_if_one_arrives_before_the_step(
        tmp_path: Path) -> None:
    embedder = SlowEmbedder()
    m = Memory(layers=[MemLayer(subscribes_to=HEARD, temporal_change=True)], position=ODOM, embedding_client=embedder,
               config=MemoryConfig(db_path=str(tmp_path / "m.db"), position_timeout=0.3), trigger=HEARD)
    with running(m) as (_, send):
        send(HEARD, "where was I")
        send(ODOM, odom(0.0, 0.0))
        send(HEARD, "here")
        assert wait_for(lambda: m.stats["no_position"] == 1 and m.stats["stored"] + m.stats["pending"] >= 1)
        found: Any = m.semantic_search(query="where was I here")
        assert "here" in found and "where was I" not in found


class BlockingEmbedder(WordEmbedder):
    """Each request after the dimension probe takes ``delay`` s; ``busy`` is set while one runs."""

    def __init__(self, delay: float) -> None:
        super().__init__()
        self.delay = delay
        self.busy = threading.Event()

    def _embed(self, texts: list[str]) -> list[list[float]]:
        if self.calls:  # not the probe
            self.busy.set()
            time.sleep(self.delay)
            self.busy.clear()
        return super()._embed(texts)


def test_a_value_is_placed_where_the_robot_was_when_it_arrived_even_if_the_worker_was_busy_longer_than_the_timeout(
        tmp_path: Path) -> None:
    embedder = BlockingEmbedder(delay=1.0)
    db = tmp_path / "busy.db"
    m = Memory(layers=[MemLayer(subscribes_to=HEARD, temporal_change=True)], position=ODOM, embedding_client=embedder,
               config=MemoryConfig(db_path=str(db), position_timeout=0.4, flush_interval=0.0), trigger=10.0)
    with running(m) as (_, send):
        send(ODOM, odom(1.0, 0.0))
        send(HEARD, "first, heard at one")
        assert wait_for(embedder.busy.is_set)  # the worker embeds the first value for 1 s
        send(ODOM, odom(2.0, 0.0))
        send(HEARD, "second, heard at two")
        assert wait_for(lambda: m.stats["stored"] == 2, timeout=10), m.stats
    assert rows(db) == [("first, heard at one", 1.0), ("second, heard at two", 2.0)]
    assert m.stats["no_position"] == 0


def test_the_store_action_does_not_take_away_values_still_waiting_for_their_step(tmp_path: Path) -> None:
    db = tmp_path / "store.db"
    m = Memory(layers=[MemLayer(subscribes_to=HEARD, temporal_change=True)], position=ODOM,
               embedding_client=SlowEmbedder(), trigger=HEARD,
               config=MemoryConfig(db_path=str(db), flush_batch_size=1))
    with running(m) as (_, send):
        send(ODOM, odom(3.0, 0.0))
        for i in range(10):
            send(HEARD, f"value {i}")
        m.store()  # the newest value once more, now; the ten still go in as they arrived
        assert wait_for(lambda: m.stats["stored"] == 11, timeout=10), m.stats
    texts = [t for t, _ in rows(db)]
    assert sorted(texts) == sorted([f"value {i}" for i in range(10)] + ["value 9"])
    assert [t for t in texts if t != "value 9"] == [f"value {i}" for i in range(9)]
