"""Memory suite: observations stored per second and ``semantic_search`` latency, the component against emem directly.

Both sides live in one process and are measured interleaved, round after round (the order alternates),
on the same texts, the same embedding client and the same settings (``MemoryConfig``'s defaults:
batches of ``flush_batch_size`` = 5):

- writes, framework: a running Memory component with one String layer that triggers it (each value is
  an observation, as a speech or captioning stream feeds it) and an Odometry position, fed as a robot
  feeds it: for each value a pose then the text, published at once on the memory transport, without
  waiting for the component. Timed from the first publish to the last observation committed to SQLite
  (``stats["stored"]``).
- writes, raw: ``emem.SpatioTemporalMemory.add`` with the embedding precomputed by the same client,
  five texts per embedding request, emem committing every fifth ``add`` (its own batching, with the same
  settings). Timed from the first embedding request to the last commit. After each timed write the rows
  are counted through another SQLite connection (both sides must have committed them all).
- search: ``semantic_search(query, n_results=5)`` on the two databases (the same observations), raw a
  direct call on the emem object, framework a request to the component's ``execute_method`` service
  (payload ``string``), and the component's method called in this thread (payload ``method_call``: the
  component's own cost, without the service's hand-offs caller -> request lane -> worker and back); the
  three alternate query by query.

Each round adds ``n`` observations to each side; the figures are the medians over the rounds.
Run alone: ``python -m benchmarks.memory --values 300 --rounds 3``.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import math
import sqlite3
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .map import _embedder

TEXTS = ["a red cup on the kitchen table", "a person walking in the corridor", "the charging dock by the door",
         "a cat sleeping on the sofa", "a bicycle leaning on the garage wall"]
QUERIES = 50
#: MemoryConfig's default flush_batch_size, used by both sides.
BATCH = 5


def unavailable_reason() -> str | None:
    """Why the suite cannot run here, or None."""
    return None if importlib.util.find_spec("emem") else "the memory extra is not installed (emem)"


def committed(db_path: Path) -> int:
    """Observations committed to the SQLite file at ``db_path``, read through a connection of its own."""
    with contextlib.closing(sqlite3.connect(db_path)) as db:
        return int(db.execute("SELECT COUNT(*) FROM observations").fetchone()[0])


def _texts(n: int, tag: str) -> list[str]:
    return [f"{TEXTS[i % len(TEXTS)]} #{tag}-{i}" for i in range(n)]


class RawSide:
    """emem used directly, as a program without the framework would."""

    def __init__(self, folder: Path) -> None:
        from emem import SpatioTemporalMemory, SpatioTemporalMemoryConfig  # noqa: PLC0415

        from agents_core.components.memory.engine import ClientEmbedder  # noqa: PLC0415
        from agents_core.config import MemoryConfig  # noqa: PLC0415

        defaults = MemoryConfig()
        self.db_path = folder / "raw.db"
        self.embedder = ClientEmbedder(_embedder())
        self.mem = SpatioTemporalMemory(config=SpatioTemporalMemoryConfig(
            db_path=str(self.db_path), hnsw_path=str(folder / "raw.hnsw.bin"), embedding_dim=self.embedder.dim,
            # Count-based only: its age-based flush would fire on the first add after the pause between
            # rounds, shift the batches and leave the round's last adds uncommitted when the clock stops.
            flush_batch_size=defaults.flush_batch_size, flush_interval=math.inf,
            **defaults.engine_settings()), embedding_provider=self.embedder)

    def write(self, texts: list[str]) -> float:
        """Seconds to embed and commit ``texts`` (a multiple of BATCH: emem commits every BATCH adds)."""
        start = time.perf_counter()
        for i in range(0, len(texts), BATCH):
            batch = texts[i:i + BATCH]
            for k, (text, vec) in enumerate(zip(batch, self.embedder.embed(batch), strict=True)):
                self.mem.add(text, x=0.1 * (i + k), y=0.0, layer_name="heard", source_type="perception",
                             embedding=vec)
        return time.perf_counter() - start

    def search(self, query: str) -> float:
        start = time.perf_counter()
        self.mem.semantic_search(query=query, n_results=5)
        return time.perf_counter() - start

    def close(self) -> None:
        self.mem.close()


class FrameworkSide:
    """A Memory component under a Launcher on the memory transport."""

    def __init__(self, folder: Path, n: int) -> None:
        from agents_core import Launcher, MemoryTransport, Topic  # noqa: PLC0415
        from agents_core.components import MemLayer, Memory  # noqa: PLC0415
        from agents_core.config import MemoryConfig  # noqa: PLC0415

        odom, heard = Topic("odom", "Odometry"), Topic("heard", "String")
        self.db_path = folder / "framework.db"
        self.mem = Memory(layers=[MemLayer(subscribes_to=heard, temporal_change=True)], position=odom,
                          embedding_client=_embedder(), trigger=heard,
                          config=MemoryConfig(db_path=str(self.db_path), buffer_size=max(1000, 2 * n)))
        self.transport = MemoryTransport()
        self.launcher = Launcher(self.transport)
        self.launcher.add_pkg(components=[self.mem])
        self.launcher.start()
        self.pub_odom = self.transport.create_publisher(odom)
        self.pub_heard = self.transport.create_publisher(heard)

    def write(self, texts: list[str]) -> float:
        """Seconds from the first value published to the last one committed."""
        from agents_core.messages import OdometryMsg, PoseMsg  # noqa: PLC0415

        target = self.mem.stats["stored"] + len(texts)
        start = time.perf_counter()
        for i, text in enumerate(texts):
            self.pub_odom.publish(OdometryMsg(pose=PoseMsg(position=[0.1 * i, 0.0, 0.0])))
            self.pub_heard.publish(text)
        while self.mem.stats["stored"] < target:
            time.sleep(0.0005)
            if time.perf_counter() - start > 60:
                raise TimeoutError(f"memory bench: {self.mem.stats}")
        return time.perf_counter() - start

    def search_method(self, query: str) -> float:
        start = time.perf_counter()
        self.mem.semantic_search(query=query, n_results=5)
        return time.perf_counter() - start

    def search(self, query: str) -> float:
        start = time.perf_counter()
        self.transport.request("memory/execute_method",
                               {"method": "semantic_search", "kwargs": {"query": query, "n_results": 5}})
        return time.perf_counter() - start

    def close(self) -> None:
        try:
            self.launcher.stop()
        finally:
            self.transport.close()


def measure(n: int, rounds: int, queries: int, folder: Path,
            progress: Callable[[str], None]) -> list[dict[str, Any]]:
    """``rounds`` interleaved rounds; one record per side and round."""
    n = max(BATCH, n - n % BATCH)
    raw, fw = RawSide(folder), FrameworkSide(folder, n)
    sides = {"raw": raw, "framework": fw}
    records: list[dict[str, Any]] = []
    try:
        for side in sides.values():  # warm-up: the first writes and searches pay for caches, not recorded
            side.write(_texts(2 * BATCH, "warm"))
            side.search(TEXTS[0])
        for r in range(rounds):
            order = ["raw", "framework"] if r % 2 == 0 else ["framework", "raw"]
            rate = {}
            for mode in order:
                rate[mode] = n / sides[mode].write(_texts(n, str(r)))
                # Durable: the rows are visible to another connection once the clock stopped.
                if committed(sides[mode].db_path) != 2 * BATCH + (r + 1) * n:
                    raise RuntimeError(f"memory bench: {mode} did not commit round {r}: "
                                       f"{committed(sides[mode].db_path)} rows")
            calls = {"raw": raw.search, "framework": fw.search, "method": fw.search_method}
            lat: dict[str, list[float]] = {mode: [] for mode in calls}
            for q in range(queries):
                names = list(calls) if q % 2 == 0 else list(calls)[::-1]
                for mode in names[q % 3:] + names[:q % 3]:
                    lat[mode].append(calls[mode](TEXTS[q % len(TEXTS)]) * 1e6)
            search = {mode: statistics.median(v) for mode, v in lat.items()}
            for mode in order:
                records.append({"suite": "memory", "transport": "memory", "payload": "string", "mode": mode,
                                "round": r, "values": n, "writes_per_s": rate[mode],
                                "search_median_us": search[mode]})
                progress(f"{'memory':<10} {'memory':<6} {mode:<9} {rate[mode]:8.1f} obs/s  "
                         f"search {search[mode]:8.0f} us  (round {r})")
            # The component's method called directly against the same direct emem calls.
            records += [{"suite": "memory", "transport": "memory", "payload": "method_call", "mode": mode,
                         "round": r, "search_median_us": search["method" if mode == "framework" else "raw"]}
                        for mode in ("raw", "framework")]
            progress(f"{'memory':<10} {'memory':<6} {'method':<9} {'':>14}  search {search['method']:8.0f} us")
        stats = fw.mem.stats
        if any(stats[k] for k in ("dropped", "no_position", "unchanged", "pending")):
            raise RuntimeError(f"memory bench: the component did not store every value: {stats}")
    finally:
        fw.close()
        raw.close()
    return records


def run_suite(settings: dict[str, Any], progress: Callable[[str], None],
              ) -> tuple[list[dict[str, Any]], list[dict[str, str]]]:
    """Both sides in this process, interleaved; (records, skipped)."""
    reason = unavailable_reason()
    if reason is not None:
        progress(f"memory: skipped: {reason}")
        return [], [{"suite": "memory", "transport": "memory", "mode": "both", "reason": reason}]
    with tempfile.TemporaryDirectory() as folder:
        # At least 300 values a round: a write of 100 lasts ~20 ms here, where the wake-up of one thread on a
        # loaded machine (a few ms) would weigh as much as the throughput being measured.
        records = measure(max(300, int(settings.get("map_values", 200))), 2 * int(settings.get("rounds", 1)) + 3,
                          QUERIES, Path(folder), progress)
    return records, []


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--values", type=int, default=300)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--queries", type=int, default=QUERIES)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as folder:
        records = measure(args.values, args.rounds, args.queries, Path(folder), print)
    def ratios(payload: str, key: str) -> str:
        by_mode = {mode: [r[key] for r in records if r["payload"] == payload and r["mode"] == mode]
                   for mode in ("framework", "raw")}
        return ", ".join(f"{f / r:.2f}" for f, r in zip(by_mode["framework"], by_mode["raw"], strict=True))

    print(f"per round, framework / raw: stored/s {ratios('string', 'writes_per_s')}; semantic_search latency "
          f"through execute_method {ratios('string', 'search_median_us')}, the component's method called "
          f"directly {ratios('method_call', 'search_median_us')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
